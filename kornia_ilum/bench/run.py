r"""One bench run: every estimator under every runtime, timed and scored in the same process.

:func:`run_bench` measures, in this order (all on the current torch thread count):

1. the machine's limits (:func:`~kornia_ilum.bench.machine.machine_limits`);
2. for each estimator and each runtime that runs here (:func:`~kornia_ilum.estimators.runtime_available`; an
   estimator without a form for a runtime, such as int8 of a model without an encoder, is left out with the
   reason): its speed at batch 1 and 32 (:func:`~kornia_ilum.bench.speed.estimator_speed`), the speed-up over
   its own eager row, and the rate of operations reached against the peak of the precision used; the runtime's parity
   check (:func:`~kornia_ilum.estimators.runtime_parity`) and what ``"auto"`` picks;
3. where an ``error`` part is given (the lab's :class:`kornia_ilum_lab.bench.error.BenchError`, found by
   ``kornia-ilum bench`` through the ``kornia_ilum.bench`` entry point ``error``), the error of every row and of
   the oracles on what it scores (the held-out split where a cache is given, else the probe's check part,
   labelled as such); without it, time only;
4. one photo end to end per size of :data:`~kornia_ilum.bench.speed.E2E_SIZES` and detector: today's path
   (eager, detection at full resolution) first, then the fast runtime, then the fast runtime with detection on
   a copy of at most ``detect_side`` pixels.

With ``compile=True`` the eager estimator under :func:`torch.compile` is a row too (its compile time in the
notes).
"""

from __future__ import annotations

import copy
import time
from collections.abc import Sequence
from typing import Any

import torch

from kornia_ilum.api import cached_detector
from kornia_ilum.bench.machine import machine_limits
from kornia_ilum.bench.report import PAPER, pareto_front
from kornia_ilum.bench.speed import E2E_SIZES, end_to_end, estimator_flops, estimator_speed, portrait_photo, run_info
from kornia_ilum.core.errors import MissingWeightsError, ValueCheckError
from kornia_ilum.detection import DEFAULT_DETECTOR
from kornia_ilum.estimators import (
    AUTO_ORDER,
    DEFAULT_ESTIMATOR,
    RUNTIMES,
    SceneStrength,
    create_estimator,
    list_estimators,
    runtime_available,
    runtime_parity,
    with_runtime,
)

__all__ = ["BENCH_RUNTIMES", "PEAK_OF", "run_bench"]

#: The runtimes a bench tries for every estimator.
BENCH_RUNTIMES: tuple[str, ...] = tuple(r for r in RUNTIMES if r != "auto")
#: The machine peak each runtime's rate of operations is compared with.
PEAK_OF = {"eager": "fp32_gflops", "compile": "fp32_gflops", "onnx": "fp32_gflops", "bf16": "bf16_gflops",
           "onnx-int8": "int8_gops"}


def _label(name: str, runtime: str) -> str:
    return name if runtime == "eager" else f"{name}+{runtime}"


def run_bench(
    error: Any | None = None,
    estimators: Sequence[str] | None = None,
    *,
    runtimes: Sequence[str] = BENCH_RUNTIMES,
    quick: bool = False,
    e2e_detectors: Sequence[str] = (DEFAULT_DETECTOR,),
    detect_side: int = 320,
    compile: bool = False,
    progress: bool = True,
) -> dict[str, Any]:
    r"""Time and score the estimators under the runtimes (module docstring).

    Args:
        error: the error part (an object with ``what`` and ``score(models, rows)``, the lab's
            :class:`~kornia_ilum_lab.bench.error.BenchError`), or ``None`` to time only.
        estimators: registered names (default: all that ship weights).
        runtimes: of :data:`BENCH_RUNTIMES`; ``"eager"`` is always timed (the baseline of its speed-ups).
        quick: batches 1 and 4, 3 timed calls, one photo size: the same code path in seconds (CI).
        e2e_detectors: the detectors of the end-to-end rows (registered names); the first one's eager row at full
            resolution is the baseline of every row's speed-up. A last row times the defaults of
            ``kornia-ilum estimate`` (:data:`~kornia_ilum.detection.DEFAULT_DETECTOR` at its own detection size,
            eager).
        detect_side: the longer side of the downscaled detection of the fast end-to-end rows.
        compile: also time the eager estimator under :func:`torch.compile`.
        progress: print a line per step.

    Returns:
        the JSON-ready result: ``machine``, ``software``, ``rows`` (estimator x runtime, then the oracles),
        ``pareto``, ``auto``, ``per_tone``, ``e2e``, ``error``, ``paper``, ``notes``.

    Examples:
        A run times every estimator and runtime (the eager row of each first), so it is not run here:

        >>> "eager" in BENCH_RUNTIMES and "auto" not in BENCH_RUNTIMES
        True
        >>> result = run_bench(None, ["uniform"], quick=True)  # doctest: +SKIP
        >>> result["rows"][0]["label"], result["rows"][0]["runtime"]  # doctest: +SKIP
        ('uniform', 'eager')
    """
    say = print if progress else (lambda *a, **k: None)
    batches = (1, 4) if quick else (1, 32)
    repeats = 3 if quick else 20
    big = batches[1]
    machine = machine_limits(quick=quick)
    say(f"machine: {machine['cpu']}, fp32 {machine['fp32_gflops']:.0f} GFLOP/s, int8 {machine['int8_gops']:.0f} "
        f"GOP/s, copy {machine['copy_gbps']:.1f} GB/s")
    names = list(estimators) if estimators else [n for n in list_estimators() if n != "untrained"]
    runtimes = ["eager"] + [r for r in runtimes if r not in ("eager", "auto")]
    rows: list[dict[str, Any]] = []
    models: dict[str, Any] = {}
    notes: list[str] = []
    auto: dict[str, str] = {}
    for name in names:
        try:
            base = create_estimator(name)
        except MissingWeightsError as e:
            notes.append(f"{name}: skipped ({e})")
            continue
        flops = estimator_flops(base)
        for runtime in runtimes + (["compile"] if compile else []):
            reason = runtime_available(runtime) if runtime != "compile" else None
            if reason is not None:
                notes.append(f"{name} under {runtime}: not run here ({reason})")
                continue
            t0 = time.perf_counter()
            try:
                if runtime == "compile":
                    model = torch.compile(copy.deepcopy(base))
                else:
                    model = with_runtime(copy.deepcopy(base) if runtime == "bf16" else base, runtime)
            except ValueCheckError as e:
                notes.append(f"{name} under {runtime}: no such form ({e})")
                continue
            try:
                if runtime == "compile":  # the compiler runs on the first call of each batch size
                    for b in batches:
                        estimator_speed(model, (b,), repeats=1)
                built = time.perf_counter() - t0
                speed = estimator_speed(model, batches, repeats)
            except Exception as e:  # torch.compile fails in its own ways (graph breaks, backends): a note
                if runtime != "compile":
                    raise
                notes.append(f"{name} under torch.compile: failed ({type(e).__name__}: {str(e).splitlines()[0]})")
                continue
            if runtime == "compile":
                notes.append(f"{name} under torch.compile: compiled in {built:.0f} s for batch sizes {batches} (the "
                             "default inductor backend)")
            row: dict[str, Any] = {"label": _label(name, runtime), "estimator": name, "runtime": runtime,
                                   "gflop": flops / 1e9, "build_s": built}
            for b in batches:
                tag = "b1" if b == 1 else "b32"
                row[f"{tag}_ms_per_crop"] = speed[f"b{b}_ms_per_crop"]
                row[f"{tag}_crops_per_s"] = speed[f"b{b}_crops_per_s"]
                peak = machine[PEAK_OF[runtime]]
                gflops = flops / 1e9 * speed[f"b{b}_crops_per_s"]
                row[f"{tag}_gflops"] = gflops
                row[f"{tag}_peak_fraction"] = gflops / peak if peak else None
            if runtime not in ("eager", "compile"):
                value, tol, passed = runtime_parity(base, model, runtime)
                row["parity"] = {"value": value, "tolerance": tol, "passed": passed}
            rows.append(row)
            models[row["label"]] = model
            say(f"{row['label']}: batch 1 {row['b1_ms_per_crop']:.2f} ms, batch {big} "
                f"{row['b32_ms_per_crop']:.2f} ms/crop ({built:.1f} s to build)")
        eager = next(r for r in rows if r["label"] == name)
        for r in rows:
            if r["estimator"] == name:
                r["b1_speedup"] = eager["b1_ms_per_crop"] / r["b1_ms_per_crop"]
                r["b32_speedup"] = eager["b32_ms_per_crop"] / r["b32_ms_per_crop"]
        passed = {r["runtime"] for r in rows if r["estimator"] == name and r.get("parity", {}).get("passed")}
        auto[name] = next((o for o in AUTO_ORDER if o in passed), "eager")  # with_runtime("auto")'s rule

    per_tone, error_of = {}, {"what": "not measured (time only: the error needs the lab, kornia_ilum_lab)",
                              "short": "not measured"}
    if error is not None:
        say(f"error: {error.what}")
        scored = error.score(models, rows)
        per_tone, error_of = scored["per_tone"], scored["error"]
        say(f"scored {scored['methods']} methods in {scored['seconds']:.0f} s")

    e2e = []
    sizes = E2E_SIZES[:1] if quick else E2E_SIZES
    default = DEFAULT_ESTIMATOR if DEFAULT_ESTIMATOR in names else names[0]
    fast = auto.get(default, "eager")
    for width, height in sizes:
        photo = portrait_photo(width, height)
        configs = [(det, runtime, side) for det in e2e_detectors
                   for runtime, side in (("eager", None), (fast, None), (fast, detect_side))]
        configs.append((DEFAULT_DETECTOR, "eager", "auto"))  # what `kornia-ilum estimate` does by default
        defaults = len(configs) - 1
        if default == "ours":  # the defaults with a scene branch (its cost: an untrained one costs the same)
            configs.append((DEFAULT_DETECTOR, "eager", "auto"))
        base_ms = None  # the first row: today's path of the first detector (eager, full resolution)
        for k, (det_name, runtime, side) in enumerate(configs):
            model = models[_label(default, runtime)]
            detector = cached_detector(det_name, torch.device("cpu"), side)
            scene = SceneStrength().eval() if k > defaults else None
            ms = end_to_end(photo, model, detector, repeats=3 if quick else 10, scene=scene)
            base_ms = base_ms or ms["total"]
            e2e.append({"photo": f"{width}x{height}", "detector": det_name, "max_side": detector.max_side,
                        "estimator": default, "runtime": runtime, "ms": ms, "speedup": base_ms / ms["total"],
                        "defaults": k == defaults, "scene": scene is not None})
            say(f"e2e {width}x{height} {det_name} side {detector.max_side or 'full'} {runtime}"
                f"{' (the defaults)' if k == defaults else ' + scene branch' if scene is not None else ''}: "
                f"{ms['total']:.1f} ms")
    return {
        "machine": machine,
        "software": run_info(),
        "quick": quick,
        "batches": list(batches),
        "rows": rows,
        "pareto": pareto_front(rows),
        "auto": auto,
        "per_tone": per_tone,
        "e2e": e2e,
        "error": error_of,
        "paper": PAPER,
        "notes": notes,
    }
