"""``kornia-ilum train``: train an estimator on the light stage (:func:`kornia_ilum_lab.train.train`)."""

from __future__ import annotations

import argparse

from kornia_ilum.core.cli import key_value, nonnegative_int, positive_int
from kornia_ilum_lab.train.config import TrainConfig
from kornia_ilum_lab.train.loop import train
from kornia_ilum_lab.train.losses import BRDF_WEIGHTS

_HELP = """\
Train a lighting estimator on the virtual light stage, as LeGendre et al. 2020 did: portraits relit on the
fly from the reflectance fields of a cache (kornia-ilum synth subjects) with procedural skies and rooms plus
the real maps of --hdri (only their "train" split: the "eval" maps are held out for kornia-ilum evaluate),
multi-scale sphere-render losses and the MSG-GAN discriminator.

The run's folder OUT gets log.csv, loss.png, checkpoint.pt (atomic, every --checkpoint-every steps),
summary.json and at the end the weights NAME.safetensors. Running the same command again resumes from the
checkpoint and gives the weights of an uninterrupted run.

multi-process (DDP: gloo on CPU, NCCL on GPU):
  torchrun --standalone --nproc-per-node 2 -m kornia_ilum train --cache CACHE --out OUT ...

examples:
  kornia-ilum train --cache cache/ --hdri ../shared/data/hdri ../shared/data/hdri_more --out runs/ours
  kornia-ilum train --cache cache/ --out runs/gpu --device cuda --workers 8 --steps 20000
"""


def add_train_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add ``train`` to the ``kornia-ilum`` subcommands.

    Args:
        subparsers: the subparsers of ``kornia-ilum``'s parser (:meth:`argparse.ArgumentParser.add_subparsers`).

    Returns:
        the ``train`` parser, with :class:`~kornia_ilum_lab.train.TrainConfig`'s defaults; its ``func`` default is
        :func:`run_train`.

    Examples:
        >>> parser = argparse.ArgumentParser()
        >>> _ = add_train_parser(parser.add_subparsers())
        >>> args = parser.parse_args(["train", "--cache", "lightstage/", "--out", "runs/ours",
        ...                           "--model", "normalize_exposure=False"])
        >>> args.steps, args.model, args.func is run_train
        (3000, [('normalize_exposure', False)], True)
    """
    d = TrainConfig(out="", cache=("-",))
    cmd = subparsers.add_parser("train", help="train an estimator on the light stage",
                                description=_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    cmd.add_argument("--estimator", default=d.estimator, help=f"what to train (default: {d.estimator})")
    cmd.add_argument("--cache", nargs="+", required=True, metavar="DIR", help="light-stage cache folders")
    cmd.add_argument("--hdri", nargs="*", default=[], metavar="DIR", help="folders of real lat-long HDR maps")
    cmd.add_argument("--out", required=True, metavar="OUT", help="the run's folder (resumed if it has a checkpoint)")
    cmd.add_argument("--steps", type=nonnegative_int, default=d.steps,
                     help=f"generator steps (default: {d.steps}; 0 with --init: export only)")
    cmd.add_argument("--batch", type=positive_int, default=d.batch, help=f"samples per step (default: {d.batch})")
    cmd.add_argument("--lr", type=float, default=d.lr, help=f"generator learning rate (default: {d.lr})")
    cmd.add_argument("--seed", type=int, default=d.seed, help="seed of the data and the initialisation")
    cmd.add_argument("--workers", type=int, default=None,
                     help="data workers per process (default: 1 on CPU, min(8, cores - 1) on CUDA)")
    cmd.add_argument("--threads", type=positive_int, default=None, help="torch threads of the training process")
    cmd.add_argument("--device", default=d.device, help="cpu, cuda or cuda:N (default: cpu)")
    cmd.add_argument("--bf16", action=argparse.BooleanOptionalAction, default=d.bf16,
                     help="bfloat16 autocast for the networks (default: on CUDA and on CPUs with native bf16; "
                     "see benchmarks/bench_train.py)")
    cmd.add_argument("--channels-last", action=argparse.BooleanOptionalAction, default=d.channels_last,
                     help="channels-last memory format (default: on)")
    cmd.add_argument("--checkpoint-every", type=positive_int, default=d.checkpoint_every, metavar="N")
    cmd.add_argument("--log-every", type=positive_int, default=d.log_every, metavar="N")
    cmd.add_argument("--snapshot-every", type=int, default=d.snapshot_every, metavar="N",
                     help="keep the estimator's weights every N steps in RUN/snapshots/, for the learning curve "
                     "of `kornia-ilum evaluate --curve RUN` (default: 0, never)")
    cmd.add_argument("--average-tail", type=float, default=d.average_tail, metavar="F",
                     help="export the mean of the snapshots of the run's last fraction F of steps (stochastic "
                     "weight averaging; needs --snapshot-every; rerunning a finished run with it only "
                     "re-exports; default: 0, the last step's weights)")
    cmd.add_argument("--calibrate-energy", type=int, default=d.calibrate_energy, metavar="N",
                     help="at export, scale each colour channel so that the median estimated energy is the "
                     "truth's on N fresh training portraits (L_rec's bias to dark; docs/training.rst; "
                     "rerunning a finished run with it only re-exports; default: 0, off)")
    cmd.add_argument("--calibrate-colour", type=int, default=d.calibrate_colour, metavar="N",
                     help="at export, the same gains with their luminance kept: the estimate's white balance "
                     "alone (not with --calibrate-energy; default: 0, off)")
    cmd.add_argument("--fit-spread", type=int, default=d.fit_spread, metavar="N",
                     help="at export, fit the spread head alone (the rest frozen) on N fresh training portraits: "
                     "the Laplace likelihood of the true log energy (needs --model spread_head=True; with "
                     "--steps 0 --init WEIGHTS the run does only this; default: 0, off)")
    cmd.add_argument("--lambda-adv", type=float, default=d.lambda_adv,
                     help=f"weight of the adversarial term (default: {d.lambda_adv}; 0 turns it off)")
    cmd.add_argument("--lambda-crop", type=float, default=d.lambda_crop,
                     help="weight of the crop-consistency term (default: 0, off; docs/training.rst)")
    cmd.add_argument("--crop-pairs", type=positive_int, default=d.crop_pairs, metavar="P",
                     help=f"crop pairs per step with --lambda-crop (default: {d.crop_pairs})")
    cmd.add_argument("--lambda-colour", type=float, default=d.lambda_colour,
                     help="weight of the colour-consistency term: portraits and their greyscale twins asked for "
                     "one main light (default: 0, off; docs/training.rst)")
    cmd.add_argument("--colour-pairs", type=positive_int, default=d.colour_pairs, metavar="P",
                     help=f"greyscale twins per step with --lambda-colour (default: {d.colour_pairs})")
    cmd.add_argument("--colour-teacher", action="store_true",
                     help="with --lambda-colour, the colour photo's main light is its twin's target and is not "
                     "pulled toward the twin's (default: both pulled)")
    cmd.add_argument("--lambda-energy", type=float, default=d.lambda_energy,
                     help="weight of the log-energy term (default: 0, off: the paper's loss; docs/training.rst)")
    cmd.add_argument("--lambda-nll", type=float, default=d.lambda_nll,
                     help="weight of the scale's own term: L_rec made blind to the scale, which the Laplace "
                     "likelihood of the true log energy then learns with its spread (needs --model "
                     "spread_head=True; default: 0, off; docs/training.rst)")
    cmd.add_argument("--lambda-albedo", type=float, default=d.lambda_albedo,
                     help="weight of the auxiliary task of reading the skin's albedo from the bottleneck (needs "
                     "--model albedo_head=True, a training-only head; default: 0, off; docs/training.rst)")
    cmd.add_argument("--init", default=None, metavar="WEIGHTS",
                     help="start from these .safetensors weights of the estimator (fine-tuning)")
    cmd.add_argument("--model", nargs="*", default=[], metavar="KEY=VALUE", type=key_value,
                     help="constructor arguments of the estimator, e.g. normalize_exposure=False")
    cmd.add_argument("--data", nargs="*", default=[], metavar="KEY=VALUE", type=key_value,
                     help="PortraitConfig settings of the light-stage data, e.g. fields_per_chunk=8 shuffle=2")
    cmd.add_argument("--environment-mix", nargs="*", default=[], metavar="KEY=VALUE", type=key_value,
                     help="the training environments' mix, a study's knob: portrait_share=S (the portrait "
                     "lights' share of all draws, default 0.25) and portrait_weights=(flash,studio,window,"
                     "street,screen) (default: the light stage's; docs/environments.rst)")
    cmd.set_defaults(func=run_train, brdf_weights=dict(BRDF_WEIGHTS))
    return cmd


def run_train(args: argparse.Namespace) -> int:
    """Run ``kornia-ilum train``; prints the weight file and its SHA-256.

    Args:
        args: the options of :func:`add_train_parser`'s parser.

    Returns:
        the exit status, 0 (a failure raises).

    Examples:
        It trains, so it is not run here:

        >>> parser = argparse.ArgumentParser()
        >>> _ = add_train_parser(parser.add_subparsers())
        >>> run_train(parser.parse_args(["train", "--cache", "lightstage/", "--out", "runs/ours"]))  # doctest: +SKIP
        0
    """
    config = TrainConfig(out=args.out, cache=tuple(args.cache), hdri=tuple(args.hdri), estimator=args.estimator,
                         steps=args.steps, batch=args.batch, lr=args.lr, seed=args.seed, workers=args.workers,
                         threads=args.threads, device=args.device, bf16=args.bf16,
                         channels_last=args.channels_last, checkpoint_every=args.checkpoint_every,
                         log_every=args.log_every, snapshot_every=args.snapshot_every,
                         average_tail=args.average_tail, calibrate_energy=args.calibrate_energy,
                         calibrate_colour=args.calibrate_colour, fit_spread=args.fit_spread,
                         lambda_adv=args.lambda_adv, lambda_crop=args.lambda_crop, crop_pairs=args.crop_pairs,
                         lambda_colour=args.lambda_colour, colour_pairs=args.colour_pairs,
                         colour_teacher=args.colour_teacher,
                         lambda_energy=args.lambda_energy, lambda_nll=args.lambda_nll,
                         lambda_albedo=args.lambda_albedo, init=args.init, model=dict(args.model),
                         data=dict(args.data), environment_mix=dict(args.environment_mix))
    summary = train(config)
    if "weights" in summary:
        w = summary["weights"]
        print(f"{args.out}/{w['file']}  {w['dtype']}  sha256 {w['sha256']}  "
              f"{summary['steps']} steps in {summary['wall_time_s'] / 60:.1f} min")
    return 0
