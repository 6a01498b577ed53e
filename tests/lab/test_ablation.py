"""kornia_ilum_lab.ablation: the rows of the paper's ablations, and ``kornia-ilum ablate`` end to end on tiny data."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
import torch

import kornia_ilum_lab.train.recipes as recipes
from kornia_ilum_lab.ablation import ABLATIONS, BASELINE, ablation_config, format_ablations, run_ablations
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum_lab.evaluation import BRDF_NAMES, build_eval_set
from kornia_ilum_lab.train.data import training_dataset
from tests.lab.evaluation.helpers import write_cache
from tests.lab.train.helpers import small_data


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    """Tiny fields: seeds 0 and 5 train, 1 and 3 eval."""
    return write_cache(tmp_path_factory.mktemp("ablation_cache"), [(0, 2), (1, 3), (3, 6), (5, 4)])


class TestRows:
    def test_the_paper_rows_and_the_baseline(self) -> None:
        assert list(ABLATIONS) == ["baseline", "no-multi-scale", "no-adversarial", "no-face-detector",
                                   "black-background", "log-l2", "background-only"]

    @pytest.mark.parametrize("name", list(ABLATIONS))
    def test_each_row_is_the_baseline_with_its_own_change(self, name: str, cache) -> None:
        base = ablation_config("baseline", "run", cache=(str(cache),), data=small_data())
        row = ablation_config(name, "run", cache=(str(cache),), data=small_data())
        changed = {k for k, v in row.data_key().items() if base.data_key()[k] != v}
        expected = {k for k in ABLATIONS[name].train if k != "data"} | ({"data"} if "data" in ABLATIONS[name].train
                                                                          else set())
        assert changed == expected
        assert all(getattr(base, k) == v for k, v in BASELINE.items())
        training_dataset(row)  # the data settings are PortraitConfig's

    @pytest.mark.parametrize("name", ["no-face-detector", "black-background", "background-only"])
    def test_rows_with_another_input_are_scored_on_it(self, name: str, cache) -> None:
        row = ABLATIONS[name]
        eval_set = build_eval_set([cache], samples=2, background=row.background, portraits=row.portraits)
        plain = build_eval_set([cache], samples=2)
        assert eval_set.images.shape == plain.images.shape and not torch.equal(eval_set.images, plain.images)
        assert eval_set.description["portraits"].items() >= {k: repr(v) for k, v in row.portraits.items()}.items()
        if name == "background-only":  # the same lightings, the subject gone: metered on the background instead,
            # so in other units (the lighting is in the photo's units), by one factor per portrait
            ratio = eval_set.mirror_ball / plain.mirror_ball.clamp_min(1e-6)
            lit = plain.mirror_ball > 1e-3
            for r, m in zip(ratio, lit):
                torch.testing.assert_close(r[m], r[m].median().expand(int(m.sum())), rtol=1e-4, atol=0)

    def test_unknown_rows_and_settings_are_refused(self, cache) -> None:
        with pytest.raises(ValueCheckError, match="no ablation"):
            ablation_config("no-face", "run", cache=("c",))
        with pytest.raises(ValueCheckError, match="no ablation"):
            run_ablations(["nope"], "out", cache=("c",), eval_cache=("c",))
        with pytest.raises(ValueCheckError, match="set by the eval set"):
            build_eval_set([cache], samples=2, portraits={"background": "black"})


@pytest.mark.slow  # three short training runs
def test_ablate_trains_scores_and_writes_the_table(cache, tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(recipes, "PROBE_SIZE", 2)
    threads = torch.get_num_threads()
    try:
        result = run_ablations(["background-only", "no-adversarial"], tmp_path / "abl", cache=[str(cache)],
                               eval_cache=[str(cache)], steps=1, samples=4, batch=2, workers=0, threads=1,
                               bf16=False, log_every=1, crop_pairs=1, data=small_data())
    finally:
        torch.set_num_threads(threads)
    assert list(result["rows"]) == ["baseline", "background-only", "no-adversarial"]
    rows = result["rows"]
    assert all(set(r["l_rec"]) == set(BRDF_NAMES) for r in rows.values())
    assert all(abs(p["mean"]) < 1e-12 for p in rows["baseline"]["paired_vs_baseline"].values())
    assert rows["no-adversarial"]["baseline_l_rec"] == rows["baseline"]["l_rec"]  # one eval set for both
    assert rows["background-only"]["portraits"] == {"subject": "False"}
    saved = json.loads((tmp_path / "abl" / "ablations.json").read_text())
    assert saved["rows"].keys() == rows.keys()
    assert (tmp_path / "abl" / "ablations.md").read_text() == format_ablations(result)
    assert (tmp_path / "abl" / "ablations.rst").read_text() == format_ablations(result, "rst")
    assert not (tmp_path / "abl" / "no-adversarial" / "checkpoint.pt").exists() or torch.load(
        tmp_path / "abl" / "no-adversarial" / "checkpoint.pt", weights_only=True)["disc"] == {}


def test_the_table_in_markdown_and_rst() -> None:
    paired = {b: {"mean": 0.01, "low": 0.0, "high": 0.02} for b in BRDF_NAMES}
    row = {"paper": "no adversarial loss", "background": "environment", "portraits": {},
           "l_rec": dict.fromkeys(BRDF_NAMES, 0.2), "baseline_l_rec": dict.fromkeys(BRDF_NAMES, 0.1),
           "paired_vs_baseline": paired}
    result = {"steps": 9, "batch": 2, "samples": 4, "rows": {"no-adversarial": row}}
    md = format_ablations(result).splitlines()
    assert md[-1] == ("| no-adversarial | no adversarial loss | environment | 0.2000 / 0.2000 / 0.2000 | 0.1000 / "
                      "0.1000 / 0.1000 | +0.0100 [+0.0000, +0.0200]; +0.0100 [+0.0000, +0.0200]; +0.0100 "
                      "[+0.0000, +0.0200] |")
    rst = format_ablations(result, "rst").splitlines()
    assert rst[0] == ".. list-table::" and "   * - ``no-adversarial``" in rst and len(rst) == 4 + 2 * 6
    with pytest.raises(ValueCheckError, match="fmt"):
        format_ablations(result, "html")


def test_ablate_command_line_help() -> None:
    r = subprocess.run([sys.executable, "-m", "kornia_ilum", "ablate", "--help"], capture_output=True, text=True,
                       check=True)
    assert "background-only" in r.stdout and "--eval-cache" in r.stdout


def test_the_cli_runs_the_command_and_fails_on_one_line(tmp_path, capsys) -> None:
    from kornia_ilum.cli import main

    missing = str(tmp_path / "no_cache")
    status = main(["ablate", "--cache", missing, "--eval-cache", missing, "--out", str(tmp_path / "abl")])
    err = capsys.readouterr().err
    assert status == 1 and err.count("\n") == 1 and "no_cache" in err and "AttributeError" not in err
