"""The documentation (issue 26): the README stays short and names the test command CI runs, the
CLI reference is the parser's, every page of the mkdocs site exists, the LICENSE is MIT."""
from __future__ import annotations

import re
import runpy
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
README = (REPO / "README.md").read_text()


def test_readme_is_at_most_200_lines_and_names_the_ci_test_command():
    assert len(README.splitlines()) <= 200
    ci = (REPO / ".ci" / "run").read_text()
    command = re.search(r"^# README test command:\n(.+)$", ci, re.M).group(1).strip()
    assert f"    {command}\n" in README
    assert "python -m pip install -e '.[dev,airfoils]'" in README and "mkdocs build --strict" in ci


def test_the_cli_reference_is_the_parser():
    gen = runpy.run_path(str(REPO / "docs" / "gen_cli.py"))
    assert (REPO / "docs" / "cli.md").read_text() == gen["render"](), "run: python docs/gen_cli.py"


def test_every_page_of_the_site_exists_and_readme_links_resolve():
    nav = re.findall(r":\s*([\w-]+\.md)\s*$", (REPO / "mkdocs.yml").read_text(), re.M)
    assert len(nav) >= 12 and all((REPO / "docs" / page).is_file() for page in nav)
    for link in re.findall(r"\]\(((?:docs/|examples/)?[\w./-]+\.(?:md|py))\)", README):
        assert (REPO / link).is_file(), link
    assert (REPO / "LICENSE").read_text().startswith("MIT License")
