r"""The settings of a training run: :class:`TrainConfig` (what is asked for) and :class:`RuntimeSettings`.

:class:`TrainConfig` is what a run depends on, as given: it is stored in the run's checkpoint and summary,
and a checkpoint resumes only under the same settings (:meth:`TrainConfig.data_key`). Three of its fields
may be ``None``, "decide for this device": ``bf16``, ``channels_last`` and ``workers``.
:func:`resolve_runtime` makes that decision once, at the start of :func:`~kornia_ilum_lab.train.train`, into a
separate :class:`RuntimeSettings`, so the configuration itself (and with it the checkpoint's key) stays as
given.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from typing import Any

import torch

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum_lab.train.losses import BRDF_WEIGHTS

__all__ = ["ENVIRONMENT_MIX_KEYS", "LOSSES", "RuntimeSettings", "TrainConfig", "resolve_runtime"]

#: The settings of ``TrainConfig.environment_mix`` (its docstring).
ENVIRONMENT_MIX_KEYS = ("portrait_share", "portrait_weights")

#: The losses on the lighting that :attr:`TrainConfig.loss` can name.
LOSSES: tuple[str, ...] = ("rendering", "log_l2")


@dataclass(frozen=True)
class TrainConfig:
    r"""Everything a training run depends on (stored in its checkpoint and summary).

    Args:
        out: the run's folder (created; a checkpoint there is resumed).
        cache: light-stage cache folders (:func:`~kornia_ilum_lab.synth.lightstage.build_cache`); the ``"train"``
            subjects of all of them are used.
        hdri: folders of real lat-long maps; only each folder's ``"train"`` maps
            (:class:`~kornia_ilum_lab.synth.environments.HDRFolderSource` ``split="train"``) join the procedural
            skies and rooms.
        estimator: the registry name of the estimator to train (``"ours"``).
        steps: generator steps in all.
        batch: samples per step, over all processes (the paper's 32).
        lr: the generator's Adam learning rate (1.5e-4); the discriminator's is ``lr * disc_lr_ratio``
            (1/100).
        betas: Adam's betas (0.9, 0.999).
        lambda_scale, lambda_adv: the weights of each scale's ``L_rec`` (1) and of the adversarial term
            (0.004).
        lambda_crop: the weight of the crop-consistency term (0: off). With it, the last ``crop_pairs``
            samples of each step are replaced by a second, jittered crop of the first ``crop_pairs``
            (:func:`~kornia_ilum_lab.synth.lightstage.portraits.inner_crop_boxes`), with the same lighting, and the
            generator is also asked to predict the same lighting from both crops of a pair
            (:func:`~kornia_ilum_lab.train.recipes.train_step`): an estimate that does not swing with the face
            detector's box (docs/training.rst, "Measured"). Recipes that keep the default
            :meth:`~kornia_ilum_lab.train.recipes.Recipe.step` have it.
        crop_pairs: the pairs per step with ``lambda_crop`` (8 of a batch of 32).
        lambda_colour: the weight of the colour-consistency term (0: off). With it, ``colour_pairs`` samples of
            each step (after the crop pairs' first crops) get a greyscale twin in place of as many samples at the
            end of the batch (before the crop pairs' second crops), with the greyscale lighting target
            (:func:`~kornia_ilum_lab.synth.colour_looks.apply_looks`), and the generator is also asked for one
            main light from both: ``1 - cos`` of the two predictions' luminance dipoles
            (:func:`~kornia_ilum_lab.train.recipes.colour_consistency`). Recipes that keep the default
            :meth:`~kornia_ilum_lab.train.recipes.Recipe.step` have it.
        colour_pairs: the pairs per step with ``lambda_colour`` (4).
        colour_teacher: with ``lambda_colour``, the colour photo's main light is the twin's target and gets no
            gradient from the term (``teacher`` of :func:`~kornia_ilum_lab.train.recipes.colour_consistency`);
            off, the two are pulled toward each other.
        lambda_energy: the weight of the energy term (0: off, the paper's loss): the log of each channel's
            energy against the truth's (:func:`~kornia_ilum_lab.train.losses.energy_loss`), which ``L_rec`` on
            gamma-encoded spheres lets drift low (docs/training.rst, "Why the energy drifts low"). Recipes
            that keep the default :meth:`~kornia_ilum_lab.train.recipes.Recipe.step` have it.
        lambda_nll: the weight of the scale's own term (0: off). With it, the scale leaves ``L_rec``: every
            scale's prediction is brought to the truth's energy before the rendering loss and the discriminator
            (:func:`~kornia_ilum_lab.train.losses.to_true_energy`), and the energy is learned by ``lambda_nll`` times
            the Laplace negative log-likelihood of the true log energy under the estimate's and the spread
            head's ``b`` (:func:`~kornia_ilum_lab.train.losses.energy_nll`; the model needs the head:
            ``--model spread_head=True``). docs/training.rst, "The scale apart".
        lambda_albedo: the weight of the auxiliary albedo task (0: off): the L1 of the training-only albedo
            head's log skin albedo against the subject's tone's (:func:`~kornia_ilum_lab.train.losses.albedo_loss`;
            the model needs the head: ``--model albedo_head=True``).
        multi_scale: the rendering loss at every scale of the generator (4, 8, 16 and 32 px, the paper's
            multi-scale loss); ``False``: at the finest scale only (the paper's ablation "no multi-scale loss":
            the coarser heads then learn from the adversarial term alone).
        loss: the loss on the lighting: ``"rendering"`` (the paper's ``L_rec`` on the three spheres) or
            ``"log_l2"`` (the paper's ablation: ``mean((log(1 + L_pred) - log(1 + L_true))^2)`` over each scale's
            mirror-ball texels, :func:`~kornia_ilum_lab.train.losses.log_l2_loss`, instead of ``L_rec``).
        seed: the seed of the data and of the initialisation.
        workers: data-loader worker processes per rank (0: in the training process); ``None``: 1 on CPU (there
            the data is a small part of a step), ``min(8, cores - 1)`` on CUDA, where one worker cannot keep
            the GPU fed (docs/training.rst, "Measured").
        threads: torch threads of the training process (``None``: torch's default).
        device: ``"cpu"``, ``"cuda"`` or ``"cuda:N"`` (under ``torchrun`` each rank takes its local GPU).
        bf16: run the networks under bfloat16 autocast (losses stay float32); ``None``: on CUDA, and on CPUs
            with native bfloat16 (AVX-512 BF16 or AMX, oneDNN's check), where it shortens a step, more so
            together with ``channels_last`` (``benchmarks/bench_train.py``; docs/training.rst, "Measured").
        channels_last: the networks and crops in channels-last memory format; ``None``: on (it shortens a step
            without bfloat16 too).
        checkpoint_every, log_every: in steps.
        snapshot_every: keep the estimator's float32 weights every this many steps (0: never), as
            ``snapshots/step_NNNNNN.safetensors`` with the step, samples and wall time in the file's metadata:
            what ``kornia-ilum evaluate --curve RUN`` scores for the learning curve
            (:func:`~kornia_ilum_lab.evaluation.curve.learning_curve`).
        average_tail: export the mean of the snapshots of the run's last ``average_tail`` fraction of steps
            instead of the last step's weights (0: the last step's). That is stochastic weight averaging
            (Izmailov et al. 2018, "Averaging Weights Leads to Wider Optima and Better Generalization"): at a
            constant learning rate the weights keep wandering around a minimum, and their mean tends to lie
            nearer it than any one of them (measured once: docs/training.rst, "Twice the portraits"). Needs
            ``snapshot_every``; the networks have no batch statistics to recompute. Only the export depends on
            it, so a finished run exported again with it trains nothing.
        calibrate_energy: after training, scale each output channel so that the median ratio of estimated to
            true energy is 1 on this many fresh portraits of the training distribution (0: off;
            :func:`~kornia_ilum_lab.train.calibration.calibrate_energy`, which says why ``L_rec`` leaves a bias).
            Only the export depends on it, as for ``average_tail``.
        calibrate_colour: the same with the gains' luminance kept: the estimate's white balance alone
            (``keep_luminance`` of :func:`~kornia_ilum_lab.train.calibration.calibrate_energy`); not with
            ``calibrate_energy``.
        fit_spread: after training, fit the estimator's spread head alone, the rest frozen, on this many fresh
            portraits of the training distribution (0: off; :func:`~kornia_ilum_lab.train.calibration.fit_spread`;
            the model needs ``spread_head``). With ``steps=0`` and ``init``, the only thing the run does.
            Only the export depends on it, as for ``average_tail``.
        model: constructor arguments of the estimator to train (for example ``{"normalize_exposure": False}``),
            passed to the recipe's ``build`` (:class:`~kornia_ilum_lab.train.recipes.Recipe`).
        init: a ``.safetensors`` file of the estimator's weights to start from instead of its random
            initialisation (fine-tuning: the side branches, the discriminator and the optimisers start fresh);
            a checkpoint in ``out`` takes precedence, as for any run.
        data: fields of :class:`~kornia_ilum_lab.synth.lightstage.portraits.PortraitConfig` to replace (for
            example ``{"fields_per_chunk": 8}``), over :data:`~kornia_ilum_lab.train.data.TRAINING_PORTRAITS`;
            ``split`` and ``environments`` are set by the trainer.
        environment_mix: the training environments' mix, replacing the portrait lights' defaults:
            ``portrait_share`` (their share of all draws,
            :data:`~kornia_ilum_lab.synth.environments.portrait.PORTRAIT_SHARE` by default) and
            ``portrait_weights`` (one weight per kind of
            :data:`~kornia_ilum_lab.synth.environments.portrait.PORTRAIT_KINDS`); empty: the defaults. A study's
            knob (docs/training.rst, "The third round"): shipped weights use the defaults, whose shares have their
            reasons in :mod:`~kornia_ilum_lab.synth.environments.portrait`.

    Raises:
        ValueCheckError: a setting out of its range (a step count that is not a positive integer, no cache,
            an unknown ``loss``, ``average_tail`` without ``snapshot_every``, more crop pairs than half a
            batch, ...).

    Examples:
        >>> config = TrainConfig(out="runs/ours", cache=("lightstage/",))
        >>> config.estimator, config.steps, config.batch, config.bf16
        ('ours', 3000, 32, None)
        >>> "out" in config.data_key(), "seed" in config.data_key()  # what a checkpoint must agree on
        (False, True)
        >>> TrainConfig(out="runs/x", cache=("lightstage/",), average_tail=0.25)
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: average_tail averages the run's snapshots: it needs snapshot_every > 0
    """

    out: str
    cache: tuple[str, ...]
    hdri: tuple[str, ...] = ()
    estimator: str = "ours"
    steps: int = 3000
    batch: int = 32
    lr: float = 1.5e-4
    disc_lr_ratio: float = 0.01
    betas: tuple[float, float] = (0.9, 0.999)
    lambda_scale: float = 1.0
    lambda_adv: float = 0.004
    lambda_crop: float = 0.0
    crop_pairs: int = 8
    lambda_colour: float = 0.0
    colour_pairs: int = 4
    colour_teacher: bool = False
    lambda_energy: float = 0.0
    lambda_nll: float = 0.0
    lambda_albedo: float = 0.0
    multi_scale: bool = True
    loss: str = "rendering"
    seed: int = 0
    workers: int | None = None
    threads: int | None = None
    device: str = "cpu"
    bf16: bool | None = None
    channels_last: bool | None = None
    checkpoint_every: int = 100
    log_every: int = 10
    snapshot_every: int = 0
    average_tail: float = 0.0
    calibrate_energy: int = 0
    calibrate_colour: int = 0
    fit_spread: int = 0
    brdf_weights: dict[str, float] = field(default_factory=lambda: dict(BRDF_WEIGHTS))
    model: dict[str, Any] = field(default_factory=dict)
    init: str | None = None
    data: dict[str, Any] = field(default_factory=dict)
    environment_mix: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("steps", "batch", "checkpoint_every", "log_every", "crop_pairs", "colour_pairs"):
            v = getattr(self, name)
            zero_ok = name == "steps" and self.init is not None  # 0 steps from --init: an export alone
            if isinstance(v, bool) or not isinstance(v, int) or v < 0 or (v == 0 and not zero_ok):
                raise ValueCheckError(f"{name} must be a positive integer{' (0 only with init)' * (name == 'steps')}"
                                      f", got {v!r}")
        every = self.snapshot_every
        if isinstance(every, bool) or not isinstance(every, int) or every < 0:
            raise ValueCheckError(f"snapshot_every must be a non-negative integer, got {self.snapshot_every!r}")
        for name in ("calibrate_energy", "calibrate_colour", "fit_spread"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise ValueCheckError(f"{name} must be a non-negative integer, got {v!r}")
        unknown = sorted(set(self.environment_mix) - set(ENVIRONMENT_MIX_KEYS))
        if unknown:
            raise ValueCheckError(f"environment_mix takes {ENVIRONMENT_MIX_KEYS}, got {unknown}")
        if self.calibrate_energy and self.calibrate_colour:
            raise ValueCheckError("calibrate_energy already sets each channel's gain: calibrate_colour is a part of it")
        if not 0 <= self.average_tail < 1:
            raise ValueCheckError(f"average_tail must be in [0, 1), got {self.average_tail!r}")
        if self.average_tail > 0 and not self.snapshot_every:
            raise ValueCheckError("average_tail averages the run's snapshots: it needs snapshot_every > 0")
        if self.workers is not None and (isinstance(self.workers, bool) or not isinstance(self.workers, int)
                                         or self.workers < 0):
            raise ValueCheckError(f"workers must be a non-negative integer, got {self.workers!r}")
        if not self.cache:
            raise ValueCheckError("cache must name at least one light-stage cache folder")
        if not (self.lr > 0 and self.disc_lr_ratio > 0 and self.lambda_adv >= 0 and self.lambda_scale > 0):
            raise ValueCheckError(
                "lr, disc_lr_ratio and lambda_scale must be positive, lambda_adv non-negative"
            )
        if not self.lambda_crop >= 0:
            raise ValueCheckError(f"lambda_crop must be non-negative, got {self.lambda_crop!r}")
        if not self.lambda_colour >= 0:
            raise ValueCheckError(f"lambda_colour must be non-negative, got {self.lambda_colour!r}")
        if not self.lambda_energy >= 0:
            raise ValueCheckError(f"lambda_energy must be non-negative, got {self.lambda_energy!r}")
        if not self.lambda_nll >= 0:
            raise ValueCheckError(f"lambda_nll must be non-negative, got {self.lambda_nll!r}")
        if not self.lambda_albedo >= 0:
            raise ValueCheckError(f"lambda_albedo must be non-negative, got {self.lambda_albedo!r}")
        if not isinstance(self.colour_teacher, bool):
            raise ValueCheckError(f"colour_teacher must be True or False, got {self.colour_teacher!r}")
        if not isinstance(self.multi_scale, bool):
            raise ValueCheckError(f"multi_scale must be True or False, got {self.multi_scale!r}")
        if self.loss not in LOSSES:
            raise ValueCheckError(f"loss must be one of {', '.join(LOSSES)}, got {self.loss!r}")
        if self.lambda_crop > 0 and 2 * self.crop_pairs > self.batch:
            raise ValueCheckError(f"crop_pairs ({self.crop_pairs}) must be at most half the batch ({self.batch})")
        paired = 2 * self.crop_pairs * (self.lambda_crop > 0) + 2 * self.colour_pairs
        if self.lambda_colour > 0 and paired > self.batch:
            raise ValueCheckError(f"twice the crop pairs and the colour pairs ({paired}) must fit in the batch "
                                  f"({self.batch})")
        if self.init is not None:
            object.__setattr__(self, "init", str(self.init))
        object.__setattr__(self, "cache", tuple(str(c) for c in self.cache))
        object.__setattr__(self, "hdri", tuple(str(h) for h in self.hdri))
        object.__setattr__(self, "betas", tuple(float(b) for b in self.betas))

    def data_key(self) -> dict[str, Any]:
        """The settings that fix the data and the optimisation: a checkpoint resumes only if they agree (a
        setting that a checkpoint predates counts as its default there)."""
        skip = {"out", "steps", "threads", "checkpoint_every", "log_every", "snapshot_every", "average_tail",
                "calibrate_energy", "calibrate_colour", "fit_spread"}
        return {k: v for k, v in dataclasses.asdict(self).items() if k not in skip}


@dataclass(frozen=True)
class RuntimeSettings:
    r"""How a run executes on its device: the ``None`` settings of :class:`TrainConfig`, decided.

    Made by :func:`resolve_runtime`, once per run; the configuration keeps its ``None``.

    Args:
        bf16: the networks run under bfloat16 autocast (the losses stay float32).
        channels_last: the networks and crops are in channels-last memory format.
        workers: data-loader worker processes per rank (0: in the training process).

    Examples:
        >>> RuntimeSettings(bf16=False, channels_last=True, workers=1).memory_format
        torch.channels_last
    """

    bf16: bool
    channels_last: bool
    workers: int

    @property
    def memory_format(self) -> torch.memory_format:
        """``torch.channels_last`` or ``torch.contiguous_format``, after :attr:`channels_last`."""
        return torch.channels_last if self.channels_last else torch.contiguous_format


def resolve_runtime(config: TrainConfig, device: torch.device) -> RuntimeSettings:
    r"""``config``'s ``bf16``, ``channels_last`` and ``workers``, decided for ``device`` where ``None``.

    ``bf16``: on CUDA, and on CPUs with native bfloat16; ``channels_last``: on; ``workers``: 1 on CPU,
    ``min(8, cores - 1)`` on CUDA (:class:`TrainConfig`). Settings that are given are kept.

    Args:
        config: the run's settings.
        device: the device the run trains on.

    Returns:
        the :class:`RuntimeSettings`, none of them ``None``.

    Examples:
        >>> config = TrainConfig(out="run", cache=("cache",), bf16=False, workers=0)
        >>> resolve_runtime(config, torch.device("cpu"))
        RuntimeSettings(bf16=False, channels_last=True, workers=0)
    """
    bf16 = config.bf16
    if bf16 is None:
        native = device.type == "cpu" and torch.ops.mkldnn._is_mkldnn_bf16_supported()
        bf16 = device.type == "cuda" or native
    channels_last = True if config.channels_last is None else config.channels_last
    workers = config.workers
    if workers is None:
        workers = 1 if device.type == "cpu" else min(8, max(1, (os.cpu_count() or 2) - 1))
    return RuntimeSettings(bf16=bool(bf16), channels_last=bool(channels_last), workers=workers)
