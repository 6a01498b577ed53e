r"""``kornia-ilum synth environments``: sample lighting environments, draw a contact sheet, print statistics.

The command samples ``N`` environments with :class:`~kornia_ilum.synth.environments.EnvironmentSampler`
(procedural skies and rooms, plus the real maps of ``--folder``), with a progress bar (tqdm when it is
installed, else a counter on stderr), and writes into ``--out``:

- ``contact_sheet.png``: for each environment its 32 x 32 mirror ball and the three reference spheres
  rendered from it (diffuse, matte silver, mirror; :func:`kornia_ilum.render.render_spheres`), tone-mapped;
- ``stats.txt`` and ``stats.csv``: the statistics of :mod:`kornia_ilum.synth.stats`, per group (median and
  10th / 90th percentiles) and per environment; with ``--folder`` the real maps, as captured, are a group;
- ``stats.png``: the four histograms.

:func:`add_synth_environments_parser` adds the subcommand to an ``argparse`` subparsers action;
:func:`run_synth_environments` runs it from the parsed arguments.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import TypeVar

import torch

from kornia_ilum.cli import _positive_int  # one parser of positive ints for the whole CLI

__all__ = ["add_synth_environments_parser", "run_synth_environments", "tone_map_tile", "write_contact_sheet"]

T = TypeVar("T")

_HELP = """\
Sample N lighting environments (procedural skies and rooms, plus the real maps of --folder, augmented by
rotation, flip, exposure and white balance), and write into --out: contact_sheet.png (mirror balls with
their diffuse, matte-silver and mirror reference spheres), stats.txt / stats.csv (dynamic range,
peak-to-mean ratio, colour temperature, energy in the top 1 % of pixels, per group), and stats.png (their
histograms). Environment i of seed S is always the same.

examples:
  kornia-ilum synth environments -n 48 --out envs/
  kornia-ilum synth environments --folder ../shared/data/hdri -n 200 --sheet 48 --out envs/
"""



def _nonnegative_int(text: str) -> int:
    return 0 if text.strip() == "0" else _positive_int(text)


def add_synth_environments_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add ``synth environments`` to ``subparsers`` (reusing a ``synth`` command that is already there).

    The ``environments`` parser's defaults hold ``func=run_synth_environments``.

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
    synth = subparsers.choices.get("synth")
    if synth is None:
        synth = subparsers.add_parser(
            "synth", help="synthesis: lighting environments", description="Synthesis tools of kornia_ilum."
        )
    nested = [a for a in synth._actions if isinstance(a, argparse._SubParsersAction)]
    if nested:
        sub = nested[0]
    else:
        sub = synth.add_subparsers(dest="synth_command", metavar="COMMAND", required=True)
    env = sub.add_parser(
        "environments",
        help="sample lighting environments: contact sheet and statistics",
        description=_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    env.add_argument("--folder", metavar="DIR", help="folder of lat-long .hdr/.exr maps to add")
    env.add_argument("-n", type=_positive_int, default=48, metavar="N", help="environments to sample (48)")
    env.add_argument("--seed", type=int, default=0, metavar="S", help="seed (0)")
    env.add_argument(
        "--out", default="synth_environments", metavar="DIR", help="output folder (./synth_environments)"
    )
    env.add_argument(
        "--height", type=_positive_int, default=128, metavar="H", help="lat-long height H x 2H (128)"
    )
    env.add_argument(
        "--sheet", type=_nonnegative_int, default=48, metavar="K", help="environments on the sheet (48)"
    )
    env.add_argument("--no-augment", action="store_true", help="no rotation, flip, exposure or white balance")
    env.set_defaults(func=run_synth_environments)
    return env


def _progress(items: Iterable[T], total: int, desc: str) -> Iterator[T]:
    """tqdm on stderr when installed, else a ``desc: i/total`` counter on stderr."""
    try:
        from tqdm import tqdm
    except ImportError:
        for i, item in enumerate(items, 1):
            yield item
            print(f"\r{desc}: {i}/{total}", end="\n" if i == total else "", file=sys.stderr, flush=True)
    else:
        yield from tqdm(items, total=total, desc=desc, file=sys.stderr, unit="env")


def tone_map_tile(mirror_ball: torch.Tensor) -> torch.Tensor:
    r"""One contact-sheet tile: the mirror ball and its three reference spheres, side by side, sRGB in [0, 1].

    The exposure makes the brightest pixel of the diffuse sphere 0.8 (as one would expose a face); the
    four images share it, so suns clip in the ball and the mirror. Then clip and the sRGB curve.

    Args:
        mirror_ball: linear lighting ``(3, 32, 32)``.

    Returns:
        ``(3, 32, 4 x 32 + 3 x 2)`` sRGB image (2-pixel white gaps), float in ``[0, 1]``.

    Examples:
        >>> tone_map_tile(torch.ones(3, 32, 32)).shape
        torch.Size([3, 32, 134])
    """
    from kornia_ilum.color import linear_to_srgb
    from kornia_ilum.render import BRDFS, render_spheres
    from kornia_ilum.synth.background import LUMINANCE

    ball = mirror_ball[None].float()
    spheres = render_spheres(ball, size=32)
    lum = (spheres["diffuse"][0] * torch.tensor(LUMINANCE)[:, None, None]).sum(0)
    peak = float(lum.max())
    gain = 0.8 / peak if peak > 0 else 1.0
    gap = torch.ones(3, 32, 2)
    parts = [ball[0]] + [spheres[b][0] for b in BRDFS]
    images = [linear_to_srgb((p * gain).clamp(0.0, 1.0)) for p in parts]
    return torch.cat([x for img in images for x in (img, gap)][:-1], dim=-1)


def _caption(env) -> str:
    aug = env.params.get("augment")
    text = f"{env.source} ({env.label})"
    if aug:
        text += (
            f"\nyaw {aug['yaw_deg']:.0f}, pitch {aug['pitch_deg']:+.0f}{', flip' if aug['flip'] else ''}, "
            f"{aug['exposure_stops']:+.1f} EV, WB {aug['kelvin']:.0f} K"
        )
    return text


def write_contact_sheet(
    envs: Sequence, path: str | Path, columns: int = 4, dpi: int = 100, palette: bool = True
) -> None:
    """A PNG grid of :func:`tone_map_tile` tiles with captions (source, label, augmentation).

    With ``palette`` the PNG is stored with a 256-colour adaptive palette (Pillow, which matplotlib
    requires): a third of the size of true colour (about 160 KB instead of 550 KB for 48 tiles).
    """
    import io

    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    rows = max(1, -(-len(envs) // columns))
    fig, axes = plt.subplots(rows, columns, figsize=(2.9 * columns, 1.15 * rows + 0.4), squeeze=False)
    for ax in axes.flat:
        ax.axis("off")
    for ax, env in zip(axes.flat, envs, strict=False):
        ax.imshow(tone_map_tile(env.mirror_ball).permute(1, 2, 0).numpy(), interpolation="nearest")
        ax.set_title(_caption(env), fontsize=6, pad=2)
    fig.suptitle("mirror ball | diffuse | matte silver | mirror (one exposure per environment)", fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.3 / (1.15 * rows + 0.4)), h_pad=0.4, w_pad=0.3)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if palette:
        from PIL import Image

        buffer = io.BytesIO()
        fig.savefig(buffer, dpi=dpi, format="png")
        image = Image.open(buffer).convert("RGB")
        image.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)
    else:
        fig.savefig(path, dpi=dpi)
    plt.close(fig)


def run_synth_environments(args: argparse.Namespace) -> int:
    """Run ``synth environments`` from parsed arguments (module docstring); prints the table, returns 0.

    ``args`` needs ``folder``, ``n``, ``seed``, ``out``, ``height``; ``sheet`` (default 48) and
    ``no_augment`` (default False) are optional.

    Raises:
        HDRIOError: ``folder`` does not exist or holds no map.
        IlumError: matplotlib (needed for the figures; in the ``docs`` extra) is not installed.
    """
    from kornia_ilum.synth.environments import Augment, EnvironmentSampler, HDRFolderSource, default_sources
    from kornia_ilum.synth.stats import format_table, plot_histograms, stats_rows, summarize, write_csv

    try:
        import matplotlib  # noqa: F401
    except ImportError:
        from kornia_ilum.core.errors import IlumError

        raise IlumError(
            "synth environments draws its figures with matplotlib, which is not installed: "
            "pip install matplotlib (or kornia_ilum[docs])"
        ) from None
    out = Path(args.out)
    sources = default_sources(args.folder, height=args.height)
    augment = None if getattr(args, "no_augment", False) else Augment()
    sampler = EnvironmentSampler(sources, augment=augment, seed=args.seed)
    t0 = time.perf_counter()
    envs = [sampler.sample(i) for i in _progress(range(args.n), args.n, "sampling environments")]
    seconds = time.perf_counter() - t0
    folders = [s for s in sources if isinstance(s, HDRFolderSource)]
    real = [s.environment(i) for s in folders for i in range(len(s))]
    rows = stats_rows(real + envs)
    table = format_table(summarize(rows))
    note = (
        f"{args.n} environments (seed {args.seed}, height {args.height}, "
        f"{'no augmentation' if augment is None else 'augmented'}) sampled in {seconds:.2f} s "
        f"({args.n / seconds:.1f} environments/s)"
        + (f"; real maps as captured: {len(real)} from {args.folder}" if real else "")
        + ".\nStatistics of the 32 x 32 mirror balls (kornia_ilum.synth.stats): "
        "median [10th, 90th percentile]."
    )
    out.mkdir(parents=True, exist_ok=True)
    written = [out / "stats.txt", out / "stats.csv", out / "stats.png"]
    written[0].write_text(f"{note}\n\n{table}\n")
    write_csv(rows, written[1])
    plot_histograms(rows, written[2])
    sheet = envs[: getattr(args, "sheet", 48)]
    if sheet:
        written.insert(0, out / "contact_sheet.png")
        write_contact_sheet(sheet, written[0])
    print(note)
    print(table)
    for path in written:
        print(f"wrote {path}")
    return 0
