"""kornia_ilum_lab.train.loop: exact resume after SIGKILL, DDP with gloo, refusals, and the weight export."""

from __future__ import annotations

import dataclasses
import json
import math
import signal
import subprocess
import sys
import time

import pytest
import safetensors
import safetensors.torch
import torch

import kornia_ilum_lab.train.recipes as recipes
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.estimators import OursEstimator
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum_lab.train import TrainConfig, average_snapshots, export_weights, read_log, train
from tests.lab.train.helpers import cli, common, env, small_data, weights

_LOSS_COLUMNS = slice(4, None)  # log.csv columns after step, samples, elapsed_s, samples_per_s


@pytest.mark.slow  # subprocesses that train
class TestTrainCommand:
    def test_sigkill_then_resume_gives_the_uninterrupted_weights(self, tiny_cache, tmp_path) -> None:
        straight, killed = tmp_path / "straight", tmp_path / "killed"
        subprocess.run(cli(*common(tiny_cache, straight, 8)), check=True, env=env(), capture_output=True)
        proc = subprocess.Popen(cli(*common(tiny_cache, killed, 8)), env=env(), stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 120
        while not (killed / "checkpoint.pt").exists() and time.monotonic() < deadline:
            time.sleep(0.02)
        running = proc.poll() is None
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        assert running and proc.returncode == -signal.SIGKILL, "the run ended before it could be killed"
        assert not (killed / "ours.safetensors").exists()
        assert not list(killed.glob(".*tmp*"))  # no half-written file left behind
        subprocess.run(cli(*common(tiny_cache, killed, 8)), check=True, env=env(), capture_output=True)
        a, b = weights(straight), weights(killed)
        assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
        log_a, log_b = ((p / "log.csv").read_text() for p in (straight, killed))
        rows_a, rows_b = ([line.split(",")[_LOSS_COLUMNS] for line in log.splitlines()[1:]] for log in (log_a, log_b))
        assert len(rows_a) == 8 and rows_a == rows_b  # the same losses at every step
        summary = json.loads((straight / "summary.json").read_text())
        assert summary["steps"] == 8 and summary["weights"]["sha256"] and (straight / "loss.png").is_file()
        # the exported file loads into the registered estimator, never by unpickling
        est = OursEstimator()
        est.load_state_dict(a)

    def test_changed_settings_refuse_to_resume(self, tiny_cache, tmp_path) -> None:
        out = tmp_path / "run"
        subprocess.run(cli(*common(tiny_cache, out, 3, workers=0)), check=True, env=env(), capture_output=True)
        r = subprocess.run(cli(*common(tiny_cache, out, 4, workers=0), "--lr", "1e-3"), check=False, env=env(),
                           capture_output=True, text=True)
        assert r.returncode == 1 and "other settings" in r.stderr

    def test_torchrun_ddp_gloo_two_processes(self, tiny_cache, tmp_path) -> None:
        out = tmp_path / "ddp"
        cmd = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc-per-node", "2",
               "-m", "kornia_ilum", "train", *common(tiny_cache, out, 2, workers=0)]
        r = subprocess.run(cmd, check=False, env=env(), capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr[-3000:]
        summary = json.loads((out / "summary.json").read_text())
        assert summary["world_size"] == 2 and summary["steps"] == 2
        assert set(weights(out)) == set(OursEstimator().state_dict())


@pytest.mark.slow  # the tiny_cache fixture renders with Mitsuba; the last test trains
class TestTrain:
    def test_errors_leave_no_folder(self, tiny_cache, tmp_path) -> None:
        with pytest.raises(ValueCheckError, match="no reflectance field"):
            train(TrainConfig(out=str(tmp_path / "a"), cache=(str(tmp_path / "missing"),)))
        with pytest.raises(ValueCheckError, match=r"unknown data settings \['nope'\]"):
            train(TrainConfig(out=str(tmp_path / "b"), cache=(str(tiny_cache),), data={"nope": 1}))
        with pytest.raises(ValueCheckError, match="no training recipe for estimator 'uniform'"):
            train(TrainConfig(out=str(tmp_path / "c"), cache=(str(tiny_cache),), estimator="uniform"))
        with pytest.raises(ValueCheckError, match="steps must be a positive integer"):
            TrainConfig(out=str(tmp_path / "d"), cache=(str(tiny_cache),), steps=0)
        assert not any((tmp_path / n).exists() for n in "abcd")

    def test_summary_holds_the_config_as_given_and_the_runtime_as_decided(self, tiny_cache, tmp_path,
                                                                          monkeypatch) -> None:
        monkeypatch.setattr(recipes, "PROBE_SIZE", 2)  # the float16 probe: 2 crops, not 32
        threads = torch.get_num_threads()
        config = TrainConfig(out=str(tmp_path / "run"), cache=(str(tiny_cache),), steps=1, batch=2, workers=0,
                             threads=1, bf16=False, log_every=1, data=small_data())
        try:
            summary = train(config)
            again = train(config)  # the run is complete: resumed at its end, nothing trained
        finally:
            torch.set_num_threads(threads)
        assert summary["config"]["channels_last"] is None and summary["config"]["bf16"] is False
        assert (summary["bf16"], summary["channels_last"], summary["workers"]) == (False, True, 0)
        assert again["steps"] == 1 and again["weights"]["sha256"] == summary["weights"]["sha256"]
        assert len(read_log(tmp_path / "run")) == 1


class TestCropConsistencyAndInit:
    def test_a_fine_tune_starts_from_its_weights_and_logs_the_crop_term(self, tiny_cache, tmp_path,
                                                                         monkeypatch) -> None:
        monkeypatch.setattr(recipes, "PROBE_SIZE", 2)
        torch.manual_seed(123)  # not the run's seed: the run's own initialisation would differ
        start = OursEstimator()
        init = tmp_path / "init.safetensors"
        safetensors.torch.save_file(start.state_dict(), str(init))
        threads = torch.get_num_threads()
        config = TrainConfig(out=str(tmp_path / "run"), cache=(str(tiny_cache),), steps=1, batch=2, workers=0,
                             threads=1, bf16=False, log_every=1, lr=1e-9, lambda_crop=1.0, crop_pairs=1,
                             init=str(init), data=small_data())
        try:
            summary = train(config)
        finally:
            torch.set_num_threads(threads)
        assert summary["config"]["init"] == str(init) and summary["config"]["lambda_crop"] == 1.0
        (row,) = read_log(tmp_path / "run")
        assert row["crop"] > 0 and math.isclose(row["loss"], row["rec"] + 0.004 * row["adv"] + row["crop"],
                                                rel_tol=1e-4)
        got, ref = weights(tmp_path / "run"), start.state_dict()
        assert got.keys() == ref.keys()
        assert all(torch.allclose(got[k].float(), ref[k].float(), atol=1e-3) for k in ref)  # one step of 1e-9

    def test_snapshots_keep_the_weights_with_their_step(self, tiny_cache, tmp_path, monkeypatch) -> None:
        monkeypatch.setattr(recipes, "PROBE_SIZE", 2)
        threads = torch.get_num_threads()
        config = TrainConfig(out=str(tmp_path / "run"), cache=(str(tiny_cache),), steps=2, batch=2, workers=0,
                             threads=1, bf16=False, log_every=1, snapshot_every=1, data=small_data())
        try:
            train(config)
        finally:
            torch.set_num_threads(threads)
        files = sorted((tmp_path / "run" / "snapshots").iterdir())
        assert [f.name for f in files] == ["step_000001.safetensors", "step_000002.safetensors"]
        with safetensors.safe_open(str(files[1]), framework="pt") as f:
            meta = f.metadata()
        assert (meta["estimator"], meta["step"], meta["samples"]) == ("ours", "2", "4")
        assert float(meta["elapsed_s"]) > 0
        last, exported = safetensors.torch.load_file(files[1]), weights(tmp_path / "run")
        assert last.keys() == exported.keys() and all(v.dtype == torch.float32 for v in last.values())
        assert all(torch.allclose(last[k], exported[k].float(), atol=1e-2, rtol=1e-3) for k in last)
        assert config.data_key() == dataclasses.replace(config, snapshot_every=0).data_key()  # resumable either way

        # the finished run exported again with weight averaging: nothing trained, the mean of the tail's snapshots
        averaged = dataclasses.replace(config, average_tail=0.5)
        assert averaged.data_key() == config.data_key()
        try:
            summary = train(averaged)
        finally:
            torch.set_num_threads(threads)
        assert summary["averaged_snapshots"] == [2] and len(read_log(tmp_path / "run")) == 2
        again = dataclasses.replace(config, average_tail=0.75)  # steps 1 and 2
        try:
            summary = train(again)
        finally:
            torch.set_num_threads(threads)
        first = safetensors.torch.load_file(files[0])
        mean, steps = average_snapshots(tmp_path / "run", after=0, upto=2)
        assert summary["averaged_snapshots"] == steps == [1, 2]
        assert all(torch.allclose(mean[k], (first[k] + last[k]) / 2, atol=1e-6) for k in last)
        exported = weights(tmp_path / "run")
        assert all(torch.allclose(mean[k], exported[k].float(), atol=1e-2, rtol=1e-3) for k in last)
        with pytest.raises(ValueCheckError, match="no snapshot"):
            average_snapshots(tmp_path / "run", after=2, upto=2)
        with pytest.raises(ValueCheckError, match="snapshot_every"):
            dataclasses.replace(config, snapshot_every=0, average_tail=0.5)

    def test_no_adversarial_term_trains_no_discriminator_and_old_checkpoints_resume(self, tiny_cache, tmp_path,
                                                                                     monkeypatch) -> None:
        monkeypatch.setattr(recipes, "PROBE_SIZE", 2)
        threads = torch.get_num_threads()
        config = TrainConfig(out=str(tmp_path / "run"), cache=(str(tiny_cache),), steps=1, batch=2, workers=0,
                             threads=1, bf16=False, log_every=1, checkpoint_every=1, lambda_adv=0.0,
                             data=small_data())
        path = tmp_path / "run" / "checkpoint.pt"
        try:
            train(config)
            state = torch.load(path, weights_only=True)
            assert state["disc"] == {} and state["opt_d"] == {}
            # a checkpoint written before the ablations' settings existed holds their defaults
            for key in ("multi_scale", "loss"):
                del state["data_key"][key]
            torch.save(state, path)
            with pytest.raises(ValueCheckError, match="other settings"):
                train(dataclasses.replace(config, steps=2, loss="log_l2"))
            assert train(dataclasses.replace(config, steps=2))["steps"] == 2
        finally:
            torch.set_num_threads(threads)

    def test_init_must_be_the_estimators_weights(self, tiny_cache, tmp_path) -> None:
        init = tmp_path / "other.safetensors"
        safetensors.torch.save_file({"w": torch.ones(2)}, str(init))
        config = TrainConfig(out=str(tmp_path / "run"), cache=(str(tiny_cache),), steps=1, batch=2, workers=0,
                             init=str(init), data=small_data())
        with pytest.raises(ValueCheckError, match="no weights of estimator 'ours'"):
            train(config)
        assert not (tmp_path / "run").exists()  # refused before the run's folder is made


class TestExport:
    def test_float16_only_when_l_rec_moves_less_than_the_tolerance(self, tmp_path) -> None:
        torch.manual_seed(0)
        net = OursEstimator(latent_dim=16).eval()
        probe = {"image": torch.randint(0, 256, (2, 3, 256, 256), dtype=torch.uint8),
                 "mirror_ball": torch.rand(2, 3, 32, 32) * mirror_ball_valid(32)}
        strict = export_weights(net, tmp_path / "strict.safetensors", probe, tolerance=0.0)
        loose = export_weights(net, tmp_path / "loose.safetensors", probe, tolerance=1.0)
        assert strict["dtype"] == "float32" and loose["dtype"] == "float16"
        assert strict["l_rec_change"] == loose["l_rec_change"] < 1.0
        dtypes = {v.dtype for v in safetensors.torch.load_file(tmp_path / "loose.safetensors").values()}
        assert dtypes == {torch.float16}
        strict_dtypes = {v.dtype for v in safetensors.torch.load_file(tmp_path / "strict.safetensors").values()}
        assert strict_dtypes == {torch.float32}

    def test_read_log_of_a_folder_without_log(self, tmp_path) -> None:
        assert read_log(tmp_path) == []
