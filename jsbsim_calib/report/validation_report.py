"""The held-out validation report: reports/<aircraft>/validation.md with one figure (fit vs
held-out RMSE per fold), the physics checks, and the console tables. It draws the results of
:mod:`jsbsim_calib.calibration.validation` and :mod:`jsbsim_calib.evaluation.physics_checks`; it runs nothing."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")
from matplotlib.figure import Figure  # noqa: E402

from ..calibration.validation import FLAG_RATIO, RESOLUTION, ErrorStat, FoldResult, Validation  # noqa: E402
from ..evaluation.physics_checks import PhysicsChecks  # noqa: E402
from . import plots  # noqa: E402

STAGE_TITLES = {"steady": "stage 1 (POH climb and cruise)", "trims": "stage 2a (flight-test trims)",
                "dynamic": "stage 2b (dynamic tests)"}


def _f(v: float, d: int = 2) -> str:
    return "-" if v is None or not math.isfinite(v) else f"{v:.{d}f}"


def _digits(metric: str) -> int:
    return 0 if metric in ("roc_fpm",) else 1 if metric == "rpm" else 2


def _stat(s: ErrorStat, metric: str) -> str:
    return f"{_f(s.rmse, _digits(metric))} / {_f(s.within_pct, 0)} %"


# --------------------------------------------------------------------------- console
def format_validation(v: Validation) -> str:
    """The fold table as text: fit and held-out RMSE / within %, the ratio and the flag."""
    head = (f"{'fold':<24} {'metric':<24} {'fit RMSE / within':>20} {'held-out RMSE / within':>24} "
            f"{'in-sample':>16} {'ratio':>6}  flag")
    lines = [f"{v.aircraft}: held-out validation of {STAGE_TITLES.get(v.stage, v.stage)}", head, "-" * len(head)]
    rows = ([] if v.control is None else v.control.metrics) + v.rows()
    for m in rows:
        name = f"{m.kind}.{m.metric}"
        lines.append(f"{m.fold:<24} {name:<24} {_stat(m.fit, m.metric):>20} {_stat(m.held_out, m.metric):>24} "
                     f"{_stat(m.in_sample, m.metric):>16} {_f(m.ratio):>6}  "
                     f"{'FLAG: ' + m.flag_reason if m.flagged and m.fold != 'none (control)' else ''}")
    flagged = v.flagged()
    lines.append(f"{len(flagged)} of {len(v.rows())} fold-metrics flagged (held-out > {FLAG_RATIO:g} x fit and above "
                 f"{RESOLUTION:g} tolerance, a failed held-out trim, or no number); wall time {v.wall_time_s:.0f} s, "
                 f"{v.trims} trims")
    return "\n".join(lines)


def format_physics(pc: PhysicsChecks) -> str:
    lines = [f"{pc.aircraft}: physics checks ({pc.model} factors)"]
    for c in pc.checks():
        lines.append(f"  {'ok  ' if c.ok else 'FAIL'}  {c.name:<52} {c.value:<32} expected {c.expected}")
    lines += [f"  note: {n}" for n in pc.notes]
    return "\n".join(lines)


# --------------------------------------------------------------------------- figure
def fold_figure(validations: Sequence[Validation]) -> Figure:
    """Fit vs held-out RMSE (in tolerances) per fold, one panel per stage."""
    n = max(1, len(validations))
    fig = Figure(figsize=(11.0, 3.6 * n), dpi=100)
    for k, v in enumerate(validations):
        ax = fig.add_subplot(n, 1, k + 1)
        rows = v.rows()
        fit = [m.fit.rmse / m.tolerance for m in rows]
        held = [m.held_out.rmse / m.tolerance for m in rows]
        x = list(range(len(rows)))
        ax.bar([i - 0.2 for i in x], fit, 0.4, label="fit (fold's complement)", color="tab:blue")
        ax.bar([i + 0.2 for i in x], held, 0.4, label="held out (the fold)", color="tab:orange")
        for i, m in enumerate(rows):
            if m.flagged and math.isfinite(held[i]):
                ax.annotate("*", (i + 0.2, held[i]), ha="center", va="bottom", color="tab:red", fontsize=12)
        ax.set_xticks(x)
        ax.set_xticklabels([f"{m.fold}\n{m.metric}" for m in rows], rotation=90, fontsize=6)
        ax.axhline(1.0, color="k", lw=0.8, ls="--", label="RMSE = tolerance")
        ax.set_ylabel("RMSE / tolerance [-]")
        ax.set_title(f"{v.aircraft}, {STAGE_TITLES.get(v.stage, v.stage)}: fit vs held-out error per fold "
                     f"(* flagged)", fontsize=9)
        ax.grid(axis="y", alpha=0.3)
        ax.legend(fontsize=7)
    return fig


# --------------------------------------------------------------------------- markdown
def _md_fold_table(v: Validation) -> list[str]:
    L = ["| fold | grouping | refitted | metric | unit | fit RMSE | fit within % | held-out RMSE | held-out within % "
         "| in-sample RMSE | held-out / fit | flag |", "|---|---|---|---|---|---:|---:|---:|---:|---:|---:|---|"]
    results: list[FoldResult] = ([v.control] if v.control else []) + v.folds
    for fr in results:
        for m in fr.metrics:
            d = _digits(m.metric) + 1
            flag = "" if m.fold == "none (control)" else ("**" + m.flag_reason + "**" if m.flagged else "")
            L.append(f"| {m.fold} | {m.grouping} | {', '.join(fr.refitted)} | {m.kind}.{m.metric} | {m.unit} | "
                     f"{_f(m.fit.rmse, d)} | {_f(m.fit.within_pct, 0)} | {_f(m.held_out.rmse, d)} | "
                     f"{_f(m.held_out.within_pct, 0)} | {_f(m.in_sample.rmse, d)} | {_f(m.ratio)} | {flag} |")
    return L + [""]


def _md_validation(v: Validation) -> list[str]:
    flagged = v.flagged()
    L = [f"## {STAGE_TITLES.get(v.stage, v.stage)}", "",
         f"{len(v.folds)} folds, {len(v.rows())} fold-metrics, {len(flagged)} flagged; at most {v.max_nfev} "
         f"evaluations per refit; {v.trims} trims.", ""]
    L += _md_fold_table(v)
    fails = [f"{fr.fold.name}: {x}" for fr in v.folds for x in fr.failures]
    L += [f"* held-out trim failed: {x}" for x in fails] + ([""] if fails else [])
    L += ["Factors each refit moved most (share of their range):", ""]
    for fr in ([v.control] if v.control else []) + v.folds:
        moves = ", ".join(f"{k} {a:.4g} -> {b:.4g}" for k, a, b in fr.largest_moves())
        L.append(f"* {fr.fold.name}: {moves or 'none'}")
    L.append("")
    L += [f"* {n}" for n in v.notes] + [""]
    return L


def _md_physics(pc: PhysicsChecks) -> list[str]:
    po, pr = pc.polar, pc.propeller
    L = [f"## Physics checks ({pc.model} factors)", "", "| check | model | expected | holds |", "|---|---|---|---|"]
    L += [f"| {c.name} | {c.value} | {c.expected} | {'yes' if c.ok else '**no**'} |" for c in pc.checks()]
    L += ["", "**Climb rate against weight** (full-throttle POH climbs; classic: -ROC/W - 2 D_i V / W^2 with the "
          "lift-dependent drag of the model's polar)", "",
          "| Hp ft | T C | KCAS | W lb | ROC fpm | CL | D_i lbf | model dROC/dW fpm/lb | classic | model/classic |",
          "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    L += [f"| {w.pressure_alt_ft:.0f} | {w.temperature_c:.1f} | {w.kcas:.1f} | {w.weight_lb:.0f} | {w.roc_fpm:.0f} | "
          f"{w.cl:.3f} | {w.lift_dependent_drag_lbf:.1f} | {w.model_droc_dw_fpm_per_lb:+.3f} | "
          f"{w.classic_droc_dw_fpm_per_lb:+.3f} | {w.ratio:.2f} |" for w in pc.weight]
    trend = (f"{pc.poh_droc_dw_fpm_per_lb:+.3f} fpm/lb" if math.isfinite(pc.poh_droc_dw_fpm_per_lb)
             else "n/a (one weight)")
    L += ["", f"POH climb weights: {', '.join(f'{w:.0f}' for w in pc.poh_weights_lb)} lb; POH trend {trend}.", "",
          f"**Drag polar** (level trims, {po.pressure_alt_ft:.0f} ft ISA, {po.weight_lb:.0f} lb, flaps up; AR "
          f"{po.aspect_ratio:.2f}): CD = {po.cd0:.4f} + {po.k:.4f} CL^2, Oswald e = {po.oswald_efficiency:.3f}.", "",
          "| KTAS | CL | CD | wing CL | wing CDi | wing span efficiency (CDi table) |", "|---:|---:|---:|---:|---:|---:|"]
    L += [f"| {p.ktas:.1f} | {p.cl:.3f} | {p.cd:.4f} | {p.cl_wing:.3f} | {p.cdi_wing:.4f} | "
          f"{_f(p.wing_span_efficiency)} |" for p in po.points]
    L += ["", "Local Oswald e between neighbouring speeds: " + ", ".join(f"{e:.2f} at CL {cl:.2f}"
                                                                        for cl, e in po.local_oswald()) + ".", ""]
    return L + _md_propeller(pr) + [f"* {n}" for n in pc.notes] + [""]


def _md_propeller(pr) -> list[str]:
    lo, hi = pr.cruise_range()
    blade = "" if not math.isfinite(pr.blade_angle_deg) else f" at the median cruise blade angle {pr.blade_angle_deg:.1f} deg"
    L = [f"**Propeller efficiency** (eta = T V / P at the POH trims; table eta = J CT / CP{blade}): table peak "
         f"{pr.peak_efficiency:.3f} at J {pr.peak_advance_ratio:.2f} (uncalibrated BEM table: "
         f"{pr.neutral_peak_efficiency:.3f} at J {pr.neutral_peak_advance_ratio:.2f}); cruise J {lo:.2f}-{hi:.2f}.", "",
         "| POH points | Hp ft | mean J | mean eta | points |", "|---|---:|---:|---:|---:|"]
    L += [f"| {k} | {a:.0f} | {j:.3f} | {e:.3f} | {n} |" for k, a, j, e, n in pr.by_altitude()]
    return L + [""]


def write_validation_report(aircraft: str, validations: Sequence[Validation], physics: PhysicsChecks | None,
                            out_dir: Path, command: str) -> Path:
    """reports/<aircraft>/validation.md and validation.png; returns the Markdown path."""
    out_dir.mkdir(parents=True, exist_ok=True)
    png = out_dir / "validation.png"
    if validations:
        plots.save(fold_figure(validations), png)
    L = [f"# {aircraft}: held-out validation and physics checks", "",
         f"Generated by `{command}`. Each fold leaves a group of data out, refits the stage from its own factors "
         "with its own fit functions and real trims, and trims every point again: *fit* is the refit's error on the "
         "points it kept, *held-out* its error on the points left out, *in-sample* the stage's own model's error on "
         f"the same left-out points (it saw them). Flagged: held-out RMSE > {FLAG_RATIO:g} x fit RMSE (unless below "
         f"{RESOLUTION:g} of the metric's tolerance), a failed held-out trim, or no number (a NaN never passes). The control refits with nothing left out: what the "
         "shortened refit alone changes. The committed products are not changed.", ""]
    for v in validations:
        L += _md_validation(v)
    if validations:
        L += [f"![fit vs held-out]({png.name})", ""]
    if physics is not None:
        L += _md_physics(physics)
    md = out_dir / "validation.md"
    md.write_text("\n".join(L) + "\n")
    return md
