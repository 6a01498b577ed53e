"""kornia_ilum.bench.run: one bench run, timed, and scored by an error part where one is given (the lab's)."""

from __future__ import annotations

from kornia_ilum.bench import run_bench


class _Error:
    """A stand-in for the lab's error part: one fixed error per row, what it was measured on."""

    what = "a stand-in"

    def score(self, models, rows):
        rows.append({"label": "oracle", "estimator": "oracle", "runtime": "oracle"})
        for r in rows:
            if r["label"] in models:
                r["l_rec"] = {"diffuse": 0.1, "matte_silver": 0.2, "mirror": 0.3}
        return {"per_tone": {label: {"1": 0.1} for label in models}, "methods": len(models) + 1, "seconds": 0.0,
                "error": {"what": self.what, "short": "stand-in"}}


def test_a_run_times_scores_and_picks() -> None:
    result = run_bench(_Error(), ["uniform"], runtimes=["eager", "onnx"], quick=True, e2e_detectors=("none",),
                       progress=False)
    labels = [r["label"] for r in result["rows"]]
    assert labels == ["uniform", "uniform+onnx", "oracle"]
    eager, onnx = result["rows"][:2]
    assert eager["b1_speedup"] == 1.0 and "parity" not in eager and onnx["parity"]["passed"]
    assert eager["l_rec"]["diffuse"] == 0.1 and result["per_tone"] == {"uniform": {"1": 0.1},
                                                                       "uniform+onnx": {"1": 0.1}}
    assert result["auto"] == {"uniform": "onnx"} and result["pareto"]
    assert [e["runtime"] for e in result["e2e"]] == ["eager", "onnx", "onnx", "eager"]
    assert [e["max_side"] for e in result["e2e"]] == [None, None, 320, 240] and result["e2e"][0]["speedup"] == 1.0
    # the last row: `kornia-ilum estimate`'s defaults (YuNet at its own 240 pixels, eager)
    assert [e["defaults"] for e in result["e2e"]] == [False, False, False, True]
    assert result["e2e"][-1]["detector"] == "yunet" and not any(e["scene"] for e in result["e2e"])
    assert result["error"]["what"] == "a stand-in" and result["paper"]["fps"] == 27.5


def test_without_an_error_part_it_times_only() -> None:
    result = run_bench(None, ["uniform"], runtimes=["eager"], quick=True, e2e_detectors=("none",), progress=False)
    assert [r["label"] for r in result["rows"]] == ["uniform"] and result["per_tone"] == {}
    assert result["error"]["what"].startswith("not measured")


def test_ours_gets_a_row_with_the_scene_branch() -> None:
    """Issue 47: the defaults again with a scene branch, so its cost is one row of the same run."""
    result = run_bench(None, ["ours"], runtimes=["eager"], quick=True, e2e_detectors=("none",), progress=False)
    last, defaults = result["e2e"][-1], result["e2e"][-2]
    assert last["scene"] and not last["defaults"] and defaults["defaults"] and not defaults["scene"]
    assert (last["detector"], last["runtime"], last["max_side"]) == (defaults["detector"], "eager", 240)
