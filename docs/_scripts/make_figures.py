"""Make the docs' figures that need no light-stage render again, each stamped with where it comes from
(:mod:`kornia_ilum_lab.provenance`; ``tests/test_figures.py`` fails on a figure that another version of the code
made). Run from anywhere; needs matplotlib.

    python docs/_scripts/make_figures.py [--only mappings preview curves bench]

Writes into ``docs/_static/``:

- ``mappings.png``: both lighting mappings with the frame axes marked, for ``docs/conventions.rst``. Its code is
  the gallery example ``docs/examples/plot_mirror_ball_mapping.py``, run here unchanged, so the page figure and
  the gallery never disagree;
- ``astronaut_preview.png``: the README quick start's preview, made by that very command
  (``kornia-ilum estimate -o astronaut.exr --preview astronaut.png``, on the embedded default);
- ``ours22_curve.png``, ``sh22_curve.png``, ``sipr22_curve.png``: the learning curves of the issue-22 runs,
  drawn from the committed ``*_curve.csv`` beside them (:func:`kornia_ilum_lab.evaluation.curve.write_curve`);
- ``bench/bench.png``: run time against error, drawn from the committed run's ``bench/bench.json``
  (:func:`kornia_ilum.bench.write_report`'s figure).

The light-stage figures are made by ``docs/_scripts/make_lightstage_figures.py``, and those of the environments
by ``kornia-ilum synth environments`` (docs/environments.rst).
"""

from __future__ import annotations

import argparse
import json
import runpy
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import matplotlib

from kornia_ilum_lab.provenance import stamp_figure

matplotlib.use("Agg")

DOCS = Path(__file__).resolve().parents[1]
STATIC = DOCS / "_static"
SCRIPT = "python docs/_scripts/make_figures.py --only "
#: What the README's preview shows: the default estimate from a photo, end to end.
PREVIEW_SHOWS = ("kornia_ilum.api", "kornia_ilum.detection", "kornia_ilum.estimators", "kornia_ilum.render",
                 "kornia_ilum.geometry", "kornia_ilum.color", "kornia_ilum.io")


def mappings() -> None:
    namespace = runpy.run_path(str(DOCS / "examples" / "plot_mirror_ball_mapping.py"))
    out = STATIC / "mappings.png"
    namespace["fig"].savefig(out, dpi=100, metadata={"Software": None})
    stamp_figure(out, command=SCRIPT + "mappings", shows=["kornia_ilum.geometry"],
                 inputs=[DOCS / "examples" / "plot_mirror_ball_mapping.py"])
    print(f"wrote {out} ({out.stat().st_size // 1024} KiB)")


def preview() -> None:
    out = STATIC / "astronaut_preview.png"
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([sys.executable, "-m", "kornia_ilum", "estimate", "-o", f"{tmp}/astronaut.exr", "--preview",
                        f"{tmp}/astronaut.png"], check=True)
        shutil.copyfile(f"{tmp}/astronaut.png", out)
    stamp_figure(out, command=SCRIPT + "preview", shows=PREVIEW_SHOWS)
    print(f"wrote {out} ({out.stat().st_size // 1024} KiB)")


def curves() -> None:
    from kornia_ilum_lab.evaluation.curve import read_curve, write_curve

    for name in ("ours22", "sh22", "sipr22"):
        csv = STATIC / f"{name}_curve.csv"
        with tempfile.TemporaryDirectory() as tmp:
            run = Path(tmp) / name  # the figure's title
            run.mkdir()
            write_curve(run, read_curve(csv))
            out = STATIC / f"{name}_curve.png"
            shutil.copyfile(run / "curve.png", out)
        stamp_figure(out, command=SCRIPT + "curves", shows=["kornia_ilum_lab.evaluation.curve"], inputs=[csv])
        print(f"wrote {out} ({out.stat().st_size // 1024} KiB)")


def bench() -> None:
    from kornia_ilum.bench.report import bench_figure

    report = STATIC / "bench" / "bench.json"
    out = STATIC / "bench" / "bench.png"
    bench_figure(json.loads(report.read_text()), out)
    stamp_figure(out, command=SCRIPT + "bench", shows=["kornia_ilum.bench.report"], inputs=[report])
    print(f"wrote {out} ({out.stat().st_size // 1024} KiB)")


FIGURES = {"mappings": mappings, "preview": preview, "curves": curves, "bench": bench}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", choices=tuple(FIGURES), default=list(FIGURES))
    for name in parser.parse_args(argv).only:
        FIGURES[name]()


if __name__ == "__main__":
    main()
