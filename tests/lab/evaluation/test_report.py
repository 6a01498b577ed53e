"""kornia_ilum_lab.evaluation.report: the tables, the paired differences, Markdown and JSON."""

from __future__ import annotations

import json
import math

import safetensors.torch

from kornia_ilum.core.files import sha256_file
from kornia_ilum.estimators import create_estimator
from kornia_ilum_lab.evaluation import BRDF_NAMES, ORACLES, evaluate, format_markdown, summarize, write_report
from tests.lab.evaluation.helpers import N


class TestReport:
    def test_tables(self, eval_set, untrained_name) -> None:
        results = evaluate(eval_set, ["uniform", untrained_name])
        assert set(results["methods"]) == {"uniform", *ORACLES}
        assert "MissingWeightsError" in results["skipped"][untrained_name]
        summary = summarize(results, eval_set)
        t1, t2 = summary["table1_l_rec"], summary["table2_relative_radiance"]
        for name in ("uniform", *ORACLES):
            assert set(t1[name]) == {"indoor", "outdoor", "all"}
            assert all(isinstance(t1[name]["all"][b], float) for b in BRDF_NAMES)
            assert len(t2[name]["all"]["mean"]) == 3 and min(t2[name]["all"]["mean_abs"]) >= 0
            tones = summary["per_skin_tone"][name]
            assert sum(row["count"] for row in tones.values()) == N
        assert max(abs(v) for v in t2["mean of GT"]["all"]["mean"]) < 1e-4
        markdown = format_markdown(summary)
        assert "## Table 1" in markdown and "| uniform |" in markdown and "untrained: MissingWeightsError" in markdown
        json.dumps(summary)  # JSON-ready
        assert "weights" not in summary and "Weight files" not in markdown  # no weight file was scored

    def test_paired_differences(self, eval_set) -> None:
        results = evaluate(eval_set, ["uniform"])
        scores = results["methods"]
        paired = summarize(results, eval_set, reference="uniform")["paired"]
        assert paired["reference"] == "uniform" and set(paired["methods"]) == set(ORACLES)
        for name, rows in paired["methods"].items():
            for b in BRDF_NAMES:
                d = scores[name]["scores"][b] - scores["uniform"]["scores"][b]
                r = rows[b]
                assert math.isclose(r["mean"], float(d.double().mean()), rel_tol=1e-9, abs_tol=1e-12)
                assert r["low"] <= r["mean"] <= r["high"] and 0 <= r["better"] <= 1
        assert summarize(results, eval_set)["paired"] == {"reference": None, "methods": {}}  # no ours scored
        assert "## Paired differences: L_rec(method) - L_rec(uniform)" in format_markdown(
            summarize(results, eval_set, reference="uniform"))

    def test_weight_files_are_listed_with_their_sha256(self, eval_set, tmp_path) -> None:
        path = tmp_path / "run.safetensors"
        net = create_estimator("ours", pretrained=False)
        safetensors.torch.save_file({k: v.contiguous() for k, v in net.state_dict().items()}, str(path))
        summary = summarize(evaluate(eval_set, [], weights={"ours": path}, oracles=False), eval_set)
        assert summary["weights"] == {"ours@run.safetensors": sha256_file(path)}
        assert f"- ours@run.safetensors: sha256 {sha256_file(path)}" in format_markdown(summary)
        written = write_report(summary, tmp_path / "out" / "eval.md", tmp_path / "out" / "eval.json")
        assert [p.name for p in written] == ["eval.md", "eval.json"]
        assert json.loads(written[1].read_text())["weights"] == summary["weights"]
