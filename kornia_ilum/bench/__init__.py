r"""Run time against error (``kornia-ilum bench``): every estimator under every runtime, timed in one run on the
machine at hand, beside that machine's measured limits, and scored where the lab is installed.

- :func:`machine_limits` (:mod:`kornia_ilum.bench.machine`): fp32, bf16 and int8 matmul peaks and memory
  bandwidth;
- :func:`estimator_speed`, :func:`end_to_end` (:mod:`kornia_ilum.bench.speed`): ms per crop at batch 1 and 32,
  and one photo from file to ``.exr`` stage by stage;
- :func:`run_bench` (:mod:`kornia_ilum.bench.run`): the whole run;
- :func:`format_bench`, :func:`write_bench`, :data:`PAPER` (:mod:`kornia_ilum.bench.report`): Markdown, JSON and
  the Pareto figure, with the paper's published numbers labelled as another dataset and device;
- :mod:`kornia_ilum.bench.stress`: the numerical stress table of the public ops (``benchmarks/bench_stress.py``);
- the error part and the skips (video reuse, sparse relighting) are the lab's
  (:class:`kornia_ilum_lab.bench.error.BenchError`), found through the ``kornia_ilum.bench`` entry point ``error``
  (:func:`~kornia_ilum.bench.cli.bench_error_part`).

``import kornia_ilum`` never imports this package.
"""

from kornia_ilum.bench.machine import cpu_model, machine_limits, median_seconds, paired_median_seconds
from kornia_ilum.bench.report import PAPER, format_bench, pareto_front, write_bench
from kornia_ilum.bench.run import BENCH_RUNTIMES, PEAK_OF, run_bench
from kornia_ilum.bench.speed import E2E_SIZES, end_to_end, estimator_flops, estimator_speed, portrait_photo

__all__ = [
    "BENCH_RUNTIMES",
    "E2E_SIZES",
    "PAPER",
    "PEAK_OF",
    "cpu_model",
    "end_to_end",
    "estimator_flops",
    "estimator_speed",
    "format_bench",
    "machine_limits",
    "median_seconds",
    "paired_median_seconds",
    "pareto_front",
    "portrait_photo",
    "run_bench",
    "write_bench",
]
