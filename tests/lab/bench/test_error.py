"""kornia_ilum_lab.bench.error: the bench's error part, found by ``kornia-ilum bench`` through its entry point."""

from __future__ import annotations

from kornia_ilum.bench import run_bench
from kornia_ilum.bench.cli import bench_error_part
from kornia_ilum_lab.bench.error import BenchError


def test_the_bench_finds_the_labs_error_part() -> None:
    assert bench_error_part() is BenchError


def test_the_error_columns_and_what_they_were_measured_on() -> None:
    error = BenchError(quick=True)
    assert error.skips() is None  # no cache, no clip
    result = run_bench(error, ["uniform"], runtimes=["eager"], quick=True, e2e_detectors=("none",), progress=False)
    labels = [r["label"] for r in result["rows"]]
    assert labels == ["uniform", "SH of GT", "mean of GT"]
    assert set(result["rows"][0]["l_rec"]) == {"diffuse", "matte_silver", "mirror"}
    assert result["error"]["what"] == error.what and result["per_tone"]["uniform"]


def test_without_an_error_part_the_bench_times_only() -> None:
    result = run_bench(None, ["uniform"], runtimes=["eager"], quick=True, e2e_detectors=("none",), progress=False)
    assert [r["label"] for r in result["rows"]] == ["uniform"] and "l_rec" not in result["rows"][0]
    assert result["error"]["what"].startswith("not measured") and result["per_tone"] == {}
