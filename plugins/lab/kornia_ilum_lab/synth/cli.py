r"""``kornia-ilum synth``: lighting environments and the virtual light stage, with contact sheets.

``synth environments`` samples ``N`` environments with
:class:`~kornia_ilum_lab.synth.environments.EnvironmentSampler` (procedural skies, rooms and portrait lights, plus
the real maps of ``--folder``), with a progress bar (tqdm when it is installed, else a counter on stderr),
and writes into ``--out``:

- ``contact_sheet.png``: for each environment its 32 x 32 mirror ball and the three reference spheres
  rendered from it (diffuse, matte silver, mirror; :func:`kornia_ilum.render.render_spheres`), tone-mapped
  (:func:`~kornia_ilum_lab.synth.sheets.write_contact_sheet`);
- ``stats.txt`` and ``stats.csv``: the statistics of :mod:`kornia_ilum_lab.synth.stats`, per group (median and
  10th / 90th percentiles; procedural outdoor and indoor, the portrait lights, with ``--folder`` the real maps
  as captured and augmented), per source of the sampled environments (each sky condition, the rooms, each
  kind of portrait light, the real maps; :func:`~kornia_ilum_lab.synth.stats.source_group`) and per environment;
- ``stats.png``: the four histograms.

:func:`add_synth_environments_parser` adds the subcommand to an ``argparse`` subparsers action;
:func:`run_synth_environments` runs it from the parsed arguments.

``synth subjects`` renders the OLAT reflectance fields of light-stage subjects (MakeHuman or mannequins) into
a cache folder (:func:`~kornia_ilum_lab.synth.lightstage.build_cache`: random views, worker processes, resumable,
sharded with ``--worker I/N``, a progress bar with an ETA), then writes ``contact_sheet.png``: training
portraits composited from the cache with their ground-truth spheres
(:func:`~kornia_ilum_lab.synth.lightstage.preview.training_sheet`). :func:`add_synth_subjects_parser` and
:func:`run_synth_subjects` as above.

``synth check-skin`` runs the uniform-white check of
:mod:`~kornia_ilum_lab.synth.lightstage.calibration` over the subjects of a cache (its eval split by default): one
row per subject-view (tone, albedo, reading, energy ratio, the measured range), then how many passed; it exits
with 1 when any failed. :func:`add_synth_check_skin_parser` and :func:`run_synth_check_skin` as above.

Both contact sheets are drawn by :mod:`kornia_ilum_lab.synth.sheets`; the small argument types come from
:mod:`kornia_ilum.core.cli`.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from kornia_ilum.core.cli import fraction, nonnegative_int, positive_int
from kornia_ilum.core.errors import IlumError, ValueCheckError
from kornia_ilum.core.files import atomic_write
from kornia_ilum.core.progress import progress
from kornia_ilum_lab.provenance import stamp_figure
from kornia_ilum_lab.synth.sheets import require_matplotlib, write_contact_sheet

__all__ = [
    "add_synth_check_skin_parser",
    "add_synth_environments_parser",
    "add_synth_subjects_parser",
    "parse_seeds",
    "run_synth_check_skin",
    "run_synth_environments",
    "run_synth_subjects",
    "split_seeds",
]


#: What the figures of ``synth environments`` show (their provenance stamp, :mod:`kornia_ilum_lab.provenance`).
ENVIRONMENT_FIGURES_SHOW = ("kornia_ilum_lab.synth.environments", "kornia_ilum_lab.synth.sheets", "kornia_ilum_lab.synth.stats")
#: What the contact sheet of ``synth subjects`` shows: the light stage and the portraits made from it.
LIGHTSTAGE_FIGURES_SHOW = ("kornia_ilum_lab.synth",)


def _command_line(args: argparse.Namespace) -> str:
    """The command line that ran (``kornia-ilum`` sets it), for the figures' stamps."""
    return getattr(args, "command_line", None) or "kornia-ilum synth " + " ".join(sys.argv[1:])


_HELP = """\
Sample N lighting environments (procedural skies, rooms and portrait lights: flash, studio, window, street, screen;
plus the real maps of --folder; augmented by rotation, flip, exposure and white balance), and write into
--out: contact_sheet.png (mirror balls with their diffuse, matte-silver and mirror reference spheres),
stats.txt / stats.csv (dynamic range, peak-to-mean ratio, colour temperature, energy in the top 1 % of
pixels, per group and per source), and stats.png (their histograms per group). Environment i of seed S is
always the same.

examples:
  kornia-ilum synth environments -n 48 --out envs/
  kornia-ilum synth environments --folder ../shared/data/hdri -n 200 --sheet 48 --out envs/
"""


def _synth_subparsers(subparsers: argparse._SubParsersAction) -> argparse._SubParsersAction:
    """The subcommands of ``synth``, creating the ``synth`` command when it is not there yet."""
    synth = subparsers.choices.get("synth")
    if synth is None:
        synth = subparsers.add_parser(
            "synth", help="synthesis: lighting environments and light-stage subjects",
            description="Synthesis tools of kornia_ilum.",
        )
    nested = [a for a in synth._actions if isinstance(a, argparse._SubParsersAction)]
    if nested:
        return nested[0]
    return synth.add_subparsers(dest="synth_command", metavar="COMMAND", required=True)


def add_synth_environments_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add ``synth environments`` to ``subparsers`` (reusing a ``synth`` command that is already there).

    The ``environments`` parser's defaults hold ``func=run_synth_environments``.

    Args:
        subparsers: the subparsers action of the top-level parser (``parser.add_subparsers(...)``).

    Returns:
        the ``environments`` parser.

    Examples:
        >>> parser = argparse.ArgumentParser(prog="kornia-ilum")
        >>> add_synth_environments_parser(parser.add_subparsers(dest="command")).prog
        'kornia-ilum synth environments'
        >>> args = parser.parse_args(["synth", "environments", "-n", "4"])
        >>> args.n, args.seed, args.folder, args.func.__name__
        (4, 0, None, 'run_synth_environments')
    """
    sub = _synth_subparsers(subparsers)
    env = sub.add_parser(
        "environments",
        help="sample lighting environments: contact sheet and statistics",
        description=_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    env.add_argument("--folder", metavar="DIR", help="folder of lat-long .hdr/.exr maps to add")
    env.add_argument("-n", type=positive_int, default=48, metavar="N", help="environments to sample (48)")
    env.add_argument("--seed", type=int, default=0, metavar="S", help="seed (0)")
    env.add_argument(
        "--out", default="synth_environments", metavar="DIR", help="output folder (./synth_environments)"
    )
    env.add_argument(
        "--height", type=positive_int, default=128, metavar="H", help="lat-long height H x 2H (128)"
    )
    env.add_argument(
        "--sheet", type=nonnegative_int, default=48, metavar="K", help="environments on the sheet (48)"
    )
    env.add_argument("--no-augment", action="store_true", help="no rotation, flip, exposure or white balance")
    env.set_defaults(func=run_synth_environments)
    return env


def run_synth_environments(args: argparse.Namespace) -> int:
    """Run ``synth environments`` from parsed arguments (module docstring); prints the table, returns 0.

    ``args`` needs ``folder``, ``n``, ``seed``, ``out``, ``height``; ``sheet`` (default 48) and
    ``no_augment`` (default False) are optional.

    Args:
        args: the arguments parsed by the parser of :func:`add_synth_environments_parser`.

    Returns:
        the exit status, 0.

    Raises:
        HDRIOError: ``folder`` does not exist or holds no map.
        IlumError: matplotlib (needed for the figures; in the ``docs`` extra) is not installed.

    Examples:
        >>> parser = argparse.ArgumentParser(prog="kornia-ilum")
        >>> _ = add_synth_environments_parser(parser.add_subparsers(dest="command"))
        >>> args = parser.parse_args(["synth", "environments", "-n", "2", "--out", "envs"])
        >>> args.func is run_synth_environments  # what `kornia-ilum synth environments` calls
        True
    """
    # lazy: the statistics import the environments, a heavy import that only this sub-command needs
    from kornia_ilum_lab.synth.stats import (
        format_table,
        plot_histograms,
        source_group,
        stats_rows,
        summarize,
        write_csv,
    )

    # lazy: as above
    from kornia_ilum_lab.synth.environments import Augment, EnvironmentSampler, HDRFolderSource, default_sources

    require_matplotlib("synth environments")
    out = Path(args.out)
    sources = default_sources(args.folder, height=args.height)
    augment = None if getattr(args, "no_augment", False) else Augment()
    sampler = EnvironmentSampler(sources, augment=augment, seed=args.seed)
    t0 = time.perf_counter()
    envs = [sampler.sample(i) for i in progress(range(args.n), args.n, "sampling environments", "env")]
    seconds = time.perf_counter() - t0
    folders = [s for s in sources if isinstance(s, HDRFolderSource)]
    real = [s.environment(i) for s in folders for i in range(len(s))]
    rows = stats_rows(real + envs)
    table = format_table(summarize(rows))
    sampled = sorted(({**r, "group": source_group(e)} for r, e in zip(rows[len(real) :], envs, strict=True)),
                     key=lambda r: r["group"])  # fmt: skip
    per_source = format_table(summarize(sampled))
    note = (
        f"{args.n} environments (seed {args.seed}, height {args.height}, "
        f"{'no augmentation' if augment is None else 'augmented'}) sampled in {seconds:.2f} s "
        f"({args.n / seconds:.1f} environments/s)"
        + (f"; real maps as captured: {len(real)} from {args.folder}" if real else "")
        + ".\nStatistics of the 32 x 32 mirror balls (kornia_ilum_lab.synth.stats): "
        "median [10th, 90th percentile]."
    )
    out.mkdir(parents=True, exist_ok=True)
    written = [out / "stats.txt", out / "stats.csv", out / "stats.png"]
    written[0].write_text(f"{note}\n\n{table}\n\nPer source of the sampled environments:\n\n{per_source}\n")
    write_csv(rows, written[1])
    plot_histograms(rows, written[2])
    sheet = envs[: getattr(args, "sheet", 48)]
    if sheet:
        written.insert(0, out / "contact_sheet.png")
        write_contact_sheet(sheet, written[0])
    for figure in (p for p in written if p.suffix == ".png" and p.is_file()):  # figures record what made them
        stamp_figure(figure, command=_command_line(args), shows=ENVIRONMENT_FIGURES_SHOW)
    print(note)
    print(table)
    print("Per source of the sampled environments:")
    print(per_source)
    for path in written:
        print(f"wrote {path}")
    return 0


# ----------------------------------------------------------------------------------------------
# synth subjects

_SUBJECTS_HELP = """\
Render the OLAT reflectance fields of light-stage subjects (one render per light of the 32 x 32 mirror-ball
basis) into --out: --views random views per subject (yaw spread over +-35 degrees, pitch +-15, roll +-10,
lenses from a phone's 24 mm to an 85 mm portrait lens, the face framed at half the image height), each
subject built once, in --workers one-thread processes. Resumable: fields already on disk with the same
settings are skipped, so rerun the same command after an interruption. --worker I/N renders the subjects of
share I of N, so N machines can fill one cache. Then write --out/contact_sheet.png: --sheet training portraits
(relit, composited over their environment, exposed, cropped, 8-bit sRGB) with their ground-truth spheres.
Sources: makehuman (photoreal heads, needs the CC0 assets: --assets, $KORNIA_ILUM_MAKEHUMAN or
$KORNIA_ILUM_SHARED_DATA/makehuman) or mannequin (signed-distance heads, no assets); the default is makehuman
when its assets are found, else mannequin. Needs the lightstage extra (Mitsuba 3).

examples:
  kornia-ilum synth subjects --seeds 0-59 --views 4 --out lightstage/
  kornia-ilum synth subjects --source makehuman --assets ~/makehuman --seeds 0-99 --worker 3/8 --sheet 0 --out /shared/ls/
  kornia-ilum synth subjects --source mannequin --seeds 0-2 --size 64 --spp 4 --lighting-size 8 --out tiny/
  kornia-ilum synth subjects --split eval --seeds 200-399 --sheet 0 --out eval_subjects/   # eval seeds only
"""


def parse_seeds(text: str) -> list[int]:
    """Subject seeds from ``"0-9"``, ``"3,5,8"`` or a mix (``"0-4,10"``); ranges include both ends.

    Args:
        text: comma-separated seeds and inclusive ranges ``LO-HI``.

    Returns:
        the seeds in the order given, each once.

    Raises:
        argparse.ArgumentTypeError: ``text`` is not of that form, or names no seed.

    Examples:
        >>> parse_seeds("0-3,7")
        [0, 1, 2, 3, 7]
    """
    seeds: list[int] = []
    try:
        for part in text.split(","):
            lo, sep, hi = part.strip().partition("-")
            seeds.extend(range(int(lo), int(hi) + 1) if sep else [int(lo)])
    except ValueError:
        raise argparse.ArgumentTypeError(f"seeds must look like '0-9' or '1,4,7', got {text!r}") from None
    if not seeds:
        raise argparse.ArgumentTypeError(f"no seed in {text!r}")
    return list(dict.fromkeys(seeds))


def _worker(text: str) -> tuple[int, int]:
    index, sep, count = text.partition("/")
    try:
        i, n = int(index), int(count)
    except ValueError:
        i, n = -1, 0
    if not sep or n <= 0 or not 0 <= i < n:
        raise argparse.ArgumentTypeError(f"worker must be I/N with 0 <= I < N, got {text!r}")
    return i, n


class _SplitAction(argparse.Action):
    """``--split``: stores the choice and marks it as given (``split_given``), so that only an explicit
    ``--split`` filters the rendered seeds; the default (``"train"``) only picks the sheet's subjects."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        setattr(namespace, self.dest, values)
        namespace.split_given = True


def split_seeds(seeds: Sequence[int], split: str | None) -> list[int]:
    """The seeds whose :func:`~kornia_ilum_lab.synth.lightstage.subject_split` is ``split`` (all for ``None`` or
    ``"all"``), in order.

    Args:
        seeds: subject seeds.
        split: ``"train"``, ``"eval"``, ``"all"`` or ``None`` (all).

    Returns:
        the seeds of ``split``, in the order of ``seeds``.

    Examples:
        >>> split_seeds(range(6), "eval"), split_seeds([0, 1], "all")
        ([1, 3], [0, 1])
    """
    # lazy: importing a light-stage module loads the whole (heavy) light-stage package
    from kornia_ilum_lab.synth.lightstage.subjects.base import subject_split

    if split in (None, "all"):
        return list(seeds)
    return [s for s in seeds if subject_split(s) == split]


def add_synth_subjects_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add ``synth subjects`` to ``subparsers`` (reusing a ``synth`` command that is already there).

    The ``subjects`` parser's defaults hold ``func=run_synth_subjects``.

    Args:
        subparsers: the subparsers action of the top-level parser (``parser.add_subparsers(...)``).

    Returns:
        the ``subjects`` parser.

    Examples:
        >>> parser = argparse.ArgumentParser(prog="kornia-ilum")
        >>> subjects = add_synth_subjects_parser(parser.add_subparsers(dest="command"))
        >>> args = subjects.parse_args(["--seeds", "0-2"])
        >>> args.seeds, args.worker, args.size, args.views, args.workers, args.source, args.func.__name__
        ([0, 1, 2], (0, 1), 192, 4, 2, None, 'run_synth_subjects')
    """
    sub = _synth_subparsers(subparsers)
    cmd = sub.add_parser(
        "subjects",
        help="render light-stage reflectance fields; portrait contact sheet",
        description=_SUBJECTS_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    cmd.add_argument("--out", default="lightstage", metavar="DIR", help="the cache folder (lightstage)")
    cmd.add_argument("--seeds", type=parse_seeds, default=parse_seeds("0-9"), metavar="SEEDS",
                     help="subject seeds, e.g. 0-9 or 1,4,7 (0-9); about one in ten is an eval subject")
    cmd.add_argument("--source", choices=("makehuman", "mannequin"), default=None,
                     help="subject source (makehuman when its assets are found, else mannequin)")
    cmd.add_argument("--assets", metavar="DIR", default=None, help="the MakeHuman assets folder")
    cmd.add_argument("--clothes", action="store_true",
                     help="dress the MakeHuman subjects in the CC0 outfits, a measured fabric's albedo each")
    cmd.add_argument("--cut-below-chin", type=float, default=None, metavar="M",
                     help="the MakeHuman bust's cut, metres below the chin (0.21; up to 1.0 for wide views)")
    cmd.add_argument("--views", type=positive_int, default=4, metavar="N",
                     help="random views per subject (4)")
    cmd.add_argument("--face-fraction", type=float, default=None, metavar="F",
                     help="the face-landmark box's height over the image's in every view (0.5; smaller shows "
                          "more of the body and the surroundings)")
    cmd.add_argument("--size", type=positive_int, default=192, metavar="PX",
                     help="render side in pixels (192)")
    cmd.add_argument("--spp", type=positive_int, default=None, metavar="N",
                     help="camera samples per pixel (default: the renderer's, 32 with 4 tracing the lights)")
    cmd.add_argument("--lighting-size", type=positive_int, default=32, metavar="S",
                     help="side of the mirror-ball lighting basis (32: 812 lights)")
    cmd.add_argument("--workers", type=positive_int, default=2, metavar="N",
                     help="render processes, one thread each (2)")
    cmd.add_argument("--worker", type=_worker, default=(0, 1), metavar="I/N",
                     help="render share I of N (0/1)")
    cmd.add_argument("--threads", type=positive_int, default=None, metavar="N",
                     help="render threads with --workers 1 (default: Dr.Jit's, all cores)")
    cmd.add_argument("--variant", default=None,
                     help="Mitsuba variant (default: llvm_ad_rgb, else scalar_rgb)")
    cmd.add_argument("--device", choices=("cpu", "cuda"), default=None,
                     help="cuda: render with Mitsuba's cuda_ad_rgb variant on an NVIDIA GPU "
                          "(same as --variant cuda_ad_rgb); cpu: the default variants")
    cmd.add_argument("--sheet", type=nonnegative_int, default=64, metavar="N",
                     help="portraits in contact_sheet.png (64; 0: none)")
    cmd.add_argument("--split", choices=("train", "eval", "all"), default="train", action=_SplitAction,
                     help="render only the seeds of this split (subject_split) and show them in the sheet; "
                          "without it every seed is rendered and the sheet shows the train subjects. "
                          "--split eval --seeds 200-999 renders an eval-only cache of extra subjects")
    cmd.add_argument("--folder", metavar="DIR",
                     help="also light the sheet's portraits with these real HDR maps")
    cmd.add_argument("--seed", type=int, default=0, metavar="S", help="seed of the sheet's portraits (0)")
    cmd.add_argument("--sparse", action="store_true",
                     help="also write each field's sparse-relighting sidecar (light-major rows, the field at rank "
                     "48), for training with --data relight_eps=0.01: faster data, within about 1 %% of the "
                     "exact images (docs/skipping.rst)")
    cmd.set_defaults(func=run_synth_subjects)
    return cmd


def _subject_source(name: str | None, assets: str | None, **options):
    """The source of ``--source`` / ``--assets`` with the MakeHuman ``options`` given (``clothes``,
    ``cut_below_chin``); without ``--source``, makehuman when its assets are found."""
    # lazy: importing a light-stage module loads the whole (heavy) light-stage package
    from kornia_ilum_lab.synth.lightstage.subjects import MannequinSource, subject_source

    if name == "mannequin" and options:
        raise ValueCheckError(f"--source mannequin takes no {', '.join(sorted(options))}")
    if name == "mannequin":
        return MannequinSource()
    try:
        return subject_source("makehuman", assets=assets, **options)
    except ValueCheckError:
        raise
    except Exception as exc:  # noqa: BLE001 - missing or broken assets, whichever error the source raises
        if name == "makehuman" or options:  # MakeHuman's options asked for: no silent mannequins
            raise IlumError(f"cannot load the MakeHuman assets: {exc}") from exc
        print(f"kornia-ilum: notice: MakeHuman assets not found ({' '.join(str(exc).split())}); "
              "using the mannequins (--source mannequin)", file=sys.stderr)
        return MannequinSource()


def run_synth_subjects(args: argparse.Namespace) -> int:
    """Run ``synth subjects`` from parsed arguments (module docstring); returns 0.

    Args:
        args: the arguments parsed by the parser of :func:`add_synth_subjects_parser`.

    Returns:
        the exit status, 0.

    Raises:
        ImportError: Mitsuba (the ``lightstage`` extra) is not installed.
        IlumError: matplotlib is not installed and a sheet is asked for; ``--source makehuman`` without its
            assets (exit status 1).
        ValueCheckError: an explicit ``--split`` leaves no seed of ``--seeds``.

    Examples:
        >>> parser = argparse.ArgumentParser(prog="kornia-ilum")
        >>> _ = add_synth_subjects_parser(parser.add_subparsers(dest="command"))
        >>> args = parser.parse_args(["synth", "subjects", "--seeds", "0-3", "--split", "eval"])
        >>> args.func is run_synth_subjects, args.split_given, split_seeds(args.seeds, args.split)
        (True, True, [1, 3])
    """
    # lazy: the light-stage package is a heavy import that only this sub-command needs
    from kornia_ilum_lab.synth.lightstage.cache import SampledViews, Workers, build_cache, cache_summary
    from kornia_ilum_lab.synth.lightstage.scene import FACE_FRACTION  # lazy: as above
    from kornia_ilum_lab.synth.lightstage.preview import training_sheet  # lazy: as above
    from kornia_ilum_lab.synth.lightstage.settings import Auto  # lazy: as above
    from kornia_ilum_lab.synth.lightstage.sparse import write_sparse_cache  # lazy: as above

    if args.sheet:
        require_matplotlib("synth subjects")
    seeds = list(args.seeds)
    if getattr(args, "split_given", False) and args.split != "all":
        seeds = split_seeds(seeds, args.split)
        print(f"--split {args.split}: {len(seeds)} of {len(args.seeds)} seeds, "
              f"{len(args.seeds) - len(seeds)} of the other split skipped")
        if not seeds:
            raise ValueCheckError(f"no seed of split {args.split!r} in --seeds")
    options = {"clothes": True} if getattr(args, "clothes", False) else {}
    if getattr(args, "cut_below_chin", None) is not None:
        options["cut_below_chin"] = args.cut_below_chin
    source = _subject_source(getattr(args, "source", None), getattr(args, "assets", None), **options)
    out = Path(args.out)
    variant = "cuda_ad_rgb" if args.device == "cuda" else args.variant
    manifest = build_cache(source, seeds, out_dir=out, renderer=Auto(spp=args.spp,
                                                                     lighting_size=args.lighting_size),
                           views=SampledViews(args.views, size=args.size,
                                              fraction=getattr(args, "face_fraction", None) or FACE_FRACTION),
                           workers=Workers(processes=getattr(args, "workers", 2), index=args.worker[0],
                                           count=args.worker[1], threads=args.threads),
                           variant=variant, progress=True)
    print(f"cache {out} (source {source.name}):")
    print(cache_summary(manifest))
    if getattr(args, "sparse", False):
        written = write_sparse_cache(out)
        print(f"wrote {written} sparse-relighting sidecar(s) (*.sparse.safetensors)")
    if not args.sheet:
        return 0
    split = None if args.split == "all" else args.split
    t1 = time.perf_counter()
    count = training_sheet(out, out / "contact_sheet.png", count=args.sheet, split=split, folder=args.folder,
                           seed=args.seed)
    stamp_figure(out / "contact_sheet.png", command=_command_line(args), shows=LIGHTSTAGE_FIGURES_SHOW)
    print(f"{count} portraits in {time.perf_counter() - t1:.1f} s")
    print(f"wrote {out / 'contact_sheet.png'}")
    return 0


# ----------------------------------------------------------------------------------------------
# synth check-skin

_CHECK_SKIN_HELP = """\
The uniform-white check of a light-stage cache: relight each subject-view by a uniform white environment of
radiance 1 and compare, over the face's skin (lips included), the reading with the skin's documented albedo
(its subsurface, relighting and denoising must neither create nor lose energy: 1 - OCCLUSION <= reading /
(albedo + specular) <= 1 + RTOL) and that albedo with the measured range of facial skin of the subject's Monk
tone (docs/lightstage.rst, "Skin"). Prints one row per subject-view; exits with 1 when any fails.

examples:
  kornia-ilum synth check-skin --cache lightstage/                 # its eval subjects
  kornia-ilum synth check-skin --cache lightstage/ --split all --json skin.json
"""


def add_synth_check_skin_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add ``synth check-skin`` to ``subparsers`` (reusing a ``synth`` command that is already there).

    The ``check-skin`` parser's defaults hold ``func=run_synth_check_skin``.

    Args:
        subparsers: the subparsers action of the top-level parser (``parser.add_subparsers(...)``).

    Returns:
        the ``check-skin`` parser.

    Examples:
        >>> parser = argparse.ArgumentParser(prog="kornia-ilum")
        >>> cmd = add_synth_check_skin_parser(parser.add_subparsers(dest="command"))
        >>> args = cmd.parse_args(["--cache", "ls"])
        >>> args.cache, args.split, args.rtol, args.occlusion, args.func.__name__
        (['ls'], 'eval', 0.1, 0.15, 'run_synth_check_skin')
    """
    sub = _synth_subparsers(subparsers)
    cmd = sub.add_parser(
        "check-skin",
        help="the uniform-white check: do the cached faces reflect what measured skin does?",
        description=_CHECK_SKIN_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    cmd.add_argument("--cache", action="append", required=True, metavar="DIR",
                     help="a light-stage cache (repeatable)")
    cmd.add_argument("--split", choices=("train", "eval", "all"), default="eval",
                     help="the subjects to check (eval)")
    cmd.add_argument("--rtol", type=fraction, default=0.1, metavar="F",
                     help="how much more light than its albedo the skin may reflect (0.1)")
    cmd.add_argument("--occlusion", type=fraction, default=0.15, metavar="F",
                     help="how much less (the face's occlusion of its own environment; 0.15)")
    cmd.add_argument("--json", metavar="FILE", help="also write the rows as JSON")
    cmd.set_defaults(func=run_synth_check_skin)
    return cmd


def run_synth_check_skin(args: argparse.Namespace) -> int:
    """Run ``synth check-skin`` from parsed arguments; returns 0 when every subject-view passes, else 1.

    Args:
        args: the arguments parsed by the parser of :func:`add_synth_check_skin_parser`.

    Returns:
        the exit status: 0 when every subject-view passes, else 1.

    Raises:
        ValueCheckError: a cache of an older light stage (no albedo and skin buffers), or one without a subject
            of the split.

    Examples:
        >>> parser = argparse.ArgumentParser(prog="kornia-ilum")
        >>> _ = add_synth_check_skin_parser(parser.add_subparsers(dest="command"))
        >>> args = parser.parse_args(["synth", "check-skin", "--cache", "a", "--cache", "b", "--split", "all"])
        >>> args.func is run_synth_check_skin, args.cache, args.split
        (True, ['a', 'b'], 'all')
    """
    import dataclasses  # lazy: only this sub-command writes JSON rows
    import json  # lazy: as above

    # lazy: the light-stage package is a heavy import that only this sub-command needs
    from kornia_ilum_lab.synth.lightstage.calibration import check_cache

    split = None if args.split == "all" else args.split
    results = [r for cache in args.cache for r in check_cache(cache, split, args.rtol, args.occlusion)]
    if not results:
        raise ValueCheckError(f"no MakeHuman subject of split {args.split!r} in {', '.join(args.cache)}")

    def rgb(v: Sequence[float]) -> str:
        return " ".join(f"{x:.3f}" for x in v)

    print(f"{'subject':>7} {'view':>4} {'tone':>4} {'pixels':>6}  {'albedo + specular':<17}  {'reading':<17}  "
          f"{'energy':<17}  {'measured range':<37}  result")
    for r in results:
        verdict = " ".join(name for name, ok in (("energy", r.energy_ok), ("skin", r.skin_ok)) if not ok) or "ok"
        print(f"{r.subject_seed:>7} {r.view_index:>4} {r.skin_tone:>4} {r.pixels:>6}  {rgb(r.total):<17}  "
              f"{rgb(r.measured):<17}  {rgb(r.energy):<17}  {rgb(r.low)} .. {rgb(r.high)}  {verdict}")
    passed = sum(r.ok for r in results)
    print(f"{passed} of {len(results)} subject-views passed (energy within [{1 - args.occlusion:.2f}, "
          f"{1 + args.rtol:.2f}], skin inside its tone's measured range)")
    if args.json:
        text = json.dumps([dataclasses.asdict(r) for r in results], indent=1) + "\n"
        atomic_write(args.json, lambda tmp: tmp.write_text(text))
        print(f"wrote {args.json}")
    return 0 if passed == len(results) else 1
