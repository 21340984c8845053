"""The report of closing the loop on time histories (reports/<aircraft>/close-loop-dynamic.md + PNG).

It draws a :class:`~jsbsim_calib.calibration.closeloop_dynamic.CloseLoopDynamicResult`; it runs
nothing. Plots take an optional ``ax`` and return the figure (matplotlib's Agg backend, the
style of :mod:`.plots`).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..calibration.loop import MATERIAL, MIN_EVIDENCE, MIN_EXPLAINED, MIN_HELD_GAIN
from ..calibration.closeloop_dynamic import CloseLoopDynamicResult, structured_axes
from ..data.timehistory import CHANNELS
from ..evaluation.evaluate_dynamic import AXIS_CHANNELS, CHANNEL_SCALES
from . import plots
from .markdown import added_xml_section

REPORT = "close-loop-dynamic"
LABELS = {"p_deg_s": "roll rate", "q_deg_s": "pitch rate", "r_deg_s": "yaw rate", "roll_deg": "bank",
          "pitch_deg": "pitch attitude", "beta_deg": "sideslip", "alpha_deg": "angle of attack", "kcas": "KCAS"}


def _ax(ax, size=(6.4, 3.2)):
    if ax is not None:
        return ax.figure, ax
    fig = Figure(figsize=size, dpi=110)
    return fig, fig.add_subplot(111)


def channel_history(time_s: np.ndarray, data: np.ndarray, before: np.ndarray | None, after: np.ndarray | None,
                    channel: str, ax=None) -> Figure:
    """One channel of a maneuver: the recorded samples, the model before and after the loop."""
    fig, ax = _ax(ax)
    ax.plot(time_s, data, "o", color="k", ms=2.2, label="recorded")
    if before is not None:
        ax.plot(time_s, before, label="before", **plots.STYLES["baseline"])
    if after is not None:
        ax.plot(time_s, after, label="after", **plots.STYLES["calibrated"])
    unit = CHANNELS[channel].unit if channel in CHANNELS else ""
    ax.set_ylabel(f"{LABELS.get(channel, channel)} [{unit}]", fontsize=8)
    ax.set_xlabel("maneuver time [s]", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    return fig


def axis_histories(result: CloseLoopDynamicResult, index: int, axis: str) -> Figure:
    """The channels of one axis of test ``index``, one panel each, before and after."""
    rb, ra = result.before[index], result.after[index]
    chans = [c for c in AXIS_CHANNELS[axis] if c in rb.channels]
    fig = Figure(figsize=(6.4, 2.2 * max(1, len(chans)) + 0.4), dpi=110)
    for k, c in enumerate(chans):
        channel_history(rb.test.time_s, rb.test.channels[c], None if rb.model is None else rb.model[c],
                        None if ra.model is None else ra.model[c], c, ax=fig.add_subplot(len(chans), 1, k + 1))
    fig.suptitle(f"{rb.test.id} ({rb.test.kind}): {axis} axis", fontsize=9)
    return fig


def residual_vs_regressor(x: np.ndarray, y: np.ndarray, name: str, round_: int, axes, ax=None) -> Figure:
    """A finalist's evidence in the equation error of its round: the weighted residual the
    model leaves at each recorded sample against what the candidate's columns predict of it
    (its regressor at the linearized estimate); the candidate that explains it puts them on y = x."""
    fig, ax = _ax(ax, (4.8, 4.0))
    ax.plot(x, y, ".", ms=2, color="tab:blue", alpha=0.4, label="recorded samples")
    lim = float(np.nanmax(np.abs(np.concatenate([x, y])))) if x.size else 1.0
    ax.plot([-lim, lim], [-lim, lim], color="k", lw=0.8, label="y = x (explained)")
    ax.set_xlabel(f"{name}: its regressor x the estimate (weighted)", fontsize=8)
    ax.set_ylabel(f"{'/'.join(axes)} moment residual, data - model (weighted)", fontsize=8)
    ax.set_title(f"Round {round_}: the residual against the regressor of {name}", fontsize=9)
    ax.tick_params(labelsize=7)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    return fig


def _evidence_figures(result: CloseLoopDynamicResult, out_dir: Path) -> list[str]:
    """The residual-against-regressor plot of each added change, from the screen that flew it (a
    round screens a second axis when the first yields nothing: the last screen of its round)."""
    names = []
    for c in result.candidates:
        scr = next((s for s in reversed(result.screens) if s.round == c.round and c.effect in s.explains), None)
        if not c.accepted or scr is None:
            continue
        x, y = scr.explains[c.effect]
        name = f"{REPORT}_round{c.round}_{_safe(c.effect)}.png"
        plots.save(residual_vs_regressor(x, y, c.effect, c.round, scr.axes), out_dir / name)
        names.append(name)
    return names


def _safe(s: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in s)


def _f(x, spec: str = ".3g") -> str:
    return "-" if x is None or not math.isfinite(x) else format(x, spec)


def _diagnosis_table(diag: dict) -> list[str]:
    L = ["| channel | axis | structured | RMS | mean | trend /s | noise (est.) | why | correlates with |",
         "|---|---|---|---:|---:|---:|---:|---|---|"]
    for c, d in diag.items():
        cors = ", ".join(f"{x.regressor} (r {x.r:+.2f})" for x in d.correlates[:3]) or "-"
        L.append(f"| {c} | {d.axis} | {'**yes**' if d.structured else 'no'} | {_f(d.rms)} | {_f(d.bias, '+.3g')} | "
                 f"{_f(d.trend_per_s, '+.3g')} | {_f(d.noise)} | {d.reason} | {cors} |")
    return L + [""]


def _candidate_table(result: CloseLoopDynamicResult) -> list[str]:
    L = ["| round | effect | axis | BIC change | explains | cross-validated RSS | factor(s) | decision |",
         "|---:|---|---|---:|---:|---|---|---|"]
    for c in sorted(result.candidates, key=lambda c: (c.round, c.delta_bic)):
        fac = "; ".join(f"{k.split('.', 1)[-1]} = {v:.4g}" + (f" +/- {c.stderr[k]:.2g}" if c.stderr.get(k) else "")
                        for k, v in c.factors.items())
        cv = f"{c.cv[0]:.3g} -> {c.cv[1]:.3g}" if c.cv else "-"
        bic, share = c.evidence_cells()
        L.append(f"| {c.round} | {c.effect} | {c.axis} | {bic} | {share} | {cv} | {fac} | "
                 f"{'**added**' if c.accepted else c.reason} |")
    return L + [""]


def _screen_table(result: CloseLoopDynamicResult) -> list[str]:
    """Each round's equation-error ranking: what was flown and why (the strongest listed)."""
    L = []
    for scr in result.screens:
        L += [f"Round {scr.round}: equation error on {scr.rows} rows ({', '.join(scr.axes)} axes, "
              f"{scr.wall_time_s:.1f} s); flown: {', '.join(scr.finalists) or 'none'}.", "",
              "| candidate | kind | axes | estimate | chi-square explained | share of its axes |",
              "|---|---|---|---:|---:|---:|"]
        for r in scr.ranked[:8]:
            est = ", ".join(f"{x:.4g}" for x in r.estimate)
            L.append(f"| {r.target} | {r.kind} | {', '.join(r.axes)} | {est} | {r.explained:.1f} | "
                     f"{100 * r.share:.1f} % |")
        L.append("")
    return L


def _error_table(result: CloseLoopDynamicResult) -> list[str]:
    b, a = result.errors("before"), result.errors("after")
    L = ["| axis | channel | scale | RMS before | RMS after | largest before | largest after |",
         "|---|---|---:|---:|---:|---:|---:|"]
    for axis, chans in b.items():
        for c, e in chans.items():
            e1 = a[axis][c]
            unit = CHANNELS[c].unit
            L.append(f"| {axis} | {c} | {CHANNEL_SCALES[c]:g} {unit} | {_f(e.rms)} | {_f(e1.rms)} | {_f(e.max_abs)} | "
                     f"{_f(e1.max_abs)} |")
    return L + [""]


def _tests_table(result: CloseLoopDynamicResult) -> list[str]:
    L = ["| test | kind | samples | duration [s] | channels | input offsets [deg] | flown |",
         "|---|---|---:|---:|---|---|---|"]
    for r in result.before:
        t = r.test
        off = ", ".join(f"{c.split('_')[0]} {v:+.3f}" for c, v in result.input_offsets.get(t.id, {}).items())
        L.append(f"| {t.id} | {t.kind} | {len(t.time_s)} | {t.time_s[-1]:.1f} | {', '.join(r.channels)} | "
                 f"{off or '-'} | {'no: ' + r.failure if r.failure else 'yes'} |")
    return L + [""]


def _method() -> str:
    return ("Method (`jsbsim_calib.calibration.closeloop_dynamic`): every test is flown on the model (trim at its "
            "first sample, its inputs replayed, each surface input with a constant offset fitted per test: the "
            "error of the replay's reference, a nuisance parameter); each response channel's residual time history is diagnosed against "
            "a noise estimate from its second differences; an axis is structured when one of its channels has a "
            f"residual beyond the noise of at least {MATERIAL:g} of its scale. Every library effect that acts on a "
            "structured axis is added to a copy of the aircraft and its factor fitted alone on all the tests; the "
            f"best is added only with very strong evidence (noise-scaled BIC change <= -{MIN_EVIDENCE:g}), a material "
            f"change, at least {100 * MIN_EXPLAINED:.0f} % of the structured residual of the channels it moves "
            f"explained, and a {100 * MIN_HELD_GAIN:.0f} % gain in cross-validation whose folds are whole maneuvers; "
            "then it is refitted with the stage-2b factors of its axis. Repeat until nothing passes. The samples of "
            "a time history are correlated, so the BIC change overstates the evidence; the explained share and the "
            "cross-validation decide. (The rules are the trim loop's; where their messages say tolerance, read the "
            "channel's scale.)")


FIGURE_TESTS = 6             # plotted per structured axis: the tests with the most of its residual before


def axis_rss(r, axis: str) -> float:
    """A flown test's sum of squared scaled residuals in the channels of ``axis``."""
    n = len(r.test.time_s)
    return sum(float(r.scaled[k * n:(k + 1) * n] @ r.scaled[k * n:(k + 1) * n])
               for k, c in enumerate(r.channels) if c in AXIS_CHANNELS[axis])


def plotted_tests(result: CloseLoopDynamicResult, axis: str) -> list[int]:
    """The :data:`FIGURE_TESTS` tests with the largest residual in ``axis`` before the loop
    (the ones a reader checks the change on), in the tests' order."""
    have = [i for i, r in enumerate(result.before) if any(c in r.channels for c in AXIS_CHANNELS[axis])]
    ranked = sorted(have, key=lambda i: -axis_rss(result.before[i], axis))
    return sorted(ranked[:FIGURE_TESTS])


def _figures(result: CloseLoopDynamicResult, out_dir: Path) -> tuple[list[str], list[str]]:
    """Before/after plots of the axes structured before the loop, per axis the tests with the
    most of its residual; and a line per axis naming the tests left out."""
    names, left = [], []
    for axis in structured_axes(result.diagnosis_before):
        shown = plotted_tests(result, axis)
        for i in shown:
            name = f"{REPORT}_{_safe(result.before[i].test.id)}_{axis}.png"
            plots.save(axis_histories(result, i, axis), out_dir / name)
            names.append(name)
        others = [r.test.id for i, r in enumerate(result.before) if i not in shown
                  and any(c in r.channels for c in AXIS_CHANNELS[axis])]
        if others:
            left.append(f"{axis} axis: {len(shown)} tests with the most of its residual before; not plotted "
                        f"(less of it): {', '.join(others)}.")
    return names, left


def write_close_loop_dynamic_report(result: CloseLoopDynamicResult, out_dir: Path, written: Path | None = None,
                                    command: str = "") -> Path:
    """reports/<aircraft>/close-loop-dynamic.md: tests, diagnosis, candidates, refits, error
    before and after, what stays unexplained, time-history plots of the structured axes."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    figs, left = _figures(result, out_dir)
    evidence = _evidence_figures(result, out_dir)
    L = [f"# {result.aircraft}: closing the loop on {len(result.tests)} time histories", ""]
    if command:
        L += [f"Generated by `{command}`. " + " ".join(result.notes), ""]
    L += [_method(), "", f"**Added:** {', '.join(result.added) if result.added else 'nothing'}"
          + (f"; written to `{written}`." if written else "."), "", "## Tests", ""] + _tests_table(result)
    L += ["## Diagnosis before", ""] + _diagnosis_table(result.diagnosis_before)
    L += ["## Candidates", ""] + (_screen_table(result) + _candidate_table(result) if result.candidates else
                                  ["No candidate: no axis is structured.", ""])
    if result.refits:
        L += ["## Refits after each added effect", "", "```"] + [r.report() + "\n" for r in result.refits] + ["```", ""]
    L += added_xml_section(result)
    if evidence:
        L += ["## The residual against the regressor that explains it (equation error of the round's screen)", ""]
        L += [f"![{n}]({n})" for n in evidence] + [""]
    L += ["## Error before and after (all tests, every recorded sample)", ""] + _error_table(result)
    L += ["## Diagnosis after", ""] + _diagnosis_table(result.diagnosis_after)
    un = result.unexplained()
    L += ["**Unexplained structured residuals:** " + ("; ".join(
        f"{u.metric} (correlates with {', '.join(u.correlates_with[:3]) or 'nothing single'})" for u in un)
        if un else "none") + ".", ""]
    if figs:
        L += ["## Time histories of the axes structured before the loop (dots recorded, grey before, blue after)", ""]
        L += [" ".join(left), ""] * bool(left) + [f"![{n}]({n})" for n in figs] + [""]
    path = out_dir / f"{REPORT}.md"
    path.write_text("\n".join(L) + "\n")
    return path


def format_result(result: CloseLoopDynamicResult) -> str:
    """Console lines: per axis and channel the RMS before -> after, what was added, what stays."""
    b, a = result.errors("before"), result.errors("after")
    lines = [f"{'axis':<6} {'channel':<10} {'RMS before':>11} {'RMS after':>10}  unit"]
    for axis, chans in b.items():
        for c, e in chans.items():
            lines.append(f"{axis:<6} {c:<10} {_f(e.rms, '11.3f')} {_f(a[axis][c].rms, '10.3f')}  {CHANNELS[c].unit}")
    lines.append(f"added: {', '.join(result.added) or 'nothing'}")
    for u in result.unexplained():
        lines.append(f"unexplained: {u.metric} correlates with {', '.join(u.correlates_with[:3]) or 'no single state'}")
    return "\n".join(lines)
