r"""Contact sheets and grids: captioned PNG grids of image tiles, drawn with matplotlib.

:func:`write_grid` lays out ``(3, H, W)`` tiles with a caption each and a title, and saves the figure with
:func:`save_figure` (optionally as a dithered 256-colour palette PNG, which keeps the sheets small). The
contact sheet of lighting environments (:func:`write_contact_sheet`, tiles of :func:`tone_map_tile`) is
written by ``kornia-ilum synth environments`` (:mod:`kornia_ilum_lab.synth.cli`); the sheet of training
portraits (:func:`~kornia_ilum_lab.synth.lightstage.preview.training_sheet`) by ``kornia-ilum synth subjects``.
Both draw their grid here.

matplotlib is imported only when a figure is drawn (it is an optional dependency, in the ``docs`` extra):
:func:`require_matplotlib` turns its absence into one clear error before any work starts.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path

import torch

from kornia_ilum.color import linear_to_srgb
from kornia_ilum.core.errors import IlumError
from kornia_ilum.render import BRDFS, render_spheres
from kornia_ilum_lab.synth.background import LUMINANCE

__all__ = ["require_matplotlib", "save_figure", "tone_map_tile", "write_contact_sheet", "write_grid"]


def require_matplotlib(command: str) -> None:
    """Raise :class:`~kornia_ilum.core.errors.IlumError` naming ``command`` when matplotlib is not installed.

    Args:
        command: the command that needs matplotlib, named in the error (``"synth environments"``).

    Returns:
        ``None``; it raises when matplotlib is missing.

    Raises:
        IlumError: matplotlib cannot be imported.

    Examples:
        >>> require_matplotlib("synth environments")  # matplotlib is installed: nothing happens
    """
    try:
        import matplotlib  # noqa: F401  # lazy: an optional dependency, only probed here
    except ImportError:
        raise IlumError(
            f"{command} draws its figures with matplotlib, which is not installed: "
            "pip install matplotlib (or kornia_ilum[docs])"
        ) from None


def tone_map_tile(mirror_ball: torch.Tensor) -> torch.Tensor:
    r"""One contact-sheet tile: the mirror ball and its three reference spheres, side by side, sRGB in [0, 1].

    The exposure makes the brightest pixel of the diffuse sphere 0.8 (as one would expose a face); the
    four images share it, so suns clip in the ball and the mirror. Then clip and the sRGB curve.

    Args:
        mirror_ball: linear lighting ``(3, 32, 32)``.

    Returns:
        ``(3, 32, 4 x 32 + 3 x 2)`` sRGB image (2-pixel white gaps), float in ``[0, 1]``.

    Shape:
        - mirror_ball: :math:`(3, 32, 32)`
        - Output: :math:`(3, 32, 134)`

    Convention:
        Mirror-ball lighting and reference spheres of docs/conventions.rst, linear in; sRGB-encoded out.

    Examples:
        >>> tone_map_tile(torch.ones(3, 32, 32)).shape
        torch.Size([3, 32, 134])
    """
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
    envs: Sequence, path: str | Path, *, columns: int = 4, dpi: int = 100, palette: bool = True
) -> None:
    """A PNG grid of :func:`tone_map_tile` tiles with captions (source, label, augmentation).

    With ``palette`` the PNG is stored with a 256-colour adaptive palette (Pillow, which matplotlib
    requires), dithered: about 410 KB for 48 tiles instead of 550 KB in true colour.

    Args:
        envs: the environments (:class:`~kornia_ilum_lab.synth.environments.Environment`), one tile each.
        path: the PNG to write (missing parent folders are created).
        columns: tiles per row.
        dpi: the PNG's dots per inch.
        palette: store a 256-colour palette PNG (:func:`save_figure`).

    Returns:
        ``None``; the sheet is written to ``path``.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as d:
        ...     write_contact_sheet([], Path(d) / "empty.png", dpi=20)  # no environment: only the title
        ...     (Path(d) / "empty.png").read_bytes()[1:4]
        b'PNG'
        >>> write_contact_sheet(envs, "envs/contact_sheet.png")  # one tile per environment  # doctest: +SKIP
    """
    tiles = [tone_map_tile(env.mirror_ball) for env in envs]
    title = "mirror ball | diffuse | matte silver | mirror (one exposure per environment)"
    write_grid(tiles, [_caption(env) for env in envs], title=title, path=path, columns=columns,
               cell=(2.9, 1.15), fontsize=6, dpi=dpi, palette=palette)


def write_grid(
    tiles: Sequence[torch.Tensor],
    captions: Sequence[str],
    *,
    title: str,
    path: str | Path,
    columns: int,
    cell: tuple[float, float],
    fontsize: float,
    dpi: int,
    palette: bool,
) -> None:
    """A captioned grid of ``(3, H, W)`` images in ``[0, 1]``, ``cell`` inches per tile, saved as a PNG.

    Args:
        tiles: the images, row by row.
        captions: one caption per tile (may hold a line break).
        title: the figure's title.
        path: the PNG to write (missing parent folders are created).
        columns: tiles per row.
        cell: ``(width, height)`` of one tile's cell, in inches.
        fontsize: the captions' font size, in points.
        dpi: the PNG's dots per inch.
        palette: store a 256-colour palette PNG (:func:`save_figure`).

    Returns:
        ``None``; the grid is written to ``path``.

    Examples:
        >>> import tempfile
        >>> tiles = [torch.zeros(3, 4, 4), torch.ones(3, 4, 4)]
        >>> with tempfile.TemporaryDirectory() as d:
        ...     write_grid(tiles, ["black", "white"], title="two tiles", path=Path(d) / "sub" / "grid.png",
        ...                columns=2, cell=(1.0, 1.0), fontsize=6, dpi=20, palette=False)
        ...     (Path(d) / "sub" / "grid.png").is_file()
        True
    """
    import matplotlib  # lazy: an optional dependency, loaded only to draw

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt  # lazy: as above

    rows = max(1, -(-len(tiles) // columns))
    height = cell[1] * rows + 0.35
    fig, axes = plt.subplots(rows, columns, figsize=(cell[0] * columns, height), squeeze=False)
    for ax in axes.flat:
        ax.axis("off")
    for ax, tile, caption in zip(axes.flat, tiles, captions, strict=False):
        ax.imshow(tile.clamp(0, 1).permute(1, 2, 0).numpy(), interpolation="nearest")
        ax.set_title(caption, fontsize=fontsize, pad=1.5)
    fig.suptitle(title, fontsize=8.5)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.3 / height), h_pad=0.3, w_pad=0.2)
    save_figure(fig, path, dpi, palette)


def save_figure(fig, path: str | Path, dpi: int, palette: bool) -> None:
    """Save and close a matplotlib figure; with ``palette`` as a 256-colour adaptive-palette PNG (Pillow's
    median cut, with Floyd-Steinberg dithering so that smooth shading does not band).

    Args:
        fig: the matplotlib figure; it is closed.
        path: the PNG to write (missing parent folders are created).
        dpi: the PNG's dots per inch.
        palette: store a 256-colour palette PNG instead of true colour.

    Returns:
        ``None``; the figure is written to ``path``.

    Examples:
        >>> import tempfile
        >>> import matplotlib.pyplot as plt
        >>> from PIL import Image
        >>> fig = plt.figure(figsize=(1, 1))
        >>> with tempfile.TemporaryDirectory() as d:
        ...     save_figure(fig, Path(d) / "fig.png", dpi=20, palette=True)
        ...     with Image.open(Path(d) / "fig.png") as png:
        ...         png.mode, png.size
        ('P', (20, 20))
    """
    import matplotlib.pyplot as plt  # lazy: an optional dependency, loaded only to draw

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if palette:
        from PIL import Image  # lazy: Pillow comes with matplotlib, needed only for the palette

        buffer = io.BytesIO()
        fig.savefig(buffer, dpi=dpi, format="png")
        image = Image.open(buffer).convert("RGB")
        palette_image = image.quantize(colors=256, method=Image.Quantize.MEDIANCUT)
        image.quantize(palette=palette_image, dither=Image.Dither.FLOYDSTEINBERG).save(path, optimize=True)
    else:
        fig.savefig(path, dpi=dpi)
    plt.close(fig)
