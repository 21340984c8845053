"""The Part 60 report (reports/<aircraft>/part60/): ``part60.md`` with PNG figures and one
self-contained ``part60.html`` (the same content, figures embedded as base64 PNG), and the
console's summary table. It draws a :class:`~jsbsim_calib.evaluation.part60.Part60Evaluation`; it runs
nothing.

The document is built once as blocks (headings, paragraphs, lists, tables, figures) and
rendered to Markdown and to HTML, so both say the same.
"""
from __future__ import annotations

import base64
import html
import io
import math
import re
from dataclasses import dataclass, field
from importlib.metadata import version
from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from ..data.part60_tests import FAIL, NA, PASS  # noqa: E402
from ..evaluation.part60 import CaseResult, ObjectiveTest, Part60Evaluation, TracePlot  # noqa: E402

JSBSIM_VERSION = version("jsbsim")
CONVENTIONS = (
    "Errors are model - flight test. Surfaces are in the data's signs (elevator + trailing edge up, aileron "
    "+ right aileron trailing edge up, rudder + trailing edge right); ISA (the flight test recorded no "
    "temperature).",
    "Where Part 60 gives two tolerances joined by 'or', the less restrictive one applies. A model value that is "
    "not a number (no trim, no oscillation found) is a FAIL, never a PASS.",
    "Time histories: the inputs of the axes a test examines are replayed open loop from the model's trim at the "
    "recorded initial condition; axes the record's pilot flew closed loop are flown by the model's test pilot "
    "(their surfaces are then model outputs); the model is sampled at the flight test's times.",
    "Verdicts: PASS or FAIL against the tolerance; n/a with its reason where the model cannot do the test, the "
    "files hold no data for it, or the tolerance is the evaluator's (representative; correct trend and magnitude "
    "once the trend is right).",
)


# --------------------------------------------------------------------------- blocks
@dataclass(frozen=True)
class Heading:
    level: int
    text: str


@dataclass(frozen=True)
class Para:
    text: str


@dataclass(frozen=True)
class Bullets:
    items: tuple[str, ...]


@dataclass(frozen=True)
class Table:
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    align: str = ""                       # one of l/r per column ("" : all left)
    links: tuple[str, ...] = ()           # HTML: per row, the heading its first cell links to ("": none)


@dataclass(frozen=True)
class FigureBlock:
    name: str                             # PNG file name
    caption: str
    png: bytes = field(repr=False, default=b"")


Block = Heading | Para | Bullets | Table | FigureBlock


# --------------------------------------------------------------------------- formatting
def num(x) -> str:
    """A table number: '-' for a missing value, 'NaN' never hidden behind a blank."""
    if x is None:
        return "-"
    x = float(x)
    if math.isnan(x):
        return "-"
    if math.isinf(x):
        return "inf"
    if abs(x) >= 1000:
        return f"{x:.0f}"
    if abs(x) < 5e-4:
        return "0"
    return np.format_float_positional(x, precision=3, unique=False, fractional=False, trim="-")


def verdict_text(v: str, markdown: bool = True) -> str:
    return f"**{v}**" if (markdown and v == FAIL) else v


def safe(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_").lower()


# --------------------------------------------------------------------------- figures
def trace_plot(p: TracePlot, ax=None) -> Figure:
    """A time-history plot: flight test (black), model (blue), the tolerance band (green)
    around the flight test or a target box, vertical marks (input, T_i, ...)."""
    if ax is None:
        fig = Figure(figsize=(7.0, 3.2), dpi=100)
        ax = fig.add_subplot(111)
    else:
        fig = ax.figure
    t = np.asarray(p.time_s, float)
    if p.flight_test is not None:
        ft = np.asarray(p.flight_test, float)
        if p.band:
            ax.fill_between(t, ft - p.band, ft + p.band, color="tab:green", alpha=0.18, lw=0,
                            label=f"tolerance +-{p.band:.3g}")
        ax.plot(t, ft, color="k", lw=1.3, label="flight test")
    if p.target is not None:
        t0, t1, lo, hi = p.target
        ax.fill_between([t0, t1], [lo, lo], [hi, hi], color="tab:green", alpha=0.18, lw=0,
                        label="flight-test value +- tolerance")
    if p.model is not None:
        ax.plot(t, np.asarray(p.model, float), color="tab:blue", lw=1.3, label="model")
    for k, (tm, label) in enumerate(p.marks):
        ax.axvline(tm, color="tab:gray", ls=":", lw=0.9)
        ax.annotate(f" {label}", xy=(tm, 0.98 - 0.08 * k), xycoords=("data", "axes fraction"), fontsize=7,
                    ha="left", va="top")
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"{p.channel} [{p.unit}]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    ax.set_title(p.title, fontsize=9)
    return fig


def png_bytes(fig: Figure) -> bytes:
    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png", metadata={"Software": None})
    return buf.getvalue()


# --------------------------------------------------------------------------- the document
IMPOSSIBLE = "Tests the model cannot do"


def section_title(t: ObjectiveTest) -> str:
    """The heading of a test's section (the list of tests the model cannot do for those)."""
    return IMPOSSIBLE if t.test.not_possible else f"{t.test.id} {t.test.title}"


def anchor(heading: str) -> str:
    """An HTML id for a heading: lower case, letters, digits and hyphens (GitHub's way)."""
    return re.sub(r"[^a-z0-9_ -]", "", heading.lower()).strip().replace(" ", "-")


def summary_table(ev: Part60Evaluation, markdown: bool = True) -> Table:
    """One row per test; in the HTML page each row's test links to its section."""
    rows = tuple((t.test.id, t.test.title, t.test.level, verdict_text(t.verdict, markdown), t.reason)
                 for t in ev.tests)
    return Table(("Part 60", "test", "level", "verdict", "reason"), rows,
                 links=tuple(anchor(section_title(t)) for t in ev.tests))


def _case_tables(c: CaseResult) -> list[Block]:
    out: list[Block] = []
    if c.initial:
        out += [Para("Initial condition (flight test vs the model's trim):"),
                Table(("quantity", "unit", "flight test", "model"),
                      tuple((r.quantity, r.unit, num(r.flight_test), num(r.model)) for r in c.initial), "llrr")]
    if c.metrics:
        out += [Table(("metric", "unit", "flight test", "model", "error", "tolerance", "verdict"),
                      tuple((m.label, m.unit, m.flight_test_text or num(m.flight_test), num(m.model), num(m.error),
                             m.tolerance, verdict_text(m.verdict) + (f" ({m.reason})" if m.reason else ""))
                            for m in c.metrics), "llrrrll")]
    if c.errors:
        out += [Para("Channel errors over the record (model - flight test):"),
                Table(("channel", "unit", "samples", "RMSE", "max abs", "bias"),
                      tuple((e.channel, e.unit, str(e.n), num(e.rmse), num(e.max_abs), num(e.bias))
                            for e in c.errors), "llrrrr")]
    return out


def case_blocks(t: ObjectiveTest, c: CaseResult, k: int) -> list[Block]:
    out: list[Block] = [Heading(3, f"{c.case}: {verdict_text(c.verdict)}"), Para(f"{c.source}: {c.title}")]
    if c.failure:
        out.append(Para(f"Not flown: {c.failure}"))
    if c.assumptions:
        out += [Para("Assumptions:"), Bullets(tuple(c.assumptions))]
    out += _case_tables(c)
    for j, p in enumerate(c.plots):
        name = f"{safe(t.test.id)}_{k}_{safe(p.channel)}_{j}.png"
        out.append(FigureBlock(name, f"{c.case}: {p.title}", png_bytes(trace_plot(p))))
    return out


def section_blocks(t: ObjectiveTest) -> list[Block]:
    s = t.test
    out: list[Block] = [Heading(2, section_title(t)),
                        Para(f"Level {s.level}; flight conditions: {s.conditions}. Verdict: "
                             f"{verdict_text(t.verdict)}" + (f" ({t.reason})" if t.reason else "") + ".")]
    if s.note:
        out.append(Para(f"Note: {s.note}."))
    if s.metrics:
        out.append(Bullets(tuple(f"{m.label}: {m.tolerance.text()}" for m in s.metrics)))
    for k, c in enumerate(t.cases):
        out += case_blocks(t, c, k)
    return out


def document(ev: Part60Evaluation, command: str) -> list[Block]:
    n = ev.counts()
    blocks: list[Block] = [
        Heading(1, f"{ev.aircraft}: FAA Part 60 Level 5 FTD objective tests"),
        Para(f"Generated by `{command}` (jsbsim-calib, JSBSim {JSBSIM_VERSION}). Sources: "
             + (", ".join(f"`{Path(s).name}`" for s in ev.sources) or "none") + "."),
        Bullets(CONVENTIONS),
        Heading(2, "Summary"),
        Para(f"{n[PASS]} PASS, {n[FAIL]} FAIL, {n[NA]} n/a of {len(ev.tests)} tests."),
        summary_table(ev),
    ]
    impossible = [t for t in ev.tests if t.test.not_possible]
    if impossible:
        blocks += [Heading(2, IMPOSSIBLE),
                   Bullets(tuple(f"{t.test.id} {t.test.title}: {t.test.not_possible}" for t in impossible))]
    if ev.ignored:
        blocks += [Heading(2, "Files and records not used"), Bullets(tuple(ev.ignored))]
    for t in ev.tests:
        if not t.test.not_possible:
            blocks += section_blocks(t)
    return blocks


# --------------------------------------------------------------------------- rendering
def _md_table(b: Table) -> list[str]:
    def cell(s: str) -> str:
        return str(s).replace("|", "\\|").replace("\n", " ")
    align = b.align or "l" * len(b.header)
    sep = "|" + "|".join("---:" if a == "r" else "---" for a in align) + "|"
    return ["| " + " | ".join(map(cell, b.header)) + " |", sep] + \
        ["| " + " | ".join(map(cell, r)) + " |" for r in b.rows] + [""]


def to_markdown(blocks: Sequence[Block]) -> str:
    out: list[str] = []
    for b in blocks:
        if isinstance(b, Heading):
            out += ["#" * b.level + " " + b.text, ""]
        elif isinstance(b, Para):
            out += [b.text, ""]
        elif isinstance(b, Bullets):
            out += [f"* {i}" for i in b.items] + [""]
        elif isinstance(b, Table):
            out += _md_table(b)
        elif isinstance(b, FigureBlock):
            out += [f"![{b.caption}]({b.name})", ""]
    return "\n".join(out)


def _inline(text: str) -> str:
    """Escape, then the two Markdown marks the blocks use: **bold** and `code`."""
    t = html.escape(text)
    t = re.sub(r"\*\*(.+?)\*\*", r'<b class="fail">\1</b>', t)
    return re.sub(r"`(.+?)`", r"<code>\1</code>", t)


def _html_table(b: Table) -> str:
    align = b.align or "l" * len(b.header)
    cls = lambda k: ' class="r"' if align[k] == "r" else ""
    head = "".join(f"<th{cls(k)}>{_inline(h)}</th>" for k, h in enumerate(b.header))
    link = lambda i, k, text: (f'<a href="#{b.links[i]}">{text}</a>' if k == 0 and i < len(b.links) and b.links[i]
                               else text)
    body = "".join("<tr>" + "".join(f"<td{cls(k)}>{link(i, k, _inline(c))}</td>" for k, c in enumerate(r)) + "</tr>"
                   for i, r in enumerate(b.rows))
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


STYLE = ("body{font-family:sans-serif;max-width:1100px;margin:2em auto;line-height:1.4}"
         "table{border-collapse:collapse;margin:0.5em 0 1em}td,th{border:1px solid #ccc;padding:2px 6px;"
         "font-size:90%}th{background:#eee}.r{text-align:right}.fail{color:#b00}"
         "figure{margin:0.5em 0}figcaption{font-size:85%;color:#444}img{max-width:100%}")


def to_html(blocks: Sequence[Block], title: str) -> str:
    """One self-contained page: styles inline, figures as data: URIs."""
    out = [f"<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>{html.escape(title)}</title>"
           f"<style>{STYLE}</style></head><body>"]
    for b in blocks:
        if isinstance(b, Heading):
            ident = f' id="{anchor(b.text)}"' if b.level == 2 else ""
            out.append(f"<h{b.level}{ident}>{_inline(b.text)}</h{b.level}>")
        elif isinstance(b, Para):
            out.append(f"<p>{_inline(b.text)}</p>")
        elif isinstance(b, Bullets):
            out.append("<ul>" + "".join(f"<li>{_inline(i)}</li>" for i in b.items) + "</ul>")
        elif isinstance(b, Table):
            out.append(_html_table(b))
        elif isinstance(b, FigureBlock):
            data = base64.b64encode(b.png).decode("ascii")
            out.append(f"<figure><img alt=\"{html.escape(b.caption)}\" src=\"data:image/png;base64,{data}\">"
                       f"<figcaption>{html.escape(b.caption)}</figcaption></figure>")
    out.append("</body></html>")
    return "\n".join(out) + "\n"


@dataclass(frozen=True)
class Part60Files:
    markdown: Path
    html: Path
    figures: tuple[Path, ...]


def write_part60_report(ev: Part60Evaluation, out_dir: Path, command: str = "") -> Part60Files:
    """reports/<aircraft>/part60/: part60.md, its PNGs, and the self-contained part60.html."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    blocks = document(ev, command or f"jsbsim-calib part60 {ev.aircraft}")
    figures = []
    for b in blocks:
        if isinstance(b, FigureBlock):
            (out_dir / b.name).write_bytes(b.png)
            figures.append(out_dir / b.name)
    md = out_dir / "part60.md"
    md.write_text(to_markdown(blocks))
    page = out_dir / "part60.html"
    page.write_text(to_html(blocks, f"{ev.aircraft}: Part 60 objective tests"))
    return Part60Files(md, page, tuple(figures))


def format_part60_table(ev: Part60Evaluation, width: int = 90) -> str:
    """The summary table for the console (the reason cut to fit)."""
    lines = [f"{'Part 60':<14} {'verdict':<7} {'test':<44} reason"]
    for t in ev.tests:
        reason = t.reason if len(t.reason) <= width else t.reason[:width - 3] + "..."
        lines.append(f"{t.test.id:<14} {t.verdict:<7} {t.test.title[:44]:<44} {reason}")
    n = ev.counts()
    lines.append(f"{n[PASS]} PASS, {n[FAIL]} FAIL, {n[NA]} n/a of {len(ev.tests)} tests")
    return "\n".join(lines)
