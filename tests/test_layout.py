"""The package's layout (issue 26, item 3; docs/architecture.md): folders on floors, each importing
only the floors below it; no module imports another in a cycle; no two modules share a name;
the top level holds only the command line, the generator and the factors.

Imports are read from the source (every ``import`` and ``from ... import``, those inside
functions too), so the check needs no module to be imported.
"""
from __future__ import annotations

import ast
from collections import Counter
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "jsbsim_calib"

# bottom to top: a room imports only rooms on lower floors (and itself)
FLOORS = (
    ("core",),
    ("factors", "physics"),
    ("flight",),
    ("jsbsim",),
    ("data", "export", "generate"),
    ("evaluation",),
    ("calibration",),
    ("synthetic",),
    ("report",),
    ("cli",),
)
FLOOR = {room: k for k, rooms in enumerate(FLOORS) for room in rooms}
TOP_MODULES = {"__init__.py", "cli.py", "factors.py", "generate.py"}


def _module(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module(p): p for p in PACKAGE.rglob("*.py")}


def _imports(name: str, path: Path) -> set[str]:
    """The package's modules that ``name`` imports (a package where a name is not a module)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = package.split(".")[:len(package.split(".")) - node.level + 1] if node.level else []
            target = ".".join(base + ([node.module] if node.module else []))
            out |= {f"{target}.{a.name}" if f"{target}.{a.name}" in MODULES else target for a in node.names}
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
    return {m for m in out if m in MODULES and m != name}


GRAPH = {name: _imports(name, path) for name, path in MODULES.items()}


def _room(module: str) -> str | None:
    """The folder (or top-level module) a module belongs to; None for the package itself."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def test_the_top_level_holds_only_the_command_line_the_generator_and_the_factors():
    assert {p.name for p in PACKAGE.glob("*.py")} == TOP_MODULES
    rooms = {p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").is_file()}
    rooms |= {Path(m).stem for m in TOP_MODULES - {"__init__.py"}}
    assert rooms == set(FLOOR), "every folder of the package stands on a floor of FLOORS"


def test_no_two_modules_share_a_name():
    names = Counter(p.stem for p in PACKAGE.rglob("*.py") if p.name != "__init__.py")
    assert not [n for n, k in names.items() if k > 1]


def test_every_room_imports_only_the_floors_below_it():
    """The package itself (``from .. import __version__``) may be imported from anywhere: it
    defines nothing else."""
    up = [f"{a} -> {b}" for a, targets in GRAPH.items() for b in targets
          if _room(a) and _room(b) and _room(a) != _room(b) and FLOOR[_room(b)] >= FLOOR[_room(a)]]
    assert not up


def test_no_module_imports_another_in_a_cycle():
    seen: dict[str, int] = {}          # 1: on the path, 2: done

    def visit(m: str, path: list[str]) -> list[str] | None:
        seen[m] = 1
        for n in sorted(GRAPH[m]):
            if seen.get(n) == 1:
                return path[path.index(n):] + [n] if n in path else [m, n]
            if n not in seen and (cycle := visit(n, path + [n])):
                return cycle
        seen[m] = 2
        return None

    for m in sorted(GRAPH):
        if m not in seen:
            assert (cycle := visit(m, [m])) is None, " -> ".join(cycle)
