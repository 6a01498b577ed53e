"""Regenerate the committed figures of the docs (run from anywhere; needs matplotlib).

    python docs/_scripts/make_figures.py

``docs/_static/mappings.png``: both lighting mappings with the frame axes marked, for
``docs/conventions.rst``. Its code is the gallery example ``docs/examples/plot_mirror_ball_mapping.py``,
run here unchanged, so the page figure and the gallery never disagree.
"""

from __future__ import annotations

import runpy
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

DOCS = Path(__file__).resolve().parents[1]


def main() -> None:
    namespace = runpy.run_path(str(DOCS / "examples" / "plot_mirror_ball_mapping.py"))
    out = DOCS / "_static" / "mappings.png"
    namespace["fig"].savefig(out, dpi=100, metadata={"Software": None})
    print(f"wrote {out} ({out.stat().st_size // 1024} KiB)")


if __name__ == "__main__":
    main()
