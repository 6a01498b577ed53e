"""kornia_ilum.bench.cli: ``kornia-ilum bench --quick`` writes the tables and the figure."""

from __future__ import annotations

import json

import pytest

from kornia_ilum.cli import main


@pytest.mark.slow
def test_bench_quick_writes_the_tables_and_the_figure(tmp_path, capsys) -> None:
    out = tmp_path / "bench"
    argv = ["bench", "--quick", "--estimator", "uniform", "--runtime", "onnx", "--detector", "opencv", "--out", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == ["bench.json", "bench.md", "bench.png"]
    result = json.loads((out / "bench.json").read_text())
    assert [r["label"] for r in result["rows"]] == ["uniform", "uniform+onnx", "SH of GT", "mean of GT"]
    for row in result["rows"][:2]:
        assert row["b1_ms_per_crop"] > 0 and row["b32_crops_per_s"] > 0
        assert set(row["l_rec"]) == {"diffuse", "matte_silver", "mirror"} and len(row["relative_radiance"]) == 3
    # the error says what it was measured on: the probe, not the held-out split
    assert "TRAINING portraits" in result["error"]["what"] and result["error"]["eval_set"]["samples"] == 32
    stages = {"read", "check", "detect", "crop", "estimate", "write", "total"}
    assert all(set(e["ms"]) == stages for e in result["e2e"]) and result["e2e"][0]["runtime"] == "eager"
    assert "## The machine's limits" in printed and "another dataset" in printed


def test_bench_usage_errors_are_one_line(capsys) -> None:
    assert main(["bench", "--runtime", "tensorrt"]) == 2
    assert main(["bench", "--quick", "--detector", "haar", "--estimator", "uniform"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert all(line.startswith("kornia-ilum: error: ") for line in err[-1:])
