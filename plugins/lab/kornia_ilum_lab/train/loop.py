r"""The training loop of ``kornia-ilum train``: :func:`train`, for the settings of a
:class:`~kornia_ilum_lab.train.TrainConfig`.

The loop draws the batches, checkpoints, logs and runs under DDP; each step is the estimator's recipe's
(:meth:`Recipe.step <kornia_ilum_lab.train.recipes.Recipe.step>`; for ``ours`` the default
:func:`~kornia_ilum_lab.train.recipes.train_step`: one discriminator step, then one generator step on the
multi-scale rendering loss, LeGendre et al. 2020, Sec. 3.4). The loop calls the recipe, never the other way.

Everything that makes a run reproducible is in the checkpoint (``OUT/checkpoint.pt``, written atomically
every ``checkpoint_every`` steps): both networks, both optimisers, the step, the wall time so far and the
configuration. The data of step ``t`` is a pure function of ``(seed, t, rank, world, workers)``
(:mod:`kornia_ilum_lab.train.data`), so a run killed at any point and resumed gives the weights of an
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
import platform
import sys
import time
from pathlib import Path
from typing import Any

import safetensors.torch
import torch
import torch.distributed as dist
from torch.nn.parallel import DistributedDataParallel

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.core.files import atomic_write, sha256_file
from kornia_ilum.estimators import read_weights
from kornia_ilum.metrics import reconstruction_loss
from kornia_ilum_lab.synth.lightstage.portraits import PortraitDataset
from kornia_ilum_lab.train.calibration import calibrate_energy, fit_spread
from kornia_ilum_lab.train.config import RuntimeSettings, TrainConfig, resolve_runtime
from kornia_ilum_lab.train.data import training_dataset
from kornia_ilum_lab.train.losses import BRDF_WEIGHTS
from kornia_ilum_lab.train.recipes import Recipe, get_recipe

__all__ = ["average_snapshots", "export_weights", "read_log", "save_snapshot", "train"]

_LOG_FIELDS = ("step", "samples", "elapsed_s", "samples_per_s", "loss", "rec", "adv", "disc", "extra",
               "rec_diffuse", "rec_matte_silver", "rec_mirror")


# ----------------------------------------------------------------------------------------------- helpers
def _world() -> tuple[int, int, int]:
    """(rank, world size, local rank) from torchrun's environment."""
    return (int(os.environ.get("RANK", "0")), int(os.environ.get("WORLD_SIZE", "1")),
            int(os.environ.get("LOCAL_RANK", "0")))


def _checkpoint_path(out: Path) -> Path:
    return out / "checkpoint.pt"


def _save_checkpoint(out: Path, state: dict[str, Any]) -> None:
    atomic_write(_checkpoint_path(out), lambda tmp: torch.save(state, tmp))


def _load_checkpoint(out: Path, config: TrainConfig) -> dict[str, Any] | None:
    path = _checkpoint_path(out)
    if not path.is_file():
        return None
    state = torch.load(path, map_location="cpu", weights_only=True)
    now = json.loads(json.dumps(config.data_key()))
    # a checkpoint written before a setting existed was trained with that setting's default
    defaults = json.loads(json.dumps(TrainConfig(out="", cache=("-",)).data_key()))
    stored = {**{k: defaults[k] for k in now.keys() - state["data_key"].keys()}, **state["data_key"]}
    if stored != now:
        raise ValueCheckError(
            f"{path} was written by a run with other settings; resume with the same settings or use a new --out "
            f"(checkpoint: {state['data_key']}, now: {config.data_key()})"
        )
    return state


def read_log(out: str | os.PathLike) -> list[dict[str, float]]:
    """The rows of a run's ``log.csv`` as dicts of floats.

    Args:
        out: the run's folder.

    Returns:
        one dict per row, column -> value; an empty list without ``log.csv``.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as run:
        ...     empty = read_log(run)
        ...     _ = (Path(run) / "log.csv").write_text("step,loss\\n10,0.5\\n20,0.25\\n")
        ...     empty, read_log(run)
        ([], [{'step': 10.0, 'loss': 0.5}, {'step': 20.0, 'loss': 0.25}])
    """
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

    fields = tuple(k for k in fields if not rows or k in rows[-1])  # a recipe without spheres logs none
    atomic_write(out / "log.csv", write)


def _plot(out: Path, rows: list[dict[str, float]]) -> None:
    if not rows:
        return
    try:
        import matplotlib  # lazy: only for the curve, and optional

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt  # lazy: as matplotlib, after the backend is set
    except ImportError:  # the curve is optional; the CSV has the numbers
        return
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.5))
    steps = [r["step"] for r in rows]
    for key in ("rec_diffuse", "rec_matte_silver", "rec_mirror") if "rec_diffuse" in rows[-1] else ("rec",):
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
            f"{'diffuse' if 'rec_diffuse' in row else 'rec'} {row.get('rec_diffuse', row['rec']):.4f}  "
            f"{row['samples_per_s']:.1f} samples/s  ETA {eta}")
    end = "\r" if sys.stderr.isatty() and step < steps else "\n"
    print(line, end=end, file=sys.stderr, flush=True)


# ------------------------------------------------------------------------------------------------- train
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
        FloatingPointError: the loss became NaN or infinite.

    Examples:
        A run trains (``kornia-ilum train`` calls it), so it is not run here:

        >>> config = TrainConfig(out="runs/ours", cache=("lightstage/",), steps=3000)
        >>> summary = train(config)  # doctest: +SKIP
        >>> summary["steps"], summary["weights"]["file"]  # doctest: +SKIP
        (3000, 'ours.safetensors')
    """
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
    runtime = resolve_runtime(config, device)
    recipe = get_recipe(config.estimator)
    portraits = training_dataset(config)  # checks caches, maps and data settings before any file
    dataset = recipe.dataset(portraits)
    out = Path(config.out)
    torch.manual_seed(config.seed)
    try:
        model, disc = recipe.build(**config.model)
    except TypeError as exc:  # a recipe whose build takes no options
        if not config.model:
            raise
        raise ValueCheckError(f"estimator {config.estimator!r} takes no model options {sorted(config.model)}") from exc
    if config.lambda_adv == 0:  # no adversarial term: no discriminator to train (built first, so the RNG is the same)
        disc = None
    state = _load_checkpoint(out, config)
    start, elapsed = 0, 0.0
    if state is None and config.init is not None:  # fine-tuning: the estimator starts from these weights
        tensors, _ = read_weights(config.init, expected_by="--init")
        try:
            recipe.estimator(model).load_state_dict(tensors, strict=True)
        except RuntimeError as exc:
            raise ValueCheckError(f"init {config.init} holds no weights of estimator {config.estimator!r}: "
                                  f"{exc}") from exc
    if rank == 0:
        out.mkdir(parents=True, exist_ok=True)
    if state is not None:
        model.load_state_dict(state["model"])
        if disc is not None:
            disc.load_state_dict(state["disc"])
        start, elapsed = int(state["step"]), float(state["elapsed_s"])
    memory = runtime.memory_format
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
        ids = [device.index] if device.type == "cuda" else None
        model_ddp = DistributedDataParallel(model, device_ids=ids)
        disc_ddp = DistributedDataParallel(disc, device_ids=ids) if disc is not None else None

    rows = [r for r in read_log(out) if r["step"] <= start] if rank == 0 else []
    if start >= config.steps:
        return _finish(config, runtime, out=out, recipe=recipe, model=model, dataset=dataset,
                       portraits=portraits, rows=rows, elapsed=elapsed, step=start, rank=rank)
    batches = recipe.batches(dataset, config.batch // world, start=start, rank=rank, world=world,
                             workers=runtime.workers)
    window_t, window_n = time.perf_counter(), 0
    run_t0 = time.perf_counter()
    for step in range(start + 1, config.steps + 1):
        batch = next(batches)
        losses = recipe.step(model=model_ddp, disc=disc_ddp, opt_g=opt_g, opt_d=opt_d, batch=batch,
                             device=device, config=config, runtime=runtime)
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
        if rank == 0 and config.snapshot_every and step % config.snapshot_every == 0:
            save_snapshot(out, recipe.estimator(model), name=config.estimator, step=step,
                          samples=step * config.batch, elapsed_s=elapsed + time.perf_counter() - run_t0)
        if step % config.checkpoint_every == 0 or step == config.steps:
            if rank == 0:
                terms = tuple(name for name, weight in (("crop", config.lambda_crop), ("colour", config.lambda_colour),
                                                        ("energy", config.lambda_energy),
                                                        ("nll", config.lambda_nll), ("spread", config.lambda_nll),
                                                        ("albedo", config.lambda_albedo))
                              if weight > 0)  # a term is logged where it is on
                _write_log(out, rows, _LOG_FIELDS + terms + recipe.log_fields)
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
    return _finish(config, runtime, out=out, recipe=recipe, model=model, dataset=dataset,
                   portraits=portraits, rows=rows, elapsed=elapsed, step=config.steps, rank=rank)


def _finish(config: TrainConfig, runtime: RuntimeSettings, *, out: Path, recipe: Recipe,
            model: torch.nn.Module, dataset: PortraitDataset, portraits: PortraitDataset,
            rows: list[dict[str, float]], elapsed: float, step: int, rank: int) -> dict[str, Any]:
    """The summary and the exported weights; ``dataset`` is the recipe's training data (the float16 probe's),
    ``portraits`` the training portraits before :meth:`~kornia_ilum_lab.train.recipes.Recipe.dataset` (the
    calibrations draw the recipe's ``calibration_dataset`` of them)."""
    summary: dict[str, Any] = {
        "estimator": config.estimator, "steps": step, "samples": step * config.batch, "wall_time_s": elapsed,
        "world_size": _world()[1], "device": config.device, "threads": torch.get_num_threads(),
        "cpu": _cpu_name(), "torch": torch.__version__, "config": dataclasses.asdict(config),
        **dataclasses.asdict(runtime),  # bf16, channels_last, workers
        "final": rows[-1] if rows else None,
    }
    if rank == 0:
        estimator = recipe.estimator(model).cpu().float().eval()
        if config.average_tail > 0:
            averaged, steps = average_snapshots(out, after=(1 - config.average_tail) * step, upto=step)
            estimator.load_state_dict(averaged, strict=True)
            summary["averaged_snapshots"] = steps
        if config.calibrate_energy or config.calibrate_colour or config.fit_spread:
            calibration = recipe.calibration_dataset(portraits)
            if config.calibrate_energy:
                summary["energy_calibration"] = calibrate_energy(estimator, recipe, calibration, config.calibrate_energy)
            if config.calibrate_colour:
                summary["colour_calibration"] = calibrate_energy(estimator, recipe, calibration,
                                                                 config.calibrate_colour, keep_luminance=True)
            if config.fit_spread:
                summary["spread_fit"] = fit_spread(estimator, calibration, samples=config.fit_spread)
        path, probe = out / f"{config.estimator}.safetensors", recipe.probe(dataset)
        summary["weights"] = recipe.export(estimator, path, probe) or export_weights(estimator, path, probe)
        atomic_write(out / "summary.json", lambda tmp: tmp.write_text(json.dumps(summary, indent=2) + "\n"))
    return summary


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def save_snapshot(out: str | os.PathLike, estimator: torch.nn.Module, *, name: str, step: int, samples: int,
                  elapsed_s: float) -> Path:
    r"""Keep the estimator's float32 weights at ``step``: ``out/snapshots/step_NNNNNN.safetensors``.

    The file's safetensors metadata holds ``estimator`` (the registry name), ``step``, ``samples`` and
    ``elapsed_s`` (the run's training wall time so far): what the learning curve
    (:func:`~kornia_ilum_lab.evaluation.curve.learning_curve`) reads. Written atomically.

    Args:
        out: the run's folder (``snapshots/`` is created in it).
        estimator: the estimator whose ``state_dict`` is kept.
        name: its registry name.
        step: the training step.
        samples: the samples seen so far.
        elapsed_s: the run's training wall time so far, in seconds.

    Returns:
        the path of the snapshot.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as run:
        ...     save_snapshot(run, torch.nn.Linear(2, 1), name="ours", step=100, samples=3200,
        ...                   elapsed_s=60.0).name
        'step_000100.safetensors'
    """
    path = Path(out) / "snapshots" / f"step_{step:06d}.safetensors"
    path.parent.mkdir(parents=True, exist_ok=True)
    tensors = {k: v.detach().float().cpu().contiguous() for k, v in estimator.state_dict().items()}
    meta = {"estimator": name, "step": str(step), "samples": str(samples), "elapsed_s": f"{elapsed_s:.3f}"}
    atomic_write(path, lambda tmp: safetensors.torch.save_file(tensors, str(tmp), metadata=meta))
    return path


def average_snapshots(out: str | os.PathLike, after: float,
                      upto: int) -> tuple[dict[str, torch.Tensor], list[int]]:
    r"""The mean of a run's snapshots (:func:`save_snapshot`) of steps ``after < step <= upto``, and their steps.

    Floating-point tensors are averaged in float64 and returned in float32; any other tensor is the last
    snapshot's. Used by :attr:`~kornia_ilum_lab.train.TrainConfig.average_tail` (stochastic weight averaging).

    Args:
        out: the run's folder.
        after: the snapshots of steps above this are averaged (a fraction of the run's steps, so a float).
        upto: and of steps up to this.

    Returns:
        ``(mean, steps)``: the averaged ``state_dict`` and the steps of the snapshots in it, in order.

    Raises:
        ValueCheckError: no snapshot in that range.

    Examples:
        >>> import tempfile
        >>> model = torch.nn.Linear(2, 1, bias=False)
        >>> with tempfile.TemporaryDirectory() as run:
        ...     for step in (100, 200, 300):
        ...         _ = torch.nn.init.constant_(model.weight, step / 100)
        ...         _ = save_snapshot(run, model, name="ours", step=step, samples=32 * step, elapsed_s=1.0)
        ...     mean, steps = average_snapshots(run, after=150, upto=300)
        >>> steps, mean["weight"].tolist()
        ([200, 300], [[2.5, 2.5]])
    """
    found = []
    for path in sorted((Path(out) / "snapshots").glob("step_*.safetensors")):
        with safetensors.safe_open(str(path), "pt") as f:
            step = int(f.metadata()["step"])
        if after < step <= upto:
            found.append((step, path))
    if not found:
        raise ValueCheckError(f"no snapshot of a step in ({after:g}, {upto}] in {Path(out) / 'snapshots'} to "
                              "average; train with snapshot_every")
    snapshots = [safetensors.torch.load_file(str(path)) for _, path in found]
    mean = {k: torch.stack([s[k].double() for s in snapshots]).mean(0).float() if v.is_floating_point() else v
            for k, v in snapshots[-1].items()}
    return mean, [step for step, _ in found]


def export_weights(estimator: torch.nn.Module, path: str | os.PathLike, probe: dict[str, torch.Tensor],
                   tolerance: float = 1e-4) -> dict[str, Any]:
    r"""Write the estimator's weights as safetensors: float16 if that moves ``L_rec`` by less than ``tolerance``.

    ``L_rec`` (the metric form, all three spheres) is measured on ``probe`` (``image`` uint8 crops and
    ``mirror_ball`` truth) with the float32 weights and with the float16-rounded ones (both run in float32).

    Args:
        estimator: the estimator to export: ``estimator(crops).mirror_ball`` from sRGB crops in ``[0, 1]``.
        path: the ``.safetensors`` file to write.
        probe: a collated batch with ``image`` (uint8 crops) and ``mirror_ball`` (their lighting)
            (:meth:`~kornia_ilum_lab.train.recipes.Recipe.probe`).
        tolerance: the largest change of ``L_rec`` (any sphere) that float16 weights may make.

    Returns:
        ``{"file", "sha256", "dtype", "l_rec_change"}``, and ``l_rec_probe``: the float32 weights' ``L_rec``
        on the probe per sphere.

    Examples:
        Not run here: the first ``L_rec`` of a process builds the spheres' render operators, which is slow.

        >>> import tempfile
        >>> from types import SimpleNamespace
        >>> class Constant(torch.nn.Module):  # a lighting of 1 everywhere, whatever the crop
        ...     def __init__(self):
        ...         super().__init__()
        ...         self.light = torch.nn.Parameter(torch.ones(3, 1, 1))
        ...     def forward(self, crops):
        ...         return SimpleNamespace(mirror_ball=self.light.expand(len(crops), 3, 32, 32))
        >>> probe = {"image": torch.zeros(2, 3, 8, 8, dtype=torch.uint8), "mirror_ball": torch.ones(2, 3, 32, 32)}
        >>> with tempfile.TemporaryDirectory() as run:  # doctest: +SKIP
        ...     done = export_weights(Constant(), Path(run) / "constant.safetensors", probe)
        >>> done["file"], done["dtype"], done["l_rec_change"]  # doctest: +SKIP
        ('constant.safetensors', 'float16', 0.0)
    """
    crops = probe["image"].float() / 255.0
    truth = probe["mirror_ball"].float()

    def scores(module: torch.nn.Module) -> torch.Tensor:
        with torch.no_grad():
            pred = module(crops).mirror_ball
            return torch.stack([reconstruction_loss(pred, truth, brdf=b) for b in BRDF_WEIGHTS])

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
