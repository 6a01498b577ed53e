r"""Statistics of lighting environments, to compare generated sets with real HDR maps.

Per environment (:func:`lighting_stats`), from the luminance ``Y`` (Rec. 709 / sRGB primaries, the ``Y`` row
of :func:`kornia.color.rgb_to_xyz`) of every pixel and the pixel's exact solid angle ``Omega``:

``dynamic_range_stops``
    ``log2(P_99.99 / P_0.01)``: the 99.99th over the 0.01th percentile of ``Y``, percentiles weighted by
    solid angle, over the pixels above a floor of ``1e-6`` times the mean luminance (black pixels, such as
    an unlit floor, are left out instead of making the range infinite). On a 32 x 32 mirror ball, whose
    pixels are 1/64 sr (0.12 % of the sphere), this is the ratio of the brightest to the darkest pixel.
``peak_to_mean``
    ``max(Y) / mean(Y)``, the mean weighted by solid angle (``sum(Y Omega) / 4 pi``).
``cct_kelvin``
    The correlated colour temperature of the mean colour: ``sum(RGB Omega)`` -> CIE XYZ
    (:func:`kornia.color.rgb_to_xyz`, linear sRGB, D65) -> chromaticity ``(x, y)`` -> McCamy's cubic
    (C. S. McCamy, "Correlated color temperature as an explicit function of chromaticity coordinates",
    Color Res. Appl. 17, 1992): ``n = (x - 0.3320) / (0.1858 - y)``,
    ``CCT = 449 n^3 + 3525 n^2 + 6823.3 n + 5520.33``. Accurate to a few K near the Planckian locus from
    2856 to 6504 K, usable from about 2000 to 12500 K; strongly hued light far from the locus gets a
    nominal value. Equal-energy white (``X = Y = Z``) gives 5459 K, linear sRGB white (D65) 6503 K.
``top1_energy``
    The fraction of the luminous energy ``sum(Y Omega)`` in the brightest 1 % of the sphere's solid angle
    (pixels sorted by ``Y``, the last one counted in part), in ``[0.01, 1]``: 0.01 for a uniform map,
    close to 1 when a sun dominates.

:func:`summarize` gives the median and the 10th / 90th percentiles per group (real maps, procedural
outdoor, procedural indoor, portrait lights, ...; or any other grouping, such as :func:`source_group`, one
group per procedural kind), :func:`format_table` prints them (as a reStructuredText table), and
:func:`plot_histograms` draws the four distributions (matplotlib).

Convention:
    Lighting in the layouts of docs/conventions.rst (``"mirror_ball"``: invalid pixels are ignored;
    ``"latlong"``), linear RGB, non-negative. The statistics are scale-invariant (exposure does not change
    them).
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from kornia_ilum.core.check import check_tensor
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.geometry import latlong_solid_angles, mirror_ball_solid_angles
from kornia_ilum_lab.synth.background import LUMINANCE
from kornia_ilum_lab.synth.environments.augment import weighted_quantile
from kornia_ilum_lab.synth.environments.base import Environment
from kornia_ilum_lab.synth.sheets import save_figure

__all__ = [
    "GROUP_ORDER",
    "RGB_TO_XYZ",
    "STATS",
    "cct_mccamy",
    "environment_group",
    "format_table",
    "lighting_stats",
    "plot_histograms",
    "source_group",
    "stats_rows",
    "summarize",
    "weighted_quantile",
    "write_csv",
]

#: The statistics, in table order, with their column titles.
STATS: Mapping[str, str] = {
    "dynamic_range_stops": "dynamic range (stops)",
    "peak_to_mean": "peak / mean",
    "cct_kelvin": "CCT (K)",
    "top1_energy": "energy in top 1 %",
}

#: The order of the groups of :func:`environment_group` in tables and figures.
GROUP_ORDER: tuple[str, ...] = (
    "real",
    "real, augmented",
    "procedural outdoor",
    "procedural indoor",
    "portrait lights",
)

#: Linear sRGB -> CIE XYZ (D65), the matrix of :func:`kornia.color.rgb_to_xyz`; its middle row is luminance.
RGB_TO_XYZ: tuple[tuple[float, float, float], ...] = (
    (0.412453, 0.357580, 0.180423),
    LUMINANCE,
    (0.019334, 0.119193, 0.950227),
)


def cct_mccamy(rgb: torch.Tensor) -> float:
    r"""Correlated colour temperature (K) of a linear sRGB colour ``(3,)`` by McCamy's formula.

    See the module docstring.

    Returns ``nan`` for black.

    Args:
        rgb: a linear sRGB colour ``(3,)``, non-negative (any device and float dtype).

    Returns:
        the correlated colour temperature in kelvin, or ``nan`` for black.

    Shape:
        - rgb: :math:`(3,)`

    Convention:
        Linear sRGB (Rec. 709 primaries, D65), the colours of docs/conventions.rst ("Images").

    Examples:
        >>> round(cct_mccamy(torch.tensor([1.0, 1.0, 1.0])))  # sRGB white, D65 (6504 K)
        6503
    """
    xyz = torch.tensor(RGB_TO_XYZ, dtype=torch.float64) @ rgb.detach().to(device="cpu", dtype=torch.float64)
    total = float(xyz.sum())
    if not total > 0.0:
        return math.nan
    x, y = float(xyz[0]) / total, float(xyz[1]) / total
    if y == 0.1858:
        return math.nan
    n = (x - 0.3320) / (0.1858 - y)
    return 449.0 * n**3 + 3525.0 * n**2 + 6823.3 * n + 5520.33


def lighting_stats(lighting: torch.Tensor, layout: str = "mirror_ball") -> dict[str, float]:
    r"""The four statistics of one lighting (module docstring).

    Args:
        lighting: linear RGB lighting, non-negative.
        layout: ``"mirror_ball"`` or ``"latlong"``.

    Returns:
        ``{"dynamic_range_stops", "peak_to_mean", "cct_kelvin", "top1_energy"}`` as floats (``nan`` for a
        black map).

    Raises:
        ShapeError: wrong shape for ``layout``.
        ValueCheckError: negative lighting or an unknown layout.
        NonFiniteError: NaN or Inf.

    Shape:
        - lighting: :math:`(3, S, S)` or :math:`(3, H, 2H)`

    Convention:
        Layouts of docs/conventions.rst and exact solid angles; luminance and colour in linear sRGB (Rec. 709,
        D65).

    Examples:
        >>> s = lighting_stats(torch.ones(3, 32, 32))
        >>> round(s["dynamic_range_stops"], 6), round(s["peak_to_mean"], 6), round(s["top1_energy"], 6)
        (0.0, 1.0, 0.01)
    """
    if layout not in ("mirror_ball", "latlong"):
        raise ValueCheckError(f"layout must be 'mirror_ball' or 'latlong', got {layout!r}")
    check_tensor(lighting, "lighting", ["3", "H", "W"], nonnegative=True)
    h, w = lighting.shape[-2:]
    if (layout == "mirror_ball" and h != w) or (layout == "latlong" and w != 2 * h):
        want = "(3, S, S)" if layout == "mirror_ball" else "(3, H, 2H)"
        raise ShapeError(
            f"lighting must have shape {want} for layout {layout!r}, got {tuple(lighting.shape)}"
        )
    rgb = lighting.detach().to(device="cpu", dtype=torch.float64).flatten(1)
    omega = (mirror_ball_solid_angles(h, dtype=torch.float64) if layout == "mirror_ball"
             else latlong_solid_angles(h, dtype=torch.float64)).flatten()  # fmt: skip
    keep = omega > 0
    rgb, omega = rgb[:, keep], omega[keep]
    lum = torch.tensor(RGB_TO_XYZ[1], dtype=torch.float64) @ rgb
    total = float((lum * omega).sum())
    if not total > 0.0:
        return dict.fromkeys(STATS, math.nan)
    mean = total / float(omega.sum())
    lit = lum > 1e-6 * mean
    lo, hi = weighted_quantile(lum[lit], omega[lit], [0.0001, 0.9999]).tolist()
    order = torch.argsort(lum, descending=True)
    cum = torch.cumsum(omega[order], 0)
    budget = 0.01 * float(omega.sum())
    # the solid angle of each pixel that counts towards the top 1 %
    part = (budget - (cum - omega[order])).clamp(min=0.0).minimum(omega[order])
    return {
        "dynamic_range_stops": math.log2(hi / lo),
        "peak_to_mean": float(lum.max()) / mean,
        "cct_kelvin": cct_mccamy((rgb * omega).sum(1)),
        "top1_energy": float((lum[order] * part).sum()) / total,
    }


def environment_group(env: Environment) -> str:
    """The comparison group of an environment.

    ``"real"`` for a real map as captured (``source`` ``"real:..."``, no augmentation), ``"real, augmented"``
    for an augmented one, ``"portrait lights"`` for the lights portraits are taken under (``source``
    ``"portrait:..."``: flash, studio, window, street, screen, whatever their label), ``"procedural outdoor"`` /
    ``"procedural indoor"`` for the others (by label).

    Args:
        env: the environment.

    Returns:
        one of :data:`GROUP_ORDER`.

    Examples:
        >>> from kornia_ilum_lab.synth.environments import Environment
        >>> env = Environment(torch.ones(3, 4, 8), torch.ones(3, 32, 32), "indoor", "indoor:room")
        >>> environment_group(env)
        'procedural indoor'
        >>> environment_group(Environment(env.latlong, env.mirror_ball, "outdoor", "portrait:street"))
        'portrait lights'
    """
    if env.source.startswith("real:"):
        return "real, augmented" if "augment" in env.params else "real"
    if env.source.startswith("portrait:"):
        return "portrait lights"
    return f"procedural {env.label}"


def source_group(env: Environment) -> str:
    """One group per procedural kind, its ``source`` (``"sky: clear"``, ``"portrait: flash"``, ...); the real
    maps as :func:`environment_group` (``"real"``, ``"real, augmented"``): a finer grouping for tables.

    Args:
        env: the environment.

    Returns:
        the group's name: the environment's ``source`` with a space after its first colon, or a real map's
        group.

    Examples:
        >>> from kornia_ilum_lab.synth.environments import Environment
        >>> env = Environment(torch.ones(3, 4, 8), torch.ones(3, 32, 32), "indoor", "portrait:flash")
        >>> source_group(env)
        'portrait: flash'
    """
    if env.source.startswith("real:"):
        return environment_group(env)
    return env.source.replace(":", ": ", 1)


def stats_rows(
    envs: Iterable[Environment],
    group_of: Callable[[Environment], str] = environment_group,
    layout: str = "mirror_ball",
) -> list[dict[str, Any]]:
    """One row per environment: ``{"source", "label", "group", <the four statistics>}``.

    Computed on the mirror balls (``layout="mirror_ball"``, the estimators' target) or the lat-long maps.

    Args:
        envs: the environments.
        group_of: the grouping (:func:`environment_group`, :func:`source_group` or any function of an
            environment).
        layout: ``"mirror_ball"`` or ``"latlong"``: which of the environment's maps to measure.

    Returns:
        one dict per environment, in order: its ``source``, ``label``, ``group`` and the four statistics of
        :func:`lighting_stats`.

    Raises:
        ShapeError, ValueCheckError, NonFiniteError: as :func:`lighting_stats`.

    Examples:
        >>> from kornia_ilum_lab.synth.environments import Environment
        >>> env = Environment(torch.ones(3, 4, 8), torch.ones(3, 32, 32), "outdoor", "sky:clear")
        >>> stats_rows([env])[0]["group"]
        'procedural outdoor'
    """
    rows = []
    for env in envs:
        data = env.mirror_ball if layout == "mirror_ball" else env.latlong
        stats = lighting_stats(data, layout)
        rows.append({"source": env.source, "label": env.label, "group": group_of(env), **stats})
    return rows


def _ordered_groups(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """Groups in :data:`GROUP_ORDER`, then the others in order of first appearance."""
    seen = list(dict.fromkeys(r["group"] for r in rows))
    return [g for g in GROUP_ORDER if g in seen] + [g for g in seen if g not in GROUP_ORDER]


def summarize(rows: Sequence[Mapping[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per group (:data:`GROUP_ORDER` first): ``n`` and, per statistic, ``(p10, median, p90)``.

    Percentiles interpolate linearly (:func:`torch.quantile`), ``nan`` values are left out.

    Args:
        rows: rows of :func:`stats_rows` (each with a ``group`` and any of the statistics of :data:`STATS`).

    Returns:
        ``{group: {"n": count, statistic: (p10, median, p90), ...}}``, the groups in :data:`GROUP_ORDER` and
        then in order of first appearance; a statistic with no value in a group is left out.

    Examples:
        >>> rows = [{"group": "a", "peak_to_mean": v} for v in (1.0, 2.0, 3.0)]
        >>> summarize(rows)["a"]["peak_to_mean"]
        (1.2, 2.0, 2.8)
    """
    groups: dict[str, list[Mapping[str, Any]]] = {g: [] for g in _ordered_groups(rows)}
    for row in rows:
        groups[row["group"]].append(row)
    out: dict[str, dict[str, Any]] = {}
    for name, members in groups.items():
        out[name] = {"n": len(members)}
        for key in STATS:
            vals = torch.tensor([float(r[key]) for r in members if key in r], dtype=torch.float64)
            vals = vals[~vals.isnan()]
            if vals.numel() == 0:
                continue
            q = torch.quantile(vals, torch.tensor([0.1, 0.5, 0.9], dtype=torch.float64))
            out[name][key] = tuple(round(float(v), 10) for v in q)
    return out


def _fmt(key: str, v: float) -> str:
    if key == "top1_energy":
        return f"{100 * v:.1f} %"
    if key == "cct_kelvin":
        return f"{v:.0f}"
    if key == "peak_to_mean":
        return f"{v:.3g}" if v < 1e4 else f"{v:.2e}"
    return f"{v:.1f}"


def format_table(summary: Mapping[str, Mapping[str, Any]]) -> str:
    """The summary as a reStructuredText simple table: per group, ``median [p10, p90]`` of each statistic.

    Args:
        summary: the output of :func:`summarize`.

    Returns:
        the table, one line per group (``-`` for a missing statistic), without a final line break.

    Examples:
        >>> print(format_table({"real": {"n": 3, "peak_to_mean": (1.2, 2.0, 2.8)}}).splitlines()[1])
        group  n  dynamic range (stops)  peak / mean   CCT (K)  energy in top 1 %
    """
    header = ["group", "n", *STATS.values()]
    lines = []
    for name, entry in summary.items():
        cells = [name, str(entry["n"])]
        for key in STATS:
            if key in entry:
                p10, med, p90 = entry[key]
                cells.append(f"{_fmt(key, med)} [{_fmt(key, p10)}, {_fmt(key, p90)}]")
            else:
                cells.append("-")
        lines.append(cells)
    widths = [max(len(r[i]) for r in [header, *lines]) for i in range(len(header))]
    rule = "  ".join("=" * w for w in widths)

    def join(cells: Sequence[str]) -> str:
        return "  ".join(c.ljust(w) for c, w in zip(cells, widths, strict=True)).rstrip()

    return "\n".join([rule, join(header), rule, *(join(c) for c in lines), rule])


def write_csv(rows: Sequence[Mapping[str, Any]], path: str | os.PathLike[str]) -> None:
    """Write the rows of :func:`stats_rows` as CSV (one line per environment).

    Args:
        rows: rows of :func:`stats_rows`; other keys are ignored.
        path: the CSV file (missing parent folders are created).

    Returns:
        ``None``; the file has a header line ``source,label,group,<the statistics>``.

    Examples:
        >>> import tempfile
        >>> row = {"source": "sky:clear", "label": "outdoor", "group": "procedural outdoor", "peak_to_mean": 2.5}
        >>> with tempfile.TemporaryDirectory() as d:
        ...     write_csv([row], Path(d) / "stats.csv")
        ...     (Path(d) / "stats.csv").read_text().splitlines()[1]
        'sky:clear,outdoor,procedural outdoor,,2.5,,'
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fields = ["source", "label", "group", *STATS]
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)


def plot_histograms(rows: Sequence[Mapping[str, Any]], path: str | os.PathLike[str], dpi: int = 110) -> None:
    """Four histogram panels (one per statistic) comparing the groups; written as PNG with matplotlib.

    Per group the fraction of its environments in each bin (bins shared, evenly spaced on the axis);
    peak / mean and CCT on log axes, CCT clipped to 1500 to 30000 K (McCamy's formula gives nominal values
    far beyond for strongly hued light).

    Args:
        rows: rows of :func:`stats_rows`.
        path: the PNG to write (missing parent folders are created).
        dpi: the PNG's dots per inch.

    Returns:
        ``None``; the figure is written to ``path``.

    Examples:
        >>> import tempfile
        >>> rows = [{"group": g, "dynamic_range_stops": 8.0 + k, "peak_to_mean": 50.0 * (k + 1),
        ...          "cct_kelvin": 5000.0 + 1000 * k, "top1_energy": 0.3 + 0.2 * k}
        ...         for k, g in enumerate(["real", "procedural outdoor"])]
        >>> with tempfile.TemporaryDirectory() as d:
        ...     plot_histograms(rows, Path(d) / "stats.png", dpi=20)
        ...     (Path(d) / "stats.png").is_file()
        True
    """
    import matplotlib  # lazy: matplotlib is optional, and heavy

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt  # lazy, after the backend is chosen

    groups = _ordered_groups(rows)
    fig, axes = plt.subplots(2, 2, figsize=(9.0, 6.2), layout="constrained")
    logs = {"peak_to_mean": (1.0, None), "cct_kelvin": (1500.0, 30000.0)}  # log axes, clipped to these
    for ax, (key, title) in zip(axes.flat, STATS.items(), strict=True):
        data = {g: np.array([float(r[key]) for r in rows if r["group"] == g]) for g in groups}
        data = {g: v[np.isfinite(v)] for g, v in data.items()}
        if key == "top1_energy":
            data = {g: 100.0 * v for g, v in data.items()}
            title = "energy in the top 1 % of solid angle (%)"
        allv = np.concatenate([v for v in data.values() if v.size] or [np.ones(1)])
        if key in logs:
            lo_clip, hi_clip = logs[key]
            data = {g: np.clip(v, lo_clip, hi_clip) for g, v in data.items()}
            lo, hi = max(float(allv.min()), lo_clip), min(float(allv.max()), hi_clip or np.inf)
            bins = np.geomspace(lo, hi if hi > lo * 1.01 else lo * 1.01, 25)
            ax.set_xscale("log")
            if key == "cct_kelvin":
                title = "CCT (K; clipped to 1500 to 30000)"
                ticks = [t for t in (2000, 3000, 5000, 10000, 20000) if lo <= t <= hi]
                ax.set_xticks(ticks, [str(t) for t in ticks])
                ax.minorticks_off()
        else:
            lo, hi = float(allv.min()), float(allv.max())
            if hi - lo <= 1e-6 * max(1.0, abs(hi)):  # one value: a bin of width 1 around it
                lo, hi = lo - 0.5, hi + 0.5
            bins = np.linspace(lo, hi, 25)
        for g, v in data.items():
            if v.size:
                weights = np.full(v.size, 1.0 / v.size)  # fraction per bin: bins are even on the (log) axis
                label = f"{g} ({v.size})"
                ax.hist(v, bins=bins, weights=weights, histtype="step", linewidth=1.6, label=label)
        ax.set_title(title, fontsize=10)
        ax.set_yticks([])
    handles, labels = axes.flat[0].get_legend_handles_labels()
    ncol = max(1, len(groups))
    fig.legend(handles, labels, loc="outside lower center", ncol=ncol, fontsize=8, frameon=False)
    fig.suptitle("Lighting statistics (32 x 32 mirror balls): generated vs real", fontsize=11)
    save_figure(fig, path, dpi, palette=False)
