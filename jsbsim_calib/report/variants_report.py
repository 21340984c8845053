"""The model-variant comparison: reports/<aircraft>/slipstream.md with one figure (trims within
tolerance per axis and full-power surface errors, per variant) and the console table. It draws
the results of :mod:`jsbsim_calib.calibration.variants`; it runs nothing."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Mapping, Sequence

import matplotlib

matplotlib.use("Agg")
from matplotlib.figure import Figure  # noqa: E402

from ..calibration.variants import VariantResult  # noqa: E402

AXES = ("pitch_deg", "elevator_deg", "aileron_deg", "rudder_deg")
SAME_ABS, SAME_REL = 1e-3, 0.005       # figures closer than this are the same (a governed RPM off by 1e-7 ...)


def _cell(v) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return f"{v:.3g}" if abs(v) < 100 else f"{v:.0f}"


def table(results: Sequence[VariantResult]) -> tuple[list[str], list[list[str]]]:
    """Header and rows: one row per figure, one column per variant."""
    rows = [r.rows() for r in results]
    labels = list(dict.fromkeys(k for row in rows for k in row))
    head = ["figure"] + [r.variant.name for r in results]
    return head, [[k] + [_cell(row.get(k)) for row in rows] for k in labels]


def _better(label: str, new: float, old: float) -> bool | None:
    """Whether ``new`` is better than ``old`` for this figure (None: no order, e.g. a factor)."""
    if label.startswith("K_"):
        return None
    higher = label.endswith("within %") or "passed" in label
    return new > old if higher else new < old


def against(results: Sequence[VariantResult], reference: str = "off") -> dict[str, dict[str, list[str]]]:
    """For each variant but the reference: the figures it does better and worse than the
    reference ({variant: {"better": [...], "worse": [...]}})."""
    ref = next((r for r in results if r.variant.name == reference), None)
    if ref is None:
        return {}
    base, out = ref.rows(), {}
    for r in results:
        if r is ref:
            continue
        d = {"better": [], "worse": []}
        for k, v in r.rows().items():
            b = base.get(k)
            if v is None or b is None or abs(v - b) <= max(SAME_ABS, SAME_REL * max(abs(v), abs(b))):
                continue
            good = _better(k, v, b)
            if good is not None:
                d["better" if good else "worse"].append(f"{k} {_cell(b)} -> {_cell(v)}")
        out[r.variant.name] = d
    return out


def format_comparison(aircraft: str, results: Sequence[VariantResult]) -> str:
    head, rows = table(results)
    w = max(len(r[0]) for r in rows + [head])
    lines = [f"{aircraft}: model variants (each the whole chain from neutral factors)",
             f"{head[0]:<{w}}" + "".join(f"{h:>12}" for h in head[1:])]
    lines += [f"{r[0]:<{w}}" + "".join(f"{c:>12}" for c in r[1:]) for r in rows]
    lines.append("wall time: " + ", ".join(f"{r.variant.name} {r.wall_time_s:.0f} s" for r in results))
    return "\n".join(lines)


def comparison_figure(results: Sequence[VariantResult]) -> Figure:
    fig = Figure(figsize=(9.0, 3.4))
    a, b = fig.subplots(1, 2)
    width = 0.8 / max(len(results), 1)
    for i, r in enumerate(results):
        rows = r.rows()
        within = [rows.get(f"trims {m} within %") or 0.0 for m in AXES]
        a.bar([k + i * width for k in range(len(AXES))], within, width, label=r.variant.name)
        fp = [rows.get(f"full-power {m} RMSE") or 0.0 for m in ("elevator_deg", "rudder_deg")]
        b.bar([k + i * width for k in range(2)], fp, width, label=r.variant.name)
    a.set_xticks([k + 0.4 - width / 2 for k in range(len(AXES))], [m.split("_")[0] for m in AXES])
    a.set_ylabel("trims within tolerance [%]")
    a.set_ylim(0, 105)
    b.set_xticks([k + 0.4 - width / 2 for k in range(2)], ["elevator", "rudder"])
    b.set_ylabel("full-throttle rows: RMSE [deg]")
    for ax in (a, b):
        ax.grid(axis="y", alpha=0.3)
    fig.legend(*a.get_legend_handles_labels(), loc="upper center", ncol=len(results), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 0.92))
    return fig


def write_comparison_report(aircraft: str, results: Sequence[VariantResult], product: Mapping[str, float],
                            out_dir: Path, command: str, note: str = "") -> Path:
    """The markdown report and its figure; ``product``: the switch values the aircraft file holds."""
    out_dir.mkdir(parents=True, exist_ok=True)
    head, rows = table(results)
    lines = [f"# {aircraft}: propeller slipstream on and off", "",
             f"Made by `{command}`. Each variant runs the whole calibration chain from neutral factors on the same "
             "data (stage 1 on the POH; where the aircraft has flight-test data, stage 2a and 2b too) and is "
             "evaluated after its last stage. The slipstream model: `jsbsim_calib.physics.slipstream` "
             "(momentum theory; the tail and the immersed wing-root strips in a dynamic pressure 1 + K_slip f Tc, "
             "the swirl of the BEM torque as a sideslip at the fin, K_swirl).", "",
             "| variant | what |", "|---|---|"]
    lines += [f"| {r.variant.name} | {r.variant.doc} |" for r in results]
    lines += ["", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    for name, d in against(results).items():
        lines += ["", f"**{name}** against off: better on {'; '.join(d['better']) or 'nothing'}; "
                      f"worse on {'; '.join(d['worse']) or 'nothing'}."]
    shown = ", ".join(f"{k} = {v:g}" for k, v in product.items())
    lines += ["", f"The product (aircraft/{aircraft}/{aircraft}.xml) holds {shown}."]
    if note:
        lines += ["", note]
    if any(r.trims for r in results):
        fig = comparison_figure(results)
        fig.savefig(out_dir / "slipstream.png", dpi=110, metadata={"Software": None})
        lines += ["", "![trims within tolerance and full-throttle surface errors per variant](slipstream.png)"]
    path = out_dir / "slipstream.md"
    path.write_text("\n".join(lines) + "\n")
    return path
