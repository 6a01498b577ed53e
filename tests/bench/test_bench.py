"""kornia-ilum bench: the machine's limits, the speed and error rows, the end-to-end split, the reports."""

from __future__ import annotations

import json

import pytest

from kornia_ilum.bench import PAPER, machine_limits, pareto_front
from kornia_ilum.cli import main


def test_machine_limits_measure_every_peak_it_can() -> None:
    limits = machine_limits(quick=True)
    assert limits["cpu"] and limits["threads"] >= 1
    assert limits["fp32_gflops"] > 0 and limits["int8_gops"] > 0 and limits["copy_gbps"] > 0
    assert limits["fresh_copy_gbps"] > 0
    assert limits["bf16_gflops"] is None or limits["bf16_gflops"] > 0  # None where bf16 would be emulated


def test_pareto_front_keeps_the_rows_nothing_beats() -> None:
    rows = [{"label": n, "b1_ms_per_crop": t, "l_rec": {"diffuse": e}}
            for n, t, e in (("fast", 1.0, 0.3), ("good", 5.0, 0.1), ("worse", 6.0, 0.2), ("tie", 5.0, 0.1))]
    assert pareto_front(rows) == ["fast", "good", "tie"]


@pytest.mark.slow
def test_bench_quick_writes_the_tables_and_the_figure(tmp_path, capsys) -> None:
    out = tmp_path / "bench"
    assert main(["bench", "--quick", "--estimator", "uniform", "--runtime", "onnx", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == ["bench.json", "bench.md", "bench.png"]
    result = json.loads((out / "bench.json").read_text())
    labels = [r["label"] for r in result["rows"]]
    assert labels == ["uniform", "uniform+onnx", "SH of GT", "mean of GT"]
    for row in result["rows"][:2]:
        assert row["b1_ms_per_crop"] > 0 and row["b32_crops_per_s"] > 0 and row["b1_speedup"] > 0
        assert set(row["l_rec"]) == {"diffuse", "matte_silver", "mirror"} and len(row["relative_radiance"]) == 3
    assert result["rows"][1]["parity"]["passed"] and result["auto"]["uniform"] in ("onnx", "bf16", "eager")
    # the error says what it was measured on: the probe, not the held-out split
    assert "TRAINING portraits" in result["error"]["what"] and result["error"]["eval_set"]["samples"] == 32
    # one photo end to end, every stage named, today's path first
    stages = {"read", "check", "detect", "crop", "estimate", "write", "total"}
    assert [e["runtime"] for e in result["e2e"]][0] == "eager" and result["e2e"][0]["speedup"] == 1.0
    assert all(set(e["ms"]) == stages for e in result["e2e"]) and result["e2e"][2]["max_side"] == 320
    assert result["paper"] == PAPER and "another dataset" in (out / "bench.md").read_text()
    assert "## The machine's limits" in printed and "wrote" in printed
