"""kornia_ilum_lab.train.data: the dataset of a run and its batches, addressable by step."""

from __future__ import annotations

import dataclasses
import itertools

import pytest
import torch

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum_lab.synth.environments import PortraitLightSource
from kornia_ilum_lab.synth.lightstage.portraits import PortraitDataset
from kornia_ilum_lab.train import TrainConfig
from kornia_ilum_lab.train.data import TRAINING_PORTRAITS, StepBatches, collate, training_dataset
from tests.lab.train.helpers import small_data

pytestmark = pytest.mark.slow  # the tiny_cache fixture renders with Mitsuba


class TestData:
    def test_batches_are_addressable_by_step(self, tiny_cache) -> None:
        """Starting at step 3 gives the batches that steps 3, 4 of a run from step 0 got (any worker count)."""
        dataset = training_dataset(TrainConfig(out="unused", cache=(str(tiny_cache),), data=small_data()))
        for workers in (0, 2):
            run = list(itertools.islice(iter(StepBatches(dataset, 2, start=0, workers=workers)), 5))
            late = list(itertools.islice(iter(StepBatches(dataset, 2, start=3, workers=workers)), 2))
            for a, b in zip(run[3:], late, strict=True):
                assert torch.equal(a["image"], b["image"]) and torch.equal(a["mirror_ball"], b["mirror_ball"])
        assert not torch.equal(run[0]["image"], run[1]["image"])

    def test_training_portraits_have_no_sphere_targets_and_the_same_images(self, tiny_cache) -> None:
        """Training drops the samples' sphere targets (the losses make their own), puts a plain backdrop behind a
        quarter of the faces and jitters the crop's centre as detectors do; the sphere targets change nothing
        else."""
        data = small_data()
        dataset = training_dataset(TrainConfig(out="unused", cache=(str(tiny_cache),), data=data))
        assert TRAINING_PORTRAITS == {"sphere_sizes": (), "plain_background": 0.25, "crop_position": 0.10}
        assert dataset.config.sphere_sizes == () and dataset.config.plain_background == 0.25
        full = PortraitDataset(dataset.fields, dataclasses.replace(dataset.config, sphere_sizes=(4, 32)),
                               seed=dataset.seed)
        for a, b in zip(dataset.chunk(0, 1), full.chunk(0, 1), strict=True):
            assert a["spheres"] == {} and set(b["spheres"]) >= {"diffuse_4", "mirror_32"}
            assert torch.equal(a["image"], b["image"]) and torch.equal(a["mirror_ball"], b["mirror_ball"])
        again = training_dataset(TrainConfig(out="unused", cache=(str(tiny_cache),),
                                             data={**data, "sphere_sizes": [32]}))
        assert again.config.sphere_sizes == (32,)  # TrainConfig.data still overrides it

    def test_dataset_of_the_config(self, tiny_cache) -> None:
        """The train split of the caches, the run's seed, and the environments of its folders."""
        config = TrainConfig(out="unused", cache=(str(tiny_cache),), data=small_data(), seed=7)
        dataset = training_dataset(config)
        assert dataset.seed == 7 and dataset.config.split == "train" and dataset.config.fields_per_chunk == 1
        assert all(f.meta["split"] == "train" for f in dataset.fields) and len(dataset.fields) == 2
        with pytest.raises(ValueCheckError, match=r"unknown data settings \['nope'\]"):
            training_dataset(dataclasses.replace(config, data={"nope": 1}))

    def test_environment_mix(self, tiny_cache) -> None:
        """The portrait lights' share and kind weights of ``environment_mix`` replace the defaults; the other
        sources are untouched, and bad settings fail before any portrait is made."""
        config = TrainConfig(out="unused", cache=(str(tiny_cache),), data=small_data())
        default = training_dataset(config).environments
        mixed = training_dataset(dataclasses.replace(
            config, environment_mix={"portrait_share": 0.5, "portrait_weights": (0, 0, 0, 0, 1)})).environments
        portrait = [s for s in mixed.sources if isinstance(s, PortraitLightSource)]
        assert len(portrait) == 1 and portrait[0].default_share == 0.5 and portrait[0].weights[-1] == 1.0
        assert [type(s) for s in mixed.sources] == [type(s) for s in default.sources]
        drawn = {mixed.sample(i).source for i in range(40)}
        assert "portrait:screen" in drawn and not drawn & {"portrait:flash", "portrait:studio"}
        with pytest.raises(ValueCheckError, match="environment_mix takes"):
            dataclasses.replace(config, environment_mix={"sky_share": 0.1})
        with pytest.raises(ValueCheckError, match="weights must be 5"):
            training_dataset(dataclasses.replace(config, environment_mix={"portrait_weights": (1, 1)}))

    def test_collate(self, tiny_cache) -> None:
        dataset = training_dataset(TrainConfig(out="unused", cache=(str(tiny_cache),), data=small_data()))
        samples = dataset.samples(0)
        batch = collate([next(samples) for _ in range(3)])
        assert batch["image"].shape == (3, 3, 256, 256) and batch["image"].dtype == torch.uint8
        assert batch["mirror_ball"].shape == (3, 3, 32, 32) and len(batch["label"]) == 3
        assert batch["skin_tone"].shape == (3,) and "pair_image" not in batch
