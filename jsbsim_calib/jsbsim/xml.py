"""JSBSim's XML vocabulary: elements, fixed-precision numbers, the function language, and
reading and writing files. The only module of the workbench that imports lxml.

Numbers in generated files have a fixed precision (README, "Reproducible bytes"): scalars
:data:`NUMBER_DIGITS` significant digits; every table :data:`TABLE_DIGITS` significant
digits of its largest entry, the same decimals for all its entries (an absolute precision,
so that entries near zero, which carry the round-off of the larger terms they are sums of,
are not written to more digits than their neighbours); factor values
:data:`FACTOR_DIGITS`. Never an exponent.

Files are written atomically (a temporary file beside the target, then ``os.replace``), and
a file that already holds the bytes is left alone.
"""
from __future__ import annotations

import math
import os
import uuid
from copy import deepcopy
from decimal import Decimal
from pathlib import Path
from typing import Sequence

import numpy as np
from lxml import etree

from ..core.errors import ModelError
from ..core.units import IN

NUMBER_DIGITS = 6
TABLE_DIGITS = 6
FACTOR_DIGITS = 10          # factor values: what calibration.json records

Element = etree._Element
Tree = etree._ElementTree


# --------------------------------------------------------------------------- numbers
def fmt(x: float, digits: int = NUMBER_DIGITS) -> str:
    """``x`` to ``digits`` significant digits in plain notation (same bytes on every run)."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"cannot write {x} into a JSBSim file")
    if x == 0.0:
        return "0"
    return _plain(f"{x:.{digits}g}")


def fmt_fixed(x: float, decimals: int) -> str:
    """``x`` rounded to ``decimals`` decimal places (negative: tens, hundreds ...), plain notation."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"cannot write {x} into a JSBSim file")
    if decimals < 0:
        return _plain(f"{round(x, decimals):.0f}")
    return _plain(f"{x:.{decimals}f}")


def decimals_for(values, digits: int = TABLE_DIGITS) -> int:
    """Decimal places that give ``digits`` significant digits to the largest of ``values``."""
    top = float(np.max(np.abs(np.asarray(values, float)))) if np.size(values) else 0.0
    if top == 0.0 or not math.isfinite(top):
        return digits
    return digits - 1 - math.floor(math.log10(top))


def _plain(s: str) -> str:
    """A number string without exponent or trailing zeros; '-0' -> '0'."""
    if "e" in s or "E" in s:
        s = format(Decimal(s), "f")
    if "." in s:
        s = s.rstrip("0").rstrip(".")
    return "0" if s in ("-0", "", "-") else s


# --------------------------------------------------------------------------- elements
def element(tag: str, **attrib) -> Element:
    return etree.Element(tag, {k: str(v) for k, v in attrib.items()})


def tree(root: Element) -> Tree:
    return etree.ElementTree(root)


def sub(parent, tag: str, text: str | None = None, **attrib) -> Element:
    el = etree.SubElement(parent, tag, {k: str(v) for k, v in attrib.items()})
    if text is not None:
        el.text = f" {text} "
    return el


def comment(parent, text: str) -> None:
    parent.append(etree.Comment(f" {text} "))


def is_comment(node) -> bool:
    return isinstance(node, etree._Comment)


def comments(el):
    """The comments inside an element, in document order."""
    return el.iter(etree.Comment)


def location(parent, name: str | None, xyz_m, tag: str = "location") -> Element:
    el = sub(parent, tag, unit="IN", **({"name": name} if name else {}))
    for axis, v in zip("xyz", np.asarray(xyz_m) / IN):
        sub(el, axis, fmt(v, 5))
    return el


def data_table(parent, rows: Sequence[str], indent: str) -> Element:
    """A ``<tableData>`` of preformatted rows, closed at ``indent``."""
    td = sub(parent, "tableData")
    td.text = "\n" + "\n".join(rows) + "\n" + indent
    return td


# --------------------------------------------------------------------------- the function language
def prop(name: str) -> Element:
    el = etree.Element("property")
    el.text = f" {name} "
    return el


def value(x: float) -> Element:
    el = etree.Element("value")
    el.text = f" {fmt(x)} "
    return el


def operation(tag: str, *args: Element) -> Element:
    """``<product>``, ``<sum>``, ``<difference>``, ``<quotient>``, ``<pow>``, ``<sin>``, ``<cos>``,
    ``<max>``, ``<min>`` ... of the arguments."""
    el = etree.Element(tag)
    for a in args:
        el.append(a)
    return el


def table(row, data, row_property: str, column=None, column_property: str | None = None) -> Element:
    """A ``<table>`` over one property (``row``) or two (``row`` x ``column``)."""
    el = etree.Element("table")
    sub(el, "independentVar", row_property, lookup="row")
    if column is not None:
        sub(el, "independentVar", column_property, lookup="column")
    lines = []
    d = decimals_for(data)
    if column is not None:
        lines.append("          " + " ".join(f"{fmt(c, 5):>10}" for c in column))
        for r, row_data in zip(row, data):
            lines.append(f"{fmt(r, 5):>9} " + " ".join(f"{fmt_fixed(v, d):>10}" for v in row_data))
    else:
        for r, v in zip(row, data):
            lines.append(f"{fmt(r, 5):>9} {fmt_fixed(v, d):>12}")
    data_table(el, lines, "        ")
    return el


def function(parent, name: str, description: str, expression: Element) -> Element:
    f = sub(parent, "function", name=name)
    sub(f, "description", description)
    f.append(expression)
    return f


# --------------------------------------------------------------------------- files
def indent(tree: Tree) -> None:
    """Two-space indentation, as :func:`tostring` writes it (to hash a tree before writing it)."""
    etree.indent(tree, space="  ")


def tostring(tree: Tree, indent: bool = True) -> bytes:
    """The bytes of a file: XML declaration, UTF-8; two-space indentation (``indent``), or the
    tree's own whitespace kept as it was read (``indent=False``: a hand-formatted file keeps
    its formatting; a file this module wrote with indentation gives the same bytes)."""
    if indent:
        etree.indent(tree, space="  ")
        return etree.tostring(tree, pretty_print=True, xml_declaration=True, encoding="UTF-8")
    data = etree.tostring(tree, pretty_print=False, xml_declaration=True, encoding="UTF-8")
    return data if data.endswith(b"\n") else data + b"\n"


def element_text(el) -> str:
    """An element (or comment) as XML text, two-space indented, without what follows it."""
    if not is_comment(el):
        el = deepcopy(el)
        etree.indent(el, space="  ")
    return etree.tostring(el, encoding=str, with_tail=False)


def write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically; a file that holds them already is left alone."""
    path = Path(path)
    if path.is_file() and path.read_bytes() == data:
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        with open(tmp, "xb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def write(tree: Tree, path: Path, indent: bool = True) -> None:
    """Write a parsed file atomically; ``indent=False`` keeps its whitespace (:func:`tostring`)."""
    write_bytes(path, tostring(tree, indent))


def read(path: Path) -> Tree:
    """A parsed XML file; :class:`ModelError` when it cannot be read."""
    try:
        return etree.parse(str(path))
    except (OSError, etree.XMLSyntaxError) as exc:
        raise ModelError(f"{path}: cannot read: {exc}") from None


# what JSBSim needs of an aircraft file; without one it aborts the process (a C++ exception)
REQUIRED_SECTIONS = ("metrics", "mass_balance", "ground_reactions", "propulsion", "aerodynamics")


def structure_problems(doc: Tree, engine_dir: Path) -> list[tuple[int | None, str]]:
    """(line, what) for each thing of an aircraft file that would make JSBSim abort: not an
    ``fdm_config``, a section missing, a propulsion without an engine and its thruster, or an
    engine/thruster file that is not in ``engine_dir``."""
    root = doc.getroot()
    if root.tag != "fdm_config":
        return [(root.sourceline, f"the root element is <{root.tag}>, JSBSim needs <fdm_config>")]
    out: list[tuple[int | None, str]] = [(root.sourceline, f"no <{s}> section") for s in REQUIRED_SECTIONS
                                         if root.find(s) is None]
    prop = root.find("propulsion")
    if prop is None:
        return out
    if prop.find("engine") is None:
        out.append((prop.sourceline, "<propulsion> holds no <engine>"))
    for el in [*prop.iter("engine"), *prop.iter("thruster")]:
        f = el.get("file")
        if not f:
            out.append((el.sourceline, f"<{el.tag}> without its file attribute"))
        elif not (Path(engine_dir) / f"{f}.xml").is_file():
            out.append((el.sourceline, f"<{el.tag} file=\"{f}\">: no {f}.xml in {engine_dir}"))
    for eng in prop.iter("engine"):
        if eng.find("thruster") is None:
            out.append((eng.sourceline, "<engine> without its <thruster>"))
    return out


def parse(text: str, source: str = "") -> Element:
    """An element from XML text; :class:`ModelError` naming ``source`` when it is not well formed."""
    try:
        return etree.fromstring(text.encode())
    except etree.XMLSyntaxError as exc:
        raise ModelError(f"{source}: cannot read: {exc}") from None


def copy(tree: Tree) -> Tree:
    """An independent copy of a parsed file."""
    return deepcopy(tree)
