"""kornia_ilum.bench.run: one bench run, scored and timed in the same process."""

from __future__ import annotations

from kornia_ilum.bench import run_bench
from kornia_ilum.evaluation import probe_eval_set


def test_a_run_times_scores_and_picks() -> None:
    result = run_bench(probe_eval_set(slice(64, 72)), "8 probe portraits", ["uniform"], ["eager", "onnx"],
                       quick=True, e2e_detectors=("none",), progress=False)
    labels = [r["label"] for r in result["rows"]]
    assert labels == ["uniform", "uniform+onnx", "SH of GT", "mean of GT"]
    eager, onnx = result["rows"][:2]
    assert eager["b1_speedup"] == 1.0 and "parity" not in eager and onnx["parity"]["passed"]
    assert abs(eager["l_rec"]["diffuse"] - onnx["l_rec"]["diffuse"]) < 1e-5  # float32 parity, so the same error
    assert result["auto"] == {"uniform": "onnx"} and result["pareto"]
    assert [e["runtime"] for e in result["e2e"]] == ["eager", "onnx", "onnx", "eager"]
    assert [e["max_side"] for e in result["e2e"]] == [None, None, 320, 240] and result["e2e"][0]["speedup"] == 1.0
    # the last row: `kornia-ilum estimate`'s defaults (YuNet at its own 240 pixels, eager)
    assert [e["defaults"] for e in result["e2e"]] == [False, False, False, True]
    assert result["e2e"][-1]["detector"] == "yunet"
    assert result["error"]["what"] == "8 probe portraits" and result["paper"]["fps"] == 27.5
