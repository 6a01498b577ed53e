"""kornia-ilum train: the training networks, the losses, exact resume after SIGKILL, DDP with gloo."""

from __future__ import annotations

import itertools
import json
import os
import signal
import subprocess
import sys
import time

import pytest
import safetensors.torch
import torch

from kornia_ilum.estimators import OursEstimator
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum.render import mirror_ball_pyramid
from kornia_ilum.train import (
    BRDF_WEIGHTS,
    SCALES,
    MSGDiscriminator,
    MultiScaleOurs,
    TrainConfig,
    training_losses,
)
from kornia_ilum.train.data import StepBatches


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "kornia_ilum", "train", *args]


def _env() -> dict[str, str]:
    return {**os.environ, "OMP_NUM_THREADS": "1", "KORNIA_ILUM_DEBUG": "1"}


def _common(cache, out, steps: int, workers: int = 1) -> list[str]:
    return ["--cache", str(cache), "--out", str(out), "--steps", str(steps), "--batch", "2", "--threads", "1",
            "--workers", str(workers), "--checkpoint-every", "3", "--log-every", "1", "--data", *SMALL]


#: Small chunks, so that a few steps do not make a whole 256-sample group of the default settings.
SMALL = ("fields_per_chunk=1", "lightings_per_field=4", "shuffle=1", "env_pool=2", "env_refresh=1")
_LOSS_COLUMNS = slice(4, None)  # log.csv columns after step, samples, elapsed_s, samples_per_s


class TestModels:
    def test_side_branches_are_not_exported(self) -> None:
        model = MultiScaleOurs()
        out = model(torch.rand(2, 3, 256, 256))
        for s in SCALES:
            valid = mirror_ball_valid(s)
            assert out[s].shape == (2, 3, s, s) and out[s].dtype == torch.float32
            assert (out[s][:, :, valid] > 0).all() and (out[s][:, :, ~valid] == 0).all()
        assert model.estimator.state_dict().keys() == OursEstimator().state_dict().keys()
        assert not any(k.startswith("sides") for k in model.estimator.state_dict())

    def test_discriminator(self) -> None:
        d = MSGDiscriminator()
        x = {s: torch.rand(3, 3, s, s, requires_grad=True) for s in SCALES}
        logits = d(x)
        assert logits.shape == (3,)
        logits.sum().backward()
        assert all(x[s].grad is not None and x[s].grad.abs().sum() > 0 for s in SCALES)  # every scale is seen


class TestLosses:
    def test_zero_at_the_truth_and_sensitive_at_every_scale(self) -> None:
        valid = mirror_ball_valid(32)
        truth = (torch.rand(2, 3, 32, 32) + 0.1) * valid
        pred = mirror_ball_pyramid(truth, SCALES)
        loss, parts = training_losses(pred, truth, BRDF_WEIGHTS)
        assert loss.item() < 1e-6 and set(parts) == {f"rec_{b}" for b in BRDF_WEIGHTS}
        for s in SCALES:  # one bright pixel in the lighting of one scale: the loss sees it
            bumped = {k: v.clone() for k, v in pred.items()}
            i = s // 2
            bumped[s][:, :, i, i] += 50.0
            assert training_losses(bumped, truth, BRDF_WEIGHTS)[0].item() > 1e-3, s

    def test_gradients_are_finite_on_black(self) -> None:
        pred = {s: torch.zeros(1, 3, s, s, requires_grad=True) for s in SCALES}
        loss, _ = training_losses(pred, torch.zeros(1, 3, 32, 32), BRDF_WEIGHTS)
        loss.backward()
        assert all(torch.isfinite(pred[s].grad).all() for s in SCALES)


class TestData:
    def test_batches_are_addressable_by_step(self, tiny_cache) -> None:
        """Starting at step 3 gives the batches that steps 3, 4 of a run from step 0 got (any worker count)."""
        from kornia_ilum.train.loop import _dataset

        data = dict(s.split("=") for s in SMALL)
        dataset = _dataset(TrainConfig(out="unused", cache=(str(tiny_cache),), data={k: int(v) for k, v in data.items()}))
        for workers in (0, 2):
            run = list(itertools.islice(iter(StepBatches(dataset, 2, 0, workers=workers)), 5))
            late = list(itertools.islice(iter(StepBatches(dataset, 2, 3, workers=workers)), 2))
            for a, b in zip(run[3:], late, strict=True):
                assert torch.equal(a["image"], b["image"]) and torch.equal(a["mirror_ball"], b["mirror_ball"])
        assert not torch.equal(run[0]["image"], run[1]["image"])

    def test_training_portraits_have_no_sphere_targets_and_the_same_images(self, tiny_cache) -> None:
        """Training drops the samples' sphere targets (the losses make their own); nothing else changes."""
        import dataclasses

        from kornia_ilum.synth.lightstage.portraits import PortraitDataset
        from kornia_ilum.train.loop import TRAINING_PORTRAITS, _dataset

        data = {k: int(v) for k, v in (s.split("=") for s in SMALL)}
        dataset = _dataset(TrainConfig(out="unused", cache=(str(tiny_cache),), data=data))
        assert TRAINING_PORTRAITS == {"sphere_sizes": ()} and dataset.config.sphere_sizes == ()
        full = PortraitDataset(dataset.fields, dataclasses.replace(dataset.config, sphere_sizes=(4, 32)),
                               seed=dataset.seed)
        for a, b in zip(dataset.chunk(0, 1), full.chunk(0, 1), strict=True):
            assert a["spheres"] == {} and set(b["spheres"]) >= {"diffuse_4", "mirror_32"}
            assert torch.equal(a["image"], b["image"]) and torch.equal(a["mirror_ball"], b["mirror_ball"])
        again = _dataset(TrainConfig(out="unused", cache=(str(tiny_cache),), data={**data, "sphere_sizes": [32]}))
        assert again.config.sphere_sizes == (32,)  # TrainConfig.data still overrides it


def _weights(out) -> dict[str, torch.Tensor]:
    return safetensors.torch.load_file(out / "ours.safetensors")


class TestTrainCommand:
    def test_sigkill_then_resume_gives_the_uninterrupted_weights(self, tiny_cache, tmp_path) -> None:
        straight, killed = tmp_path / "straight", tmp_path / "killed"
        subprocess.run(_cli(*_common(tiny_cache, straight, 8)), check=True, env=_env(), capture_output=True)
        proc = subprocess.Popen(_cli(*_common(tiny_cache, killed, 8)), env=_env(), stdout=subprocess.DEVNULL,
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
        subprocess.run(_cli(*_common(tiny_cache, killed, 8)), check=True, env=_env(), capture_output=True)
        a, b = _weights(straight), _weights(killed)
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
        subprocess.run(_cli(*_common(tiny_cache, out, 3, workers=0)), check=True, env=_env(), capture_output=True)
        r = subprocess.run(_cli(*_common(tiny_cache, out, 4, workers=0), "--lr", "1e-3"), check=False, env=_env(),
                           capture_output=True, text=True)
        assert r.returncode == 1 and "other settings" in r.stderr

    def test_torchrun_ddp_gloo_two_processes(self, tiny_cache, tmp_path) -> None:
        out = tmp_path / "ddp"
        cmd = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc-per-node", "2",
               "-m", "kornia_ilum", "train", *_common(tiny_cache, out, 2, workers=0)]
        r = subprocess.run(cmd, check=False, env=_env(), capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr[-3000:]
        summary = json.loads((out / "summary.json").read_text())
        assert summary["world_size"] == 2 and summary["steps"] == 2
        assert set(_weights(out)) == set(OursEstimator().state_dict())


class TestBadInput:
    def test_errors_leave_no_folder(self, tiny_cache, tmp_path) -> None:
        from kornia_ilum.core.errors import ValueCheckError
        from kornia_ilum.train import train

        with pytest.raises(ValueCheckError, match="no reflectance field"):
            train(TrainConfig(out=str(tmp_path / "a"), cache=(str(tmp_path / "missing"),)))
        with pytest.raises(ValueCheckError, match=r"unknown data settings \['nope'\]"):
            train(TrainConfig(out=str(tmp_path / "b"), cache=(str(tiny_cache),), data={"nope": 1}))
        with pytest.raises(ValueCheckError, match="no training recipe for estimator 'uniform'"):
            train(TrainConfig(out=str(tmp_path / "c"), cache=(str(tiny_cache),), estimator="uniform"))
        with pytest.raises(ValueCheckError, match="steps must be a positive integer"):
            TrainConfig(out=str(tmp_path / "d"), cache=(str(tiny_cache),), steps=0)
        assert not any((tmp_path / n).exists() for n in "abcd")


class TestExport:
    def test_float16_only_when_l_rec_moves_less_than_the_tolerance(self, tmp_path) -> None:
        from kornia_ilum.train import export_weights

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
