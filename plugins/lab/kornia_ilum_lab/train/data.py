r"""Training data from the light stage: the dataset of a run, and its batches addressable by step, so that a
resumed run sees the same data.

:func:`training_dataset` builds the portraits of a :class:`~kornia_ilum_lab.train.TrainConfig`: the ``"train"``
subjects of its caches, relit under procedural skies and rooms plus the ``"train"`` maps of its ``hdri``
folders, with :data:`TRAINING_PORTRAITS` and the run's ``data`` settings.

Batch ``t`` of rank ``r`` with ``W`` loader workers is batch ``t // W`` of the stream
``r * W + t % W`` of a :class:`~kornia_ilum_lab.synth.lightstage.portraits.PortraitDataset`: each stream is the
dataset's own sample order for that worker (:meth:`PortraitDataset.samples`), cut into batches. A loader
worker owns the streams of every ``W``-th step, so the :class:`~torch.utils.data.DataLoader`'s round robin
over workers yields the steps in order; starting at step ``t0`` only regenerates the group of chunks that
step ``t0`` falls in. The streams depend on ``W`` and the world size, which a checkpoint records.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
from collections.abc import Iterator, Sequence
from typing import Any

import torch
from torch.utils.data import DataLoader, IterableDataset, get_worker_info

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.estimators.probe import PROBE_SAMPLES, write_probe
from kornia_ilum_lab.synth.environments import EnvironmentSampler, HDRFolderSource, PortraitLightSource, default_sources
from kornia_ilum_lab.synth.environments.portrait import PORTRAIT_SHARE
from kornia_ilum_lab.synth.lightstage.portraits import PortraitConfig, PortraitDataset, load_fields
from kornia_ilum_lab.train.config import TrainConfig

__all__ = ["PROBE_SEED", "TRAINING_PORTRAITS", "StepBatches", "batch_loader", "collate", "training_dataset",
           "write_training_probe"]

#: What training changes in the :class:`~kornia_ilum_lab.synth.lightstage.portraits.PortraitConfig` defaults
#: (before ``TrainConfig.data``): no sphere targets in the samples (the losses make their own); a plain backdrop
#: behind a quarter of the faces, so the model reads the light from the face, not from the background; the crop's
#: centre jittered by up to 10 % of its side (the evaluation's default 6 % is narrower than two detectors' boxes
#: of one face differ, docs/training.rst).
TRAINING_PORTRAITS: dict[str, Any] = {"sphere_sizes": (), "plain_background": 0.25, "crop_position": 0.10}


def _training_environments(config: TrainConfig) -> EnvironmentSampler:
    """The run's environments: the procedural sources plus the ``"train"`` maps of each folder of
    ``config.hdri``, drawn with ``config.seed``; the portrait lights' share and kind weights from
    ``config.environment_mix`` where it sets them (:class:`PortraitLightSource` checks them)."""
    sources = default_sources()
    if config.environment_mix:
        mix = config.environment_mix
        portrait = PortraitLightSource(weights=mix.get("portrait_weights"),
                                       share=mix.get("portrait_share", PORTRAIT_SHARE))
        sources = [portrait if isinstance(s, PortraitLightSource) else s for s in sources]
    sources += [HDRFolderSource(folder, split="train") for folder in config.hdri]
    return EnvironmentSampler(sources=sources, seed=config.seed)


def training_dataset(config: TrainConfig) -> PortraitDataset:
    """The run's portraits (module docstring), seeded with ``config.seed``.

    Args:
        config: the run's settings: its ``cache``, ``hdri``, ``seed``, ``data`` and ``lambda_crop`` (a second
            crop per sample when it is on).

    Returns:
        the endless dataset of the run's portraits, without sphere targets.

    Raises:
        ValueCheckError: no ``"train"`` subject in the caches, or ``config.data`` names a setting that
            :class:`~kornia_ilum_lab.synth.lightstage.portraits.PortraitConfig` does not have.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as empty:
        ...     training_dataset(TrainConfig(out=empty, cache=(empty,)))  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: no reflectance field in '...' for split 'train'
        >>> dataset = training_dataset(TrainConfig(out="runs/ours", cache=("lightstage/",)))  # doctest: +SKIP
        >>> sample = next(iter(dataset))  # doctest: +SKIP
        >>> tuple(sample["image"].shape), sample["image"].dtype, tuple(sample["mirror_ball"].shape)  # doctest: +SKIP
        ((3, 256, 256), torch.uint8, (3, 32, 32))
    """
    fields = [f for folder in config.cache for f in load_fields(folder, split="train")]
    allowed = {f.name for f in dataclasses.fields(PortraitConfig)} - {"split", "environments"}
    unknown = sorted(set(config.data) - allowed)
    if unknown:
        known = ", ".join(sorted(allowed))
        raise ValueCheckError(f"unknown data settings {unknown}; PortraitConfig has: {known}")
    overrides = {k: tuple(v) if isinstance(v, list) else v for k, v in config.data.items()}
    if config.lambda_crop > 0:  # the crop-consistency term cuts each pair's second crop from these boxes
        overrides["second_crop"] = True
    # No sphere targets: the losses render their own from each sample's mirror ball (train_step), and drawing
    # them would take a good part of the data's time (docs/training.rst, "Measured"). The images and
    # lightings are the same either way.
    return PortraitDataset(fields, PortraitConfig(**{**TRAINING_PORTRAITS, **overrides, "split": "train",
                                                     "environments": _training_environments(config)}),
                           seed=config.seed)


#: The seed of the shipped probe's portraits (training runs use 0 and 1).
PROBE_SEED = 7


def write_training_probe(folder: str | os.PathLike[str], cache: Sequence[str | os.PathLike[str]],
                         *,
                         hdri: Sequence[str | os.PathLike[str]] = (), samples: int = PROBE_SAMPLES,
                         seed: int = PROBE_SEED) -> dict[str, Any]:
    r"""Write the runtimes' probe (:mod:`kornia_ilum.estimators.probe`) from the training portraits.

    ``samples`` portraits of :func:`training_dataset` (the ``"train"`` subjects of ``cache`` under the
    procedural environments and the ``"train"`` maps of ``hdri``, :data:`TRAINING_PORTRAITS`), one lighting per
    view and a chunk of 8 views, so the probe spans many subjects; drawn with ``seed``, not a training run's.

    Args:
        folder: the folder that gets ``probe.jpg`` and ``probe.safetensors``
            (:func:`~kornia_ilum.estimators.probe.write_probe`).
        cache: light-stage caches with ``"train"`` subjects.
        hdri: folders of real maps (their ``"train"`` maps).
        samples: the number of portraits.
        seed: the seed of the portraits.

    Returns:
        the probe's metadata (also stored in ``probe.safetensors``).

    Raises:
        ValueCheckError: as :func:`training_dataset`.

    Examples:
        >>> from kornia_ilum.estimators.probe import PROBE_SAMPLES
        >>> PROBE_SAMPLES  # the portraits it writes
        320

        It relights subjects of a light-stage cache (``kornia-ilum export --probe DIR --cache CACHE`` calls it):

        >>> meta = write_training_probe("probe/", ["lightstage/"], hdri=["hdri/"])  # doctest: +SKIP
        >>> meta["samples"], meta["split"], meta["seed"]  # doctest: +SKIP
        (320, 'train', 7)
    """
    config = TrainConfig(out=str(folder), cache=[str(c) for c in cache], hdri=[str(h) for h in hdri], seed=seed,
                         data={"fields_per_chunk": 8, "lightings_per_field": 1, "env_pool": 8, "env_refresh": 8,
                               "shuffle": 1})
    dataset = training_dataset(config)
    images, balls, tones, subjects, labels, sources = [], [], [], [], [], []
    for sample in itertools.islice(dataset, samples):
        images.append(sample["image"])
        balls.append(sample["mirror_ball"].float())
        tones.append(int(sample["skin_tone"]))
        subjects.append(int(sample["subject_seed"]))
        labels.append(str(sample["label"]))
        sources.append(str(sample["source"]))
    meta = {"samples": len(images), "split": "train", "seed": seed, "caches": config.cache, "hdri": config.hdri,
            "subjects": sorted(set(subjects)), "skin_tones": {str(t): tones.count(t) for t in sorted(set(tones))},
            "portraits": "TRAINING_PORTRAITS, one lighting per view, 8 views per chunk",
            "per_sample": {"label": labels, "skin_tone": tones, "subject_seed": subjects, "source": sources}}
    write_probe(folder, torch.stack(images).float() / 255.0, torch.stack(balls), meta)
    return meta


def collate(samples: list[dict[str, Any]]) -> dict[str, Any]:
    """Stack what training reads: ``image`` (uint8), ``mirror_ball``, and the per-sample labels; for paired
    samples (``PortraitConfig.pairs``) also ``pair_image``, ``pair_mirror_ball`` and ``alpha`` (uint8); with
    ``PortraitConfig.second_crop``, ``second_crop`` ``(B, 4)``; with ``PortraitConfig.frame``, ``frame`` (uint8),
    ``frame_box`` and ``frame_window`` ``(B, 4)``.

    Args:
        samples: samples of a :class:`~kornia_ilum_lab.synth.lightstage.portraits.PortraitDataset`.

    Returns:
        the batch: ``image``, ``mirror_ball`` and ``skin_tone`` stacked, ``label`` a list, and the paired and
        second-crop fields where the samples have them.

    Shape:
        - image: :math:`(B, 3, S, S)` uint8; mirror_ball: :math:`(B, 3, 32, 32)`; skin_tone: :math:`(B,)`

    Convention:
        ``image`` holds sRGB codes (docs/conventions.rst, "Images", times 255); ``mirror_ball`` is linear
        lighting in their units ("Mirror ball", "Units of lighting").

    Examples:
        >>> sample = {"image": torch.zeros(3, 8, 8, dtype=torch.uint8), "mirror_ball": torch.ones(3, 32, 32),
        ...           "label": "indoor", "skin_tone": 5}
        >>> batch = collate([sample, sample])
        >>> tuple(batch["image"].shape), tuple(batch["mirror_ball"].shape), batch["label"]
        ((2, 3, 8, 8), (2, 3, 32, 32), ['indoor', 'indoor'])
    """
    batch = {
        "image": torch.stack([s["image"] for s in samples]),
        "mirror_ball": torch.stack([s["mirror_ball"] for s in samples]),
        "label": [s["label"] for s in samples],
        "skin_tone": torch.tensor([s["skin_tone"] for s in samples]),
    }
    if "pair" in samples[0]:
        batch["pair_image"] = torch.stack([s["pair"]["image"] for s in samples])
        batch["pair_mirror_ball"] = torch.stack([s["pair"]["mirror_ball"] for s in samples])
        batch["alpha"] = torch.stack([s["alpha"] for s in samples])
    if "second_crop" in samples[0]:
        batch["second_crop"] = torch.stack([s["second_crop"] for s in samples])
    if "frame" in samples[0]:
        batch["frame"] = torch.stack([s["frame"] for s in samples])
        batch["frame_box"] = torch.stack([s["frame_box"] for s in samples])
        batch["frame_window"] = torch.stack([s["frame_window"] for s in samples])
    return batch


class StepBatches(IterableDataset):
    r"""The batches of steps ``start, start + 1, ...`` of one rank (module docstring).

    Args:
        dataset: the portraits (endless: ``config.length`` is ``None``).
        batch: samples per batch on this rank.
        start: the first step.
        rank, world: this process's rank and the number of processes.
        workers: the loader's workers (0: the batches are made in the iterating process).

    Examples:
        Its batches are drawn from a light-stage cache's portraits:

        >>> config = TrainConfig(out="runs/ours", cache=("lightstage/",))
        >>> steps = StepBatches(training_dataset(config), batch=8, start=100)  # doctest: +SKIP
        >>> batch = next(iter(steps))  # doctest: +SKIP
        >>> tuple(batch["image"].shape)  # doctest: +SKIP
        (8, 3, 256, 256)
    """

    def __init__(self, dataset: PortraitDataset, batch: int, *, start: int = 0, rank: int = 0, world: int = 1,
                 workers: int = 0) -> None:
        super().__init__()
        self.dataset, self.batch, self.start = dataset, batch, start
        self.rank, self.world, self.workers = rank, world, workers

    def _stream(self, step: int) -> int:
        w = max(self.workers, 1)
        return self.rank * w + step % w

    def _batches(self, first: int) -> Iterator[dict[str, Any]]:
        """Batches of steps ``first, first + W, ...``: consecutive batches of one stream."""
        w = max(self.workers, 1)
        position = first // w  # the batch's index within its stream
        samples = self.dataset.samples(self._stream(first), start=position * self.batch)
        while True:
            yield collate([next(samples) for _ in range(self.batch)])

    def __iter__(self) -> Iterator[dict[str, Any]]:
        info = get_worker_info()
        if info is None:  # in process: interleave the streams of all the steps' residues
            w = max(self.workers, 1)
            streams = [self._batches(self.start + k) for k in range(w)]
            while True:
                for stream in streams:
                    yield next(stream)
        torch.set_num_threads(1)
        yield from self._batches(self.start + info.id)


def batch_loader(dataset: PortraitDataset, batch: int, *, start: int = 0, rank: int = 0, world: int = 1,
                 workers: int = 0) -> Iterator[dict[str, Any]]:
    """An endless iterator of the batches of steps ``start, start + 1, ...`` (:class:`StepBatches`).

    Args:
        dataset: the portraits.
        batch: samples per batch on this rank.
        start: the first step.
        rank: this process's rank.
        world: the number of processes.
        workers: loader worker processes (forked; 0: the batches are made in this process).

    Returns:
        the iterator of collated batches (:func:`collate`), in step order.

    Examples:
        >>> config = TrainConfig(out="runs/ours", cache=("lightstage/",))
        >>> batches = batch_loader(training_dataset(config), batch=8, workers=2)  # doctest: +SKIP
        >>> sorted(next(batches))  # doctest: +SKIP
        ['image', 'label', 'mirror_ball', 'skin_tone']
    """
    steps = StepBatches(dataset, batch, start=start, rank=rank, world=world, workers=workers)
    if workers == 0:
        return iter(steps)
    loader = DataLoader(steps, batch_size=None, num_workers=workers, persistent_workers=False,
                        prefetch_factor=2, multiprocessing_context="fork")
    return iter(loader)
