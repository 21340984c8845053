"""The flight card of a plan (``jsbsim-calib plan``): a page a pilot can fly from.

Per maneuver: why it is flown (the standard errors it is predicted to leave), the conditions,
the inputs (surfaces in the flight test's signs and words), what the pilot holds, the
excursions the model predicts and the limits to stop at, and a drawing of the input with
the predicted response. Written as Markdown with PNG figures beside it and as one
self-contained HTML file (the figures embedded).
"""
from __future__ import annotations

import base64
import html
import math
from pathlib import Path

from matplotlib.figure import Figure

from ..synthetic.design import ENVELOPE, MIN_SPEED_SHARE, Pick, Proposal
from ..synthetic.maneuvers import InputSpec, ManeuverSpec, file_stem_of, input_shape
from .plots import save

SIGN_WORDS = {"elevator_deg": ("trailing edge up (nose up)", "trailing edge down (nose down)"),
              "aileron_deg": ("right wing down (roll right)", "left wing down (roll left)"),
              "rudder_deg": ("right pedal (nose right)", "left pedal (nose left)"),
              "throttle_norm": ("throttle forward", "throttle back"), "flaps_deg": ("flaps down", "flaps up")}
SHAPE_WORDS = {"pulse": "pulse", "step": "step", "doublet": "doublet", "3211": "3-2-1-1", "multisine": "multisine"}
LOOP_WORDS = {"pitch": "hold the pitch attitude", "altitude": "hold the altitude", "bank": "hold the bank angle",
              "sideslip": "hold the sideslip", "heading": "hold the heading", "airspeed": "hold the airspeed"}
RESPONSE = {"elevator_deg": ("q_deg_s", "pitch_deg"), "aileron_deg": ("p_deg_s", "roll_deg"),
            "rudder_deg": ("r_deg_s", "beta_deg")}


def _unit(channel: str) -> str:
    return "" if channel == "throttle_norm" else " deg"


def input_words(i: InputSpec) -> str:
    """An input as a pilot reads it."""
    surface = i.channel.split("_")[0]
    way = SIGN_WORDS[i.channel][0 if i.amplitude >= 0 else 1]
    amp = f"{abs(i.amplitude):g}{_unit(i.channel)} {way}"
    if i.shape == "multisine":
        amp = f"peak {abs(i.amplitude):g}{_unit(i.channel)} either way"
        timing = (f"for {i.length_s:g} s from t = {i.start_s:g} s, frequencies {i.band_hz[0]:g}-{i.band_hz[1]:g} Hz "
                  "(follow the drawn trace; a flight-test input box plays it best)")
    elif i.shape == "3211":
        timing = (f"at t = {i.start_s:g} s: steps of 3, 2, 1 and 1 units of {i.length_s:g} s, alternating "
                  "direction, starting as stated")
    elif i.shape == "doublet":
        timing = f"at t = {i.start_s:g} s: {i.length_s:g} s one way, then {i.length_s:g} s the other"
    elif i.shape == "step" and i.length_s is None:
        timing = f"at t = {i.start_s:g} s, held to the end"
    else:
        timing = f"at t = {i.start_s:g} s, held {i.length_s:g} s"
    return f"{SHAPE_WORDS[i.shape]} of the {surface}: {amp}; {timing}; ramps of {i.ramp_s:g} s"


def _conditions(m: ManeuverSpec) -> list[tuple[str, str]]:
    c = m.start
    speed = f"{c.kcas:g} KCAS" if c.kcas is not None else f"{c.ktas:g} KTAS"
    power = f"throttle {c.throttle:g}, path free" if c.mode == "full_throttle" else \
        "trimmed for level flight, then the throttle left where it is"
    rows = [("pressure altitude", f"{c.pressure_alt_ft:,.0f} ft"), ("airspeed", speed), ("flaps", f"{c.flaps_deg:g} deg"),
            ("weight", f"{c.weight_lb:,.0f} lb"), ("CG", f"{c.cg_in:g} in aft of datum"), ("power", power),
            ("mixture", str(c.mixture))]
    if c.bank_deg:
        rows.append(("bank", f"{c.bank_deg:g} deg, coordinated turn"))
    return rows


def _pilot(m: ManeuverSpec) -> list[str]:
    out = []
    for h in m.holds:
        what = LOOP_WORDS[h.loop]
        if h.target is not None:
            what += f" at {h.target:g}"
        elif h.offset is not None:
            what += f" at trim {h.offset:+g}"
        end = f" to {h.end_s:g} s" if math.isfinite(h.end_s) else " to the end"
        out.append(f"{what}, from {h.start_s:g} s{end}")
    return out or ["hands off the held axes: the inputs only (open loop)"]


def _excursions(p: Pick) -> list[tuple[str, str]]:
    t = p.scored.trajectory
    rows = [("bank", "roll_deg", "deg"), ("pitch", "pitch_deg", "deg"), ("load factor", "nz_g", "g"),
            ("airspeed", "kcas", "KCAS"), ("angle of attack", "alpha_deg", "deg"), ("sideslip", "beta_deg", "deg")]
    return [(words, f"{t[c].min():.3g} to {t[c].max():.3g} {unit}") for words, c, unit in rows]


def _limits() -> list[str]:
    words = {"roll_deg": "bank", "nz_g": "load factor", "alpha_deg": "angle of attack", "beta_deg": "sideslip"}
    out = [f"{words[c]} outside {lo:g} to {hi:g}" for c, (lo, hi) in ENVELOPE.items()]
    out.append(f"airspeed below {MIN_SPEED_SHARE:.0%} of the start speed")
    return out


def maneuver_figure(p: Pick) -> Figure:
    """The inputs as designed (the flight test's signs) over the predicted response."""
    m, t = p.scored.candidate.spec, p.scored.trajectory
    fig = Figure(figsize=(7.0, 4.6), dpi=100)
    ax1, ax2 = fig.add_subplot(211), fig.add_subplot(212)
    for i in m.inputs:
        length = i.length_s if i.length_s is not None else m.duration_s
        times, values = input_shape(i, i.start_s, length, i.amplitude)
        times, values = [*times, m.duration_s], [*values, values[-1]]
        ax1.plot(times, values, lw=1.6, label=f"{i.channel} ({SIGN_WORDS[i.channel][0].split(' (')[0]} +)")
    ax1.set_ylabel("input [deg]")
    if m.inputs:
        ax1.legend(fontsize=8, loc="upper right")
    else:
        ax1.text(0.5, 0.5, "no open-loop input: the pilot's loops fly it", ha="center", transform=ax1.transAxes)
    ax1.grid(alpha=0.3)
    axes = RESPONSE.get(m.inputs[0].channel, ("q_deg_s", "pitch_deg")) if m.inputs else ("q_deg_s", "pitch_deg")
    for c in axes:
        ax2.plot(t.time_s, t[c], lw=1.3, label=f"{c} (model)")
    ax2.set_xlabel("time from the start of the maneuver [s]")
    ax2.set_ylabel("predicted response [deg, deg/s]")
    ax2.legend(fontsize=8, loc="upper right")
    ax2.grid(alpha=0.3)
    ax1.set_title(f"{m.id}: {m.title}", fontsize=9)
    fig.tight_layout()
    return fig


def _sections(proposal: Proposal) -> list[dict]:
    out = []
    for k, p in enumerate(proposal.picks, 1):
        m = p.scored.candidate.spec
        se = ", ".join(f"{n} {proposal.se_in_hand[n]:.3g} -> {p.se_after[n]:.3g}" for n in proposal.targets)
        out.append({"number": k, "spec": m, "stem": file_stem_of(m), "why": p.scored.candidate.source,
                    "se": se, "conditions": _conditions(m), "inputs": [input_words(i) for i in m.inputs],
                    "pilot": _pilot(m), "excursions": _excursions(p)})
    return out


def _intro(proposal: Proposal) -> list[str]:
    se = ", ".join(f"{n} +/- {proposal.se_in_hand[n]:.3g}" for n in proposal.targets)
    return [f"Aircraft `{proposal.aircraft}`. Data in hand: {proposal.evidence}.",
            (f"The loosest factors now: {se} (one standard error). Each maneuver below is the one that most "
             "shrinks them, given the data in hand and the maneuvers above it; the standard errors after it "
             "are predicted by the model, assuming the new records are explained to their sensor noise."),
            (f"Candidates flown on the model: {proposal.tried}; left out: {len(proposal.dropped)} (they break a "
             "limit below, do not trim, or their records would not replay faithfully: the list at the end). Fly "
             "each maneuver from steady, trimmed flight at its conditions; time 0 is the start of the record."),
            "Stop the maneuver and recover if: " + "; ".join(_limits()) + "."]


def markdown(proposal: Proposal, figure_names: dict[str, str]) -> str:
    lines = [f"# Flight card: {proposal.aircraft}, {len(proposal.picks)} maneuvers", ""]
    lines += [x + "\n" for x in _intro(proposal)]
    for s in _sections(proposal):
        m = s["spec"]
        lines += [f"## {s['number']}. {m.id}: {m.title}", "", f"*Why:* {s['why']}. *Standard errors after it:* {s['se']}.",
                  "", f"Duration {m.duration_s:g} s (Part 60: {m.part60}).", "", "| condition | value |", "|---|---|"]
        lines += [f"| {a} | {b} |" for a, b in s["conditions"]]
        lines += ["", "**Inputs**", ""] + [f"- {x}" for x in s["inputs"]]
        lines += ["", "**Pilot**", ""] + [f"- {x}" for x in s["pilot"]]
        lines += ["", "**Predicted by the model**", "", "| quantity | range |", "|---|---|"]
        lines += [f"| {a} | {b} |" for a, b in s["excursions"]]
        lines += ["", f"![{m.id}]({figure_names[m.id]})", ""]
    if proposal.dropped:
        lines += ["## Candidates left out", "", "| candidate | why |", "|---|---|"]
        lines += [f"| {c} | {why} |" for c, why in proposal.dropped]
    return "\n".join(lines) + "\n"


STYLE = ("body{font-family:sans-serif;max-width:52em;margin:2em auto;line-height:1.4}"
         "table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #999;padding:.2em .6em}"
         "section{border-top:2px solid #333;margin-top:2em}img{max-width:100%}")


def _table(rows) -> str:
    return "<table>" + "".join(f"<tr><td>{html.escape(a)}</td><td>{html.escape(b)}</td></tr>" for a, b in rows) + "</table>"


def _items(xs) -> str:
    return "<ul>" + "".join(f"<li>{html.escape(x)}</li>" for x in xs) + "</ul>"


def html_page(proposal: Proposal, figures: dict[str, bytes]) -> str:
    """One self-contained page: the figures embedded as PNG data."""
    e = html.escape
    body = [f"<h1>Flight card: {e(proposal.aircraft)}, {len(proposal.picks)} maneuvers</h1>"]
    body += [f"<p>{e(x)}</p>" for x in _intro(proposal)]
    for s in _sections(proposal):
        m = s["spec"]
        png = base64.b64encode(figures[m.id]).decode()
        body += [f"<section><h2>{s['number']}. {e(m.id)}: {e(m.title)}</h2>",
                 f"<p><em>Why:</em> {e(s['why'])}. <em>Standard errors after it:</em> {e(s['se'])}.</p>",
                 f"<p>Duration {m.duration_s:g} s (Part 60: {e(m.part60)}).</p>", _table(s["conditions"]),
                 "<h3>Inputs</h3>", _items(s["inputs"]), "<h3>Pilot</h3>", _items(s["pilot"]),
                 "<h3>Predicted by the model</h3>", _table(s["excursions"]),
                 f'<img alt="{e(m.id)}" src="data:image/png;base64,{png}"></section>']
    if proposal.dropped:
        body += ["<section><h2>Candidates left out</h2>", _table(proposal.dropped), "</section>"]
    return ("<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>Flight card</title>"
            f"<style>{STYLE}</style></head><body>" + "\n".join(body) + "</body></html>\n")


def write_flight_card(proposal: Proposal, out_dir: Path | str) -> dict[str, Path]:
    """flight_card.md with its PNGs, and flight_card.html (self-contained), in ``out_dir``; the
    figures of an earlier card there are removed (a new plan picks other maneuvers)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    for old in out_dir.glob("flight_card_*.png"):
        old.unlink()
    names, pngs = {}, {}
    for p in proposal.picks:
        m = p.scored.candidate.spec
        names[m.id] = f"flight_card_{file_stem_of(m)}.png"
        save(maneuver_figure(p), out_dir / names[m.id])
        pngs[m.id] = (out_dir / names[m.id]).read_bytes()
    md, page = out_dir / "flight_card.md", out_dir / "flight_card.html"
    md.write_text(markdown(proposal, names))
    page.write_text(html_page(proposal, pngs))
    return {"markdown": md, "html": page}
