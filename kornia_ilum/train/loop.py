r"""The training loop of ``kornia-ilum train``: :class:`TrainConfig` and :func:`train`.

One step (LeGendre et al. 2020, Sec. 3.4):

1. the generator predicts lighting at 4, 8, 16 and 32 px (:class:`~kornia_ilum.train.models.MultiScaleOurs`);
   the ground truth is brought to the same sizes by the energy-keeping pyramid of SPEC.md, "Multi-scale";
2. the discriminator (:class:`~kornia_ilum.train.models.MSGDiscriminator`) takes one Adam step on the clipped
   mirror balls of the truth (real) and of the prediction (fake, detached): the logistic loss
   ``softplus(-D(real)) + softplus(D(fake))``;
3. the generator takes one Adam step on
   ``sum_s lambda_s sum_k lambda_k L_rec(k, s) + lambda_adv softplus(-D(fake))``, with the training form of
   ``L_rec`` (:func:`~kornia_ilum.metrics.reconstruction_loss`, ``gamma="safe"``).

Everything that makes a run reproducible is in the checkpoint (``OUT/checkpoint.pt``, written atomically
every ``checkpoint_every`` steps): both networks, both optimisers, the step, the wall time so far and the
configuration. The data of step ``t`` is a pure function of ``(seed, t, rank, world, workers)``
(:mod:`kornia_ilum.train.data`), so a run killed at any point and resumed gives the weights of an
uninterrupted run, bit for bit on the same machine and thread count.

Outputs in ``OUT``: ``log.csv`` (one row per ``log_every`` steps), ``loss.png``, ``checkpoint.pt``,
``summary.json`` and, at the end, the estimator's weights ``<name>.safetensors`` (:func:`export_weights`).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch
import torch.nn.functional as F

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.core.files import atomic_write

__all__ = ["BRDF_WEIGHTS", "TRAINING_PORTRAITS", "TrainConfig", "export_weights", "read_log", "train", "train_step",
           "training_losses"]

#: lambda_k of the paper: mirror 0.2, diffuse 0.6, matte silver 0.2.
BRDF_WEIGHTS: dict[str, float] = {"diffuse": 0.6, "matte_silver": 0.2, "mirror": 0.2}
#: What training changes in the :class:`~kornia_ilum.synth.lightstage.portraits.PortraitConfig` defaults
#: (before ``TrainConfig.data``): no sphere targets in the samples (the losses make their own).
TRAINING_PORTRAITS: dict[str, Any] = {"sphere_sizes": ()}
_LOG_FIELDS = ("step", "samples", "elapsed_s", "samples_per_s", "loss", "rec", "adv", "disc", "extra",
               "rec_diffuse", "rec_matte_silver", "rec_mirror")


@dataclass(frozen=True)
class TrainConfig:
    r"""Everything a training run depends on (stored in its checkpoint and summary).

    Args:
        out: the run's folder (created; a checkpoint there is resumed).
        cache: light-stage cache folders (:func:`~kornia_ilum.synth.lightstage.build_cache`); the ``"train"``
            subjects of all of them are used.
        hdri: folders of real lat-long maps; only each folder's ``"train"`` maps
            (:class:`~kornia_ilum.synth.environments.HDRFolderSource` ``split="train"``) join the procedural
            skies and rooms.
        estimator: the registry name of the estimator to train (``"ours"``).
        steps: generator steps in all.
        batch: samples per step, over all processes (the paper's 32).
        lr: the generator's Adam learning rate (1.5e-4); the discriminator's is ``lr * disc_lr_ratio`` (1/100).
        betas: Adam's betas (0.9, 0.999).
        lambda_scale, lambda_adv: the weights of each scale's ``L_rec`` (1) and of the adversarial term (0.004).
        seed: the seed of the data and of the initialisation.
        workers: data-loader worker processes per rank (0: in the training process); ``None``: 1 on CPU (the
            data costs about a tenth of a step there), ``min(8, cores - 1)`` on CUDA, where one worker's 150 to
            200 samples/s would starve the GPU.
        threads: torch threads of the training process (``None``: torch's default).
        device: ``"cpu"``, ``"cuda"`` or ``"cuda:N"`` (under ``torchrun`` each rank takes its local GPU).
        bf16: run the networks under bfloat16 autocast (losses stay float32); ``None``: on CUDA, and on CPUs
            with native bfloat16 (AVX-512 BF16 or AMX, oneDNN's check), where ``benchmarks/bench_train.py``
            measured a step at 0.53x the float32 time together with ``channels_last`` (AMD EPYC Zen 4).
        channels_last: the networks and crops in channels-last memory format; ``None``: on (0.65x alone).
        checkpoint_every, log_every: in steps.
        data: fields of :class:`~kornia_ilum.synth.lightstage.portraits.PortraitConfig` to replace (for
            example ``{"fields_per_chunk": 8}``), over :data:`TRAINING_PORTRAITS`; ``split`` and
            ``environments`` are set by the trainer.
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
    seed: int = 0
    workers: int | None = None
    threads: int | None = None
    device: str = "cpu"
    bf16: bool | None = None
    channels_last: bool | None = None
    checkpoint_every: int = 100
    log_every: int = 10
    brdf_weights: dict[str, float] = field(default_factory=lambda: dict(BRDF_WEIGHTS))
    data: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("steps", "batch", "checkpoint_every", "log_every"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v <= 0:
                raise ValueCheckError(f"{name} must be a positive integer, got {v!r}")
        if self.workers is not None and (isinstance(self.workers, bool) or not isinstance(self.workers, int)
                                         or self.workers < 0):
            raise ValueCheckError(f"workers must be a non-negative integer, got {self.workers!r}")
        if not self.cache:
            raise ValueCheckError("cache must name at least one light-stage cache folder")
        if not (self.lr > 0 and self.disc_lr_ratio > 0 and self.lambda_adv >= 0 and self.lambda_scale > 0):
            raise ValueCheckError("lr, disc_lr_ratio and lambda_scale must be positive, lambda_adv non-negative")
        object.__setattr__(self, "cache", tuple(str(c) for c in self.cache))
        object.__setattr__(self, "hdri", tuple(str(h) for h in self.hdri))
        object.__setattr__(self, "betas", tuple(float(b) for b in self.betas))

    def data_key(self) -> dict[str, Any]:
        """The settings that fix the data and the optimisation: a checkpoint resumes only if they agree."""
        skip = {"out", "steps", "threads", "checkpoint_every", "log_every"}
        return {k: v for k, v in dataclasses.asdict(self).items() if k not in skip}


# ------------------------------------------------------------------------------------------------ losses
def _pyramid(lighting: torch.Tensor, sizes) -> dict[int, torch.Tensor]:
    from kornia_ilum.render import mirror_ball_pyramid

    return mirror_ball_pyramid(lighting, sizes)


def _mirror_images(lightings: dict[int, torch.Tensor]) -> dict[int, torch.Tensor]:
    """The clipped, gamma-encoded mirror spheres that the discriminator sees, one per scale."""
    from kornia_ilum.render import sphere_pyramid

    return {s: sphere_pyramid(x, sizes=(s,), brdfs=("mirror",), gamma="safe")[f"mirror_{s}"]
            for s, x in lightings.items()}


def training_losses(pred: dict[int, torch.Tensor], target: torch.Tensor, brdf_weights: dict[str, float],
                    lambda_scale: float = 1.0, truth: dict[int, torch.Tensor] | None = None
                    ) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    r"""The multi-scale rendering loss ``sum_s lambda_s sum_k lambda_k L_rec(k, s)`` (training form).

    Args:
        pred: ``{size: (B, 3, size, size)}`` predicted linear lighting per scale.
        target: ``(B, 3, 32, 32)`` ground-truth lighting; brought to each size by the energy-keeping pyramid.
        brdf_weights: ``lambda_k`` per sphere.
        lambda_scale: ``lambda_s``, the same for every scale.
        truth: ``target``'s pyramid at the sizes of ``pred``, when the caller has it already.

    Returns:
        the loss and its parts: ``rec_<brdf>`` at 32 px (detached).
    """
    from kornia_ilum.metrics import reconstruction_loss

    if truth is None:
        truth = _pyramid(target, tuple(pred))
    total = target.new_zeros(())
    parts = {}
    for s, x in pred.items():
        for brdf, weight in brdf_weights.items():
            term = reconstruction_loss(x, truth[s], brdf, size=s, gamma="safe")
            total = total + lambda_scale * weight * term
            if s == max(pred):
                parts[f"rec_{brdf}"] = term.detach()
    return total, parts


def resolve_defaults(config: TrainConfig, device: torch.device) -> TrainConfig:
    """``config`` with ``bf16``, ``channels_last`` and ``workers`` decided where they are ``None``
    (:class:`TrainConfig`)."""
    bf16 = config.bf16
    if bf16 is None:
        bf16 = device.type == "cuda" or (device.type == "cpu" and torch.ops.mkldnn._is_mkldnn_bf16_supported())
    channels_last = True if config.channels_last is None else config.channels_last
    workers = config.workers
    if workers is None:
        workers = 1 if device.type == "cpu" else min(8, max(1, (os.cpu_count() or 2) - 1))
    return dataclasses.replace(config, bf16=bool(bf16), channels_last=bool(channels_last), workers=workers)


def train_step(model: torch.nn.Module, disc: torch.nn.Module | None, opt_g: torch.optim.Optimizer,
               opt_d: torch.optim.Optimizer | None, crops: torch.Tensor, target: torch.Tensor,
               config: TrainConfig, recipe: Any = None) -> dict[str, torch.Tensor]:
    r"""One discriminator step, then one generator step (module docstring); returns the detached losses.

    Args:
        model: the multi-scale generator (possibly DDP-wrapped): ``crops -> {size: lighting}``.
        disc: the discriminator (possibly DDP-wrapped) or ``None``.
        opt_g, opt_d: their optimisers.
        crops: ``(B, 3, 256, 256)`` sRGB in ``[0, 1]``, in the networks' memory format.
        target: ``(B, 3, 32, 32)`` linear ground-truth lighting.
        config: ``bf16``, ``channels_last``, the loss weights.
        recipe: its :meth:`~kornia_ilum.train.recipes.Recipe.extra_losses` join the generator's loss.
    """
    memory = torch.channels_last if config.channels_last else torch.contiguous_format
    autocast = torch.autocast(crops.device.type, dtype=torch.bfloat16, enabled=config.bf16)
    with autocast:
        pred = model(crops)
    truth = _pyramid(target, tuple(pred))  # the losses' targets, and the discriminator's real images
    rec, parts = training_losses(pred, target, config.brdf_weights, config.lambda_scale, truth)
    adv = disc_loss = rec.new_zeros(())
    if disc is not None:
        plain = getattr(disc, "module", disc)  # the generator's step needs no gradient sync of the discriminator
        real, fake = _mirror_images(truth), _mirror_images(pred)
        both = {s: torch.cat([real[s], fake[s].detach()]).contiguous(memory_format=memory) for s in real}
        with autocast:
            logits = disc(both).float()
        n = len(target)
        disc_loss = F.softplus(-logits[:n]).mean() + F.softplus(logits[n:]).mean()
        opt_d.zero_grad(set_to_none=True)
        disc_loss.backward()
        opt_d.step()
        with autocast:
            adv = F.softplus(-plain({s: v.contiguous(memory_format=memory) for s, v in fake.items()}).float()).mean()
    extra = sum((recipe.extra_losses(pred) if recipe is not None else {}).values(), rec.new_zeros(()))
    loss = rec + config.lambda_adv * adv + extra
    opt_g.zero_grad(set_to_none=True)
    loss.backward()
    opt_g.step()
    return {"loss": loss.detach(), "rec": rec.detach(), "adv": adv.detach(), "disc": disc_loss.detach(),
            "extra": extra.detach(), **parts}


# ----------------------------------------------------------------------------------------------- helpers
def _world() -> tuple[int, int, int]:
    """(rank, world size, local rank) from torchrun's environment."""
    return (int(os.environ.get("RANK", "0")), int(os.environ.get("WORLD_SIZE", "1")),
            int(os.environ.get("LOCAL_RANK", "0")))


def _environments(config: TrainConfig):
    from kornia_ilum.synth.environments import EnvironmentSampler, HDRFolderSource, default_sources

    sources = default_sources() + [HDRFolderSource(folder, split="train") for folder in config.hdri]
    return EnvironmentSampler(sources=sources, seed=config.seed)


def _dataset(config: TrainConfig):
    from kornia_ilum.synth.lightstage.portraits import PortraitConfig, PortraitDataset, load_fields

    fields = [f for folder in config.cache for f in load_fields(folder, split="train")]
    allowed = {f.name for f in dataclasses.fields(PortraitConfig)} - {"split", "environments"}
    unknown = sorted(set(config.data) - allowed)
    if unknown:
        raise ValueCheckError(f"unknown data settings {unknown}; PortraitConfig has: {', '.join(sorted(allowed))}")
    overrides = {k: tuple(v) if isinstance(v, list) else v for k, v in config.data.items()}
    # No sphere targets: the losses render their own from each sample's mirror ball (train_step), and drawing
    # them would cost a fifth of the data's time. The images and lightings are the same either way.
    return PortraitDataset(fields, PortraitConfig(**{**TRAINING_PORTRAITS, **overrides, "split": "train",
                                                     "environments": _environments(config)}), seed=config.seed)


def _checkpoint_path(out: Path) -> Path:
    return out / "checkpoint.pt"


def _save_checkpoint(out: Path, state: dict[str, Any]) -> None:
    atomic_write(_checkpoint_path(out), lambda tmp: torch.save(state, tmp))


def _load_checkpoint(out: Path, config: TrainConfig) -> dict[str, Any] | None:
    path = _checkpoint_path(out)
    if not path.is_file():
        return None
    state = torch.load(path, map_location="cpu", weights_only=True)
    if state["data_key"] != json.loads(json.dumps(config.data_key())):
        raise ValueCheckError(
            f"{path} was written by a run with other settings; resume with the same settings or use a new --out "
            f"(checkpoint: {state['data_key']}, now: {config.data_key()})"
        )
    return state


def read_log(out: str | os.PathLike) -> list[dict[str, float]]:
    """The rows of a run's ``log.csv`` as dicts of floats."""
    path = Path(out) / "log.csv"
    if not path.is_file():
        return []
    with open(path, newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def _write_log(out: Path, rows: list[dict[str, float]], fields: tuple[str, ...]) -> None:
    def write(tmp: Path) -> None:
        with open(tmp, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=fields)
            w.writeheader()
            for row in rows:
                w.writerow({k: f"{row[k]:.6g}" for k in fields})

    atomic_write(out / "log.csv", write)


def _plot(out: Path, rows: list[dict[str, float]]) -> None:
    if not rows:
        return
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # the curve is optional; the CSV has the numbers
        return
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.5))
    steps = [r["step"] for r in rows]
    for key in ("rec_diffuse", "rec_matte_silver", "rec_mirror"):
        ax[0].plot(steps, [r[key] for r in rows], label=key.removeprefix("rec_"))
    ax[0].set(xlabel="step", ylabel="L_rec at 32 px (training form)", yscale="log")
    ax[0].legend()
    ax[1].plot(steps, [r["adv"] for r in rows], label="generator adversarial")
    ax[1].plot(steps, [r["disc"] for r in rows], label="discriminator")
    ax[1].set(xlabel="step", ylabel="logistic loss")
    ax[1].legend()
    fig.tight_layout()
    atomic_write(out / "loss.png", lambda tmp: fig.savefig(tmp, dpi=100))
    plt.close(fig)


def _status(step: int, steps: int, row: dict[str, float], remaining_s: float) -> None:
    eta = time.strftime("%H:%M:%S", time.gmtime(max(remaining_s, 0.0)))
    line = (f"train: step {step}/{steps} ({100 * step // steps}%)  loss {row['loss']:.4f}  "
            f"diffuse {row['rec_diffuse']:.4f}  {row['samples_per_s']:.1f} samples/s  ETA {eta}")
    end = "\r" if sys.stderr.isatty() and step < steps else "\n"
    print(line, end=end, file=sys.stderr, flush=True)


# ------------------------------------------------------------------------------------------------- train
def _recipe(name: str):
    from kornia_ilum.train.recipes import get_recipe

    return get_recipe(name)


def train(config: TrainConfig) -> dict[str, Any]:
    r"""Train (or resume) the estimator ``config.estimator`` on the light stage; returns the run's summary.

    Runs in one process, or under ``torchrun`` with DistributedDataParallel (gloo on CPU, NCCL on CUDA): each
    rank draws its own data streams and takes ``batch / world`` samples a step. Rank 0 writes the files.

    Args:
        config: the run (:class:`TrainConfig`).

    Returns:
        the summary (also ``OUT/summary.json``): steps, samples, wall time, hardware, final losses, the weight
        file and its SHA-256.

    Raises:
        ValueCheckError: bad settings, or a checkpoint in ``out`` from a run with other settings.
    """
    import torch.distributed as dist

    rank, world, local_rank = _world()
    if config.batch % world:
        raise ValueCheckError(f"batch ({config.batch}) must be a multiple of the number of processes ({world})")
    device = torch.device(config.device)
    if device.type == "cuda" and world > 1:
        device = torch.device("cuda", local_rank)
    if device.type == "cuda":
        torch.cuda.set_device(device)
    if world > 1 and not dist.is_initialized():
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo")
    if config.threads is not None:
        torch.set_num_threads(config.threads)
    precision = resolve_defaults(config, device)
    recipe = _recipe(config.estimator)
    dataset = recipe.dataset(_dataset(config))  # checks the caches, maps and data settings before any file
    out = Path(config.out)
    if rank == 0:
        out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(config.seed)
    model, disc = recipe.build()
    state = _load_checkpoint(out, config)
    start, elapsed = 0, 0.0
    if state is not None:
        model.load_state_dict(state["model"])
        if disc is not None:
            disc.load_state_dict(state["disc"])
        start, elapsed = int(state["step"]), float(state["elapsed_s"])
    memory = torch.channels_last if precision.channels_last else torch.contiguous_format
    model = model.to(device, memory_format=memory)
    disc = disc.to(device, memory_format=memory) if disc is not None else None
    opt_g = torch.optim.Adam(model.parameters(), lr=config.lr, betas=config.betas)
    opt_d = (torch.optim.Adam(disc.parameters(), lr=config.lr * config.disc_lr_ratio, betas=config.betas)
             if disc is not None else None)
    if state is not None:
        opt_g.load_state_dict(state["opt_g"])
        if opt_d is not None:
            opt_d.load_state_dict(state["opt_d"])
    model_ddp, disc_ddp = model, disc
    if world > 1:
        from torch.nn.parallel import DistributedDataParallel as DDP

        ids = [device.index] if device.type == "cuda" else None
        model_ddp = DDP(model, device_ids=ids)
        disc_ddp = DDP(disc, device_ids=ids) if disc is not None else None

    rows = [r for r in read_log(out) if r["step"] <= start] if rank == 0 else []
    if start >= config.steps:
        return _finish(config, precision, out, recipe, model, dataset, rows, elapsed, start, rank)
    batches = recipe.batches(dataset, config.batch // world, start, rank, world, precision.workers)
    window_t, window_n = time.perf_counter(), 0
    run_t0 = time.perf_counter()
    for step in range(start + 1, config.steps + 1):
        batch = next(batches)
        losses = recipe.step(model_ddp, disc_ddp, opt_g, opt_d, batch, device, precision)
        if not torch.isfinite(losses["loss"]):
            raise FloatingPointError(f"the training loss became {losses['loss'].item()} at step {step}; lower --lr")
        window_n += len(batch["image"]) * world
        if rank == 0 and (step % config.log_every == 0 or step == config.steps):
            now = time.perf_counter()
            rate = window_n / max(now - window_t, 1e-9)
            window_t, window_n = now, 0
            row = {"step": step, "samples": step * config.batch, "elapsed_s": elapsed + now - run_t0,
                   "samples_per_s": rate, **{k: v.item() for k, v in losses.items()}}
            rows.append(row)
            _status(step, config.steps, row, (config.steps - step) * config.batch / max(rate, 1e-9))
        if step % config.checkpoint_every == 0 or step == config.steps:
            if rank == 0:
                _write_log(out, rows, _LOG_FIELDS + recipe.log_fields)
                _save_checkpoint(out, {
                    "step": step, "elapsed_s": elapsed + time.perf_counter() - run_t0,
                    "model": model.state_dict(), "disc": disc.state_dict() if disc is not None else {},
                    "opt_g": opt_g.state_dict(), "opt_d": opt_d.state_dict() if opt_d is not None else {},
                    "data_key": json.loads(json.dumps(config.data_key())),
                })
                _plot(out, rows)
            if world > 1:
                dist.barrier()
    elapsed += time.perf_counter() - run_t0
    return _finish(config, precision, out, recipe, model, dataset, rows, elapsed, config.steps, rank)


def _finish(config: TrainConfig, resolved: TrainConfig, out: Path, recipe, model, dataset, rows, elapsed: float,
            step: int, rank: int) -> dict[str, Any]:
    """The summary and the exported weights; ``resolved`` is ``config`` with :func:`resolve_defaults` applied."""
    summary: dict[str, Any] = {
        "estimator": config.estimator, "steps": step, "samples": step * config.batch, "wall_time_s": elapsed,
        "world_size": _world()[1], "device": config.device, "threads": torch.get_num_threads(),
        "cpu": _cpu_name(), "torch": torch.__version__, "config": dataclasses.asdict(config),
        **{k: getattr(resolved, k) for k in ("bf16", "channels_last", "workers")},
        "final": rows[-1] if rows else None,
    }
    if rank == 0:
        estimator = recipe.estimator(model).cpu().float().eval()
        summary["weights"] = export_weights(estimator, out / f"{config.estimator}.safetensors",
                                            recipe.probe(dataset))
        atomic_write(out / "summary.json", lambda tmp: tmp.write_text(json.dumps(summary, indent=2) + "\n"))
    return summary


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    import platform

    return platform.processor() or platform.machine()


def export_weights(estimator: torch.nn.Module, path: str | os.PathLike, probe: dict[str, torch.Tensor],
                   tolerance: float = 1e-4) -> dict[str, Any]:
    r"""Write the estimator's weights as safetensors: float16 if that moves ``L_rec`` by less than ``tolerance``.

    ``L_rec`` (the metric form, all three spheres) is measured on ``probe`` (``image`` uint8 crops and
    ``mirror_ball`` truth) with the float32 weights and with the float16-rounded ones (both run in float32).

    Returns:
        ``{"file", "sha256", "dtype", "l_rec_change"}``.
    """
    import safetensors.torch

    from kornia_ilum.core.files import sha256_file
    from kornia_ilum.metrics import reconstruction_loss

    crops = probe["image"].float() / 255.0
    truth = probe["mirror_ball"].float()

    def scores(module: torch.nn.Module) -> torch.Tensor:
        with torch.no_grad():
            pred = module(crops).mirror_ball
            return torch.stack([reconstruction_loss(pred, truth, b) for b in BRDF_WEIGHTS])

    state = {k: v.detach().float().contiguous() for k, v in estimator.state_dict().items()}
    full = scores(estimator)
    rounded = {k: v.half().float() for k, v in state.items()}
    saved = {k: v.clone() for k, v in estimator.state_dict().items()}
    estimator.load_state_dict(rounded)
    half = scores(estimator)
    estimator.load_state_dict(saved)
    change = float((half - full).abs().max())
    use_half = change < tolerance and all(math.isfinite(float(v.abs().max())) for v in rounded.values())
    tensors = {k: (v.half() if use_half else v) for k, v in state.items()}
    path = Path(path)
    atomic_write(path, lambda tmp: safetensors.torch.save_file(tensors, str(tmp)))
    return {"file": path.name, "sha256": sha256_file(path), "dtype": "float16" if use_half else "float32",
            "l_rec_change": change, "l_rec_probe": dict(zip(BRDF_WEIGHTS, full.tolist(), strict=True))}
