"""kornia_ilum_lab.train.config: the settings of a run and what is decided of them for the device."""

from __future__ import annotations

import dataclasses

import pytest
import torch

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum_lab.train import BRDF_WEIGHTS, RuntimeSettings, TrainConfig, resolve_runtime


class TestTrainConfig:
    def test_defaults_are_the_papers(self) -> None:
        c = TrainConfig(out="run", cache=["a", "b"])
        assert (c.batch, c.lr, c.disc_lr_ratio, c.betas, c.lambda_adv, c.lambda_scale) == (
            32, 1.5e-4, 0.01, (0.9, 0.999), 0.004, 1.0)
        assert c.cache == ("a", "b") and c.brdf_weights == BRDF_WEIGHTS and c.brdf_weights is not BRDF_WEIGHTS
        assert c.bf16 is None and c.channels_last is None and c.workers is None  # decided by resolve_runtime
        assert c.multi_scale and c.loss == "rendering"

    @pytest.mark.parametrize("bad", [{"steps": 0}, {"batch": True}, {"workers": -1}, {"cache": ()},
                                     {"lr": 0.0}, {"lambda_adv": -1.0}, {"lambda_crop": -1.0},
                                     {"lambda_energy": -0.1}, {"snapshot_every": -1},
                                     {"crop_pairs": 0}, {"lambda_crop": 1.0, "crop_pairs": 17},
                                     {"multi_scale": 1}, {"loss": "l2"}])
    def test_bad_settings(self, bad) -> None:
        with pytest.raises(ValueCheckError):
            TrainConfig(**{"out": "run", "cache": ("a",), **bad})

    def test_data_key_leaves_out_what_may_change_on_resume(self) -> None:
        c = TrainConfig(out="run", cache=("a",))
        key = c.data_key()
        assert not {"out", "steps", "threads", "checkpoint_every", "log_every"} & set(key)
        assert key == dataclasses.replace(c, out="other", steps=9, threads=1, log_every=5).data_key()
        assert key != dataclasses.replace(c, lr=1e-3).data_key()
        assert key["bf16"] is None  # as given: the checkpoint's key never holds what the device decided


class TestResolveRuntime:
    def test_given_settings_are_kept(self) -> None:
        c = TrainConfig(out="run", cache=("a",), bf16=False, channels_last=False, workers=3)
        assert resolve_runtime(c, torch.device("cpu")) == RuntimeSettings(bf16=False, channels_last=False,
                                                                          workers=3)

    def test_none_is_decided_for_the_device(self) -> None:
        cpu = resolve_runtime(TrainConfig(out="run", cache=("a",)), torch.device("cpu"))
        assert cpu.bf16 == bool(torch.ops.mkldnn._is_mkldnn_bf16_supported())
        assert cpu.channels_last is True and cpu.workers == 1
        cuda = resolve_runtime(TrainConfig(out="run", cache=("a",)), torch.device("cuda"))
        assert cuda.bf16 is True and 1 <= cuda.workers <= 8

    def test_memory_format(self) -> None:
        assert RuntimeSettings(bf16=False, channels_last=True, workers=0).memory_format == torch.channels_last
        contiguous = RuntimeSettings(bf16=True, channels_last=False, workers=0)
        assert contiguous.memory_format == torch.contiguous_format
