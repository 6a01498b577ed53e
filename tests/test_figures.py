"""Figures that cannot go stale: every figure of the docs and the README carries a provenance stamp
(:mod:`kornia_ilum_lab.provenance`), and the code and data it shows are those of this commit."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from kornia_ilum_lab.provenance import figure_problems, read_stamp

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
#: Folders of the docs that the build writes (sphinx-gallery's output and the build itself): not committed.
BUILT = ("_build", "auto_examples")


def committed_figures() -> list[Path]:
    """Every PNG and JPEG under docs/ (but the build's outputs), and every image the README shows."""
    found = {p for ext in ("*.png", "*.jpg", "*.jpeg") for p in DOCS.rglob(ext)
             if not any(part in BUILT for part in p.relative_to(DOCS).parts)}
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    found |= {ROOT / m for m in re.findall(r"!\[[^\]]*\]\(([^)\s]+)\)", readme) if not m.startswith("http")}
    return sorted(found)


def test_there_are_figures_and_the_readme_shows_existing_ones():
    figures = committed_figures()
    assert len(figures) >= 10
    missing = [str(p.relative_to(ROOT)) for p in figures if not p.is_file()]
    assert not missing, f"the README shows figures that do not exist: {missing}"


@pytest.mark.parametrize("figure", committed_figures(), ids=lambda p: str(p.relative_to(ROOT)))
def test_every_figure_was_made_by_this_code(figure):
    problems = figure_problems(figure)
    assert not problems, "\n".join(problems)


def test_a_stale_figure_fails(tmp_path):
    """The check fails on a figure made by another version of the code it shows, and on changed data."""
    current = next(p for p in committed_figures() if read_stamp(p) and read_stamp(p)["shows"])
    stale = tmp_path / current.name
    shutil.copyfile(current, stale)
    stamp = read_stamp(stale)
    module = next(iter(stamp["shows"]))
    # the same figure, stamped as made by other code: rewrite the fingerprint it records
    data = stale.read_bytes().replace(stamp["shows"][module].encode(), b"0" * 64)
    stale.write_bytes(data)
    problems = figure_problems(stale)
    assert problems and f"another version of {module}" in problems[0] and stamp["command"] in problems[0]
