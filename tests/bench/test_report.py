"""kornia_ilum.bench.report: the Pareto front, the Markdown, the JSON and the figure."""

from __future__ import annotations

import json

from kornia_ilum.bench import PAPER, format_bench, pareto_front, write_bench


def _result() -> dict:
    machine = {"cpu": "a CPU", "flags": ["avx2"], "threads": 2, "fp32_gflops": 100.0, "bf16_gflops": None,
               "int8_gops": 300.0, "copy_gbps": 10.0, "fresh_copy_gbps": 3.0}
    rows = [{"label": "net", "estimator": "net", "runtime": "eager", "gflop": 0.7, "b1_ms_per_crop": 10.0,
             "b32_ms_per_crop": 8.0, "b32_crops_per_s": 125.0, "b1_speedup": 1.0, "b32_speedup": 1.0,
             "b1_peak_fraction": 0.7, "b32_peak_fraction": 0.875, "l_rec": {"diffuse": 0.1, "matte_silver": 0.2,
             "mirror": 0.3}, "l_rec_groups": {"indoor": {"diffuse": 0.1}, "outdoor": {"diffuse": 0.1}},
             "relative_radiance": [0.1, 0.0, -0.1]},
            {"label": "net+onnx", "estimator": "net", "runtime": "onnx", "gflop": 0.7, "b1_ms_per_crop": 5.0,
             "b32_ms_per_crop": 4.0, "b32_crops_per_s": 250.0, "b1_speedup": 2.0, "b32_speedup": 2.0,
             "l_rec": {"diffuse": 0.1, "matte_silver": 0.2, "mirror": 0.3},
             "parity": {"value": 1e-6, "tolerance": 1e-4, "passed": True}},
            {"label": "mean of GT", "estimator": "mean of GT", "runtime": "oracle",
             "l_rec": {"diffuse": 0.15, "matte_silver": 0.2, "mirror": 0.3}}]
    e2e = [{"photo": "640x480", "detector": "opencv", "max_side": None, "estimator": "net", "runtime": "eager",
            "ms": dict.fromkeys(("read", "check", "detect", "crop", "estimate", "write", "total"), 1.0),
            "speedup": 1.0}]
    return {"machine": machine, "software": {"torch": "x"}, "rows": rows, "pareto": pareto_front(rows),
            "auto": {"net": "onnx"}, "per_tone": {"net": {"1": 0.1}}, "e2e": e2e,
            "error": {"what": "a test set", "short": "test"}, "paper": PAPER, "notes": ["a note"]}


def test_pareto_front_keeps_the_rows_nothing_beats() -> None:
    rows = [{"label": n, "b1_ms_per_crop": t, "l_rec": {"diffuse": e}}
            for n, t, e in (("fast", 1.0, 0.3), ("good", 5.0, 0.1), ("worse", 6.0, 0.2), ("tie", 5.0, 0.1))]
    assert pareto_front(rows) == ["fast", "good", "tie"]
    assert pareto_front(_result()["rows"]) == ["net+onnx"]  # as good, twice as fast; the oracle is not timed


def test_the_markdown_names_the_machine_the_error_and_the_paper() -> None:
    text = format_bench(_result())
    assert "a CPU" in text and "| bf16 matmul | not native |" in text and "a test set" in text
    assert "| **net+onnx** | onnx |" in text and "net -> onnx" in text and "another dataset" in text
    assert "| 640x480 | opencv | full | eager |" in text and "- a note" in text


def test_write_bench_writes_three_files_atomically(tmp_path) -> None:
    written = write_bench(_result(), tmp_path / "out")
    assert [p.name for p in written] == ["bench.md", "bench.json", "bench.png"]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["bench.json", "bench.md", "bench.png"]
    assert json.loads((tmp_path / "out" / "bench.json").read_text())["auto"] == {"net": "onnx"}
    assert (tmp_path / "out" / "bench.png").read_bytes()[:4] == b"\x89PNG"
