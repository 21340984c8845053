"""The close-loop report's section on synthesized terms (:mod:`jsbsim_calib.calibration.synthesis`):
what each attempt worked on, what it selected, how the terms fared, and in words what an added
term means and where it sits in the aircraft file. Text only; :func:`synthesis_section` returns
Markdown lines for :func:`jsbsim_calib.report.markdown.write_close_loop_report`."""
from __future__ import annotations

import math

from ..calibration.synthesis import EFFECT_PREFIX


def _num(x) -> str:
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:.4g}"


def _attempt_rows(rec) -> list[str]:
    decision = "**added**" if rec.accepted else (rec.reason or "rejected")
    if not rec.terms:
        return [f"| {rec.round} | {', '.join(rec.metrics) or '-'} | {', '.join(rec.axes) or '-'} | {rec.candidates} | "
                f"nothing | | | | | | {decision} |"]
    cv = f"{rec.cv[0]:.3g} -> {rec.cv[1]:.3g}" if rec.cv else "-"
    out = []
    for k, t in enumerate(rec.terms):
        head = (f"| {rec.round} | {', '.join(rec.metrics)} | {', '.join(rec.axes)} | {rec.candidates} | " if k == 0
                else "| | | | | ")
        tail = f" {rec.p_null:.3f} | {cv} | {decision} |" if k == 0 else " | | |"
        out.append(head + f"{t['coefficient']} ~ {t['regressor']} | {_num(t['estimate'])} | {_num(t['fitted'])} | "
                   f"{_num(t['final'])} {t['unit'] if t['unit'] != '-' else ''} |" + tail)
    return out


def _meanings(result) -> list[str]:
    out = []
    for rec in result.synthesized:
        if not rec.accepted:
            continue
        for t in rec.terms:
            unit = "" if t["unit"] == "-" else f" {t['unit']}"
            out.append(f"* **{t['coefficient']} ~ {t['regressor']} = {_num(t['final'])}{unit}**: {t['interpretation']}. "
                       f"In the aircraft: `<function name=\"aero/effects/{EFFECT_PREFIX}{t['term']}-...\">` in "
                       f"`<axis name=\"{t['axis']}\">`, its factor the persistent property "
                       f"`calibration/effects/{EFFECT_PREFIX}{t['term']}` (system `effect: {rec.effect}`): edit the "
                       f"value, or delete the function, to change or remove it.")
    return out


def synthesis_section(result) -> list[str]:
    """Markdown lines: the synthesized terms of a :class:`~jsbsim_calib.calibration.closeloop.CloseLoopResult`."""
    L = ["## Synthesized terms", "",
         "When no library effect passed and structure remained, candidate terms Delta C = K x (regressor) of the "
         "axes the structured metrics reveal were added to a copy of the aircraft and linearized by JSBSim (each "
         "coefficient stepped, every point re-trimmed); sequential thresholded least squares on the noise-weighted "
         "sensitivities selected the sparsest set (extended BIC); the set was then fitted in JSBSim with the fit "
         "engine and judged by the library's rules, plus a null test of the selection (the same selection on "
         "residuals shuffled among the points with random signs) and a cross-validation that repeats the selection "
         "in every fold.", ""]
    if not result.synthesized:
        return L + ["No synthesis was needed: " + ("the library explained the structure." if result.added
                                                    else "no structured residual remained."), ""]
    L += ["| round | structured | axes | terms tried | selected | estimate (linearized) | fitted | after refit | "
          "null test p | cross-validated RSS | decision |",
          "|---:|---|---|---:|---|---:|---:|---:|---:|---|---|"]
    for rec in result.synthesized:
        L += _attempt_rows(rec)
    L += [""]
    meanings = _meanings(result)
    L += (["**What the added terms mean:**", ""] + meanings) if meanings else ["**Added:** no synthesized term."]
    return L + [""]
