"""Sparse relighting, measured: the rows of the bench's relighting skip.

**sparse relighting** (:func:`~kornia_ilum.render.relight_sparse`): an eval subject relit by each held-out map at 16
yaws, dense against sparse (:data:`RELIGHT_SETTINGS`): ms per batch, and as error the paper's ``L_rec`` applied to
the portrait (:func:`lrec_like`), over all the maps, the sun-dominated ones and the sun-dominated outdoor ones.
``benchmarks/bench_relight.py`` prints the same measurements per map and setting.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from kornia_ilum.bench.machine import paired_median_seconds
from kornia_ilum.color import gamma_encode
from kornia_ilum.filters import soft_clip
from kornia_ilum.geometry import latlong_to_mirror_ball, mirror_ball_to_lights
from kornia_ilum.render import prepare_sparse, relight_product, relight_sparse, sparse_kept
from kornia_ilum_lab.bench.maps import small_latlong
from kornia_ilum_lab.synth.environments.real import guess_label

__all__ = ["RELIGHT_SETTINGS", "SUNNY", "lrec_like", "relight_groups", "relight_skips", "top_share", "turned_lights"]


def lrec_like(image: torch.Tensor, reference: torch.Tensor) -> float:
    """The paper's ``L_rec`` applied to relit portraits ``(B, C, P)``: the mean absolute difference of the
    gamma-encoded images, each exposed so that the reference's 99th percentile is 1 and soft-clipped, over the
    mean of the encoded reference.

    Args:
        image: the portraits to score (sparse relighting's).
        reference: the same portraits relit densely.

    Returns:
        the relative error (0 for ``image`` equal to ``reference``).

    Shape:
        - image, reference: :math:`(B, C, P)`, ``P`` pixels

    Convention:
        Both are linear images in the same units; the exposure is the reference's, per portrait.

    Examples:
        >>> reference = torch.rand(2, 3, 100, generator=torch.Generator().manual_seed(0))
        >>> lrec_like(reference, reference), lrec_like(2 * reference, reference) > 0
        (0.0, True)
    """
    scale = torch.quantile(reference.flatten(1).float(), 0.99, dim=1).clamp(min=1e-12)[:, None, None]

    def encode(x: torch.Tensor) -> torch.Tensor:
        return gamma_encode(soft_clip((x / scale).clamp(min=0)))

    ref = encode(reference)
    return float((encode(image) - ref).abs().mean() / ref.mean())


#: The sparse-relighting settings of the bench: (name, rank, eps); rank ``None`` is dense.
RELIGHT_SETTINGS = (("dense", None, 0.0), ("eps 0.005, rank 48", 48, 0.005), ("eps 0.01, rank 48", 48, 0.01),
                    ("eps 0.02, rank 48", 48, 0.02), ("eps 0.01, rank 16", 16, 0.01), ("eps 0.01, rank 32", 32, 0.01))


#: A map is sun-dominated when its brightest 1 % of directions carry at least this share of its energy.
SUNNY = 0.5


def top_share(lights: torch.Tensor) -> float:
    """The share of the energy in the brightest 1 % of directions of the first light list of ``(B, N, C)``.

    Args:
        lights: light lists (:func:`~kornia_ilum.geometry.mirror_ball_to_lights`); only the first is read.

    Returns:
        the share in ``[0, 1]``, by the mean over the channels (at least one direction is counted).

    Shape:
        - lights: :math:`(B, N, C)`

    Examples:
        >>> lights = torch.ones(1, 200, 3)
        >>> round(top_share(lights), 4)  # uniform: the top 1 % holds 1 %
        0.01
        >>> lights[0, 0] = 1000.0
        >>> top_share(lights) >= SUNNY  # one sun
        True
    """
    energy = lights[0].mean(-1).sort(descending=True).values
    return float(energy[: max(1, len(energy) // 100)].sum() / energy.sum())


def relight_groups(lights: torch.Tensor, name: str) -> list[str]:
    """The groups of maps a relighting row counts a map in, beyond all of them: the sun-dominated maps
    (:data:`SUNNY`), and those of them that are outdoor (:func:`~kornia_ilum_lab.synth.environments.guess_label`),
    issue 24's target.

    Args:
        lights: the map's light lists (:func:`turned_lights`); only the first is read.
        name: the map's file name.

    Returns:
        the group names, from none to both.

    Examples:
        >>> lights = torch.ones(1, 200, 3)
        >>> relight_groups(lights, "meadow.exr")  # uniform: not sun-dominated
        []
        >>> lights[0, 0] = 1000.0
        >>> relight_groups(lights, "meadow.exr")
        ['sun-dominated maps (top 1 % >= 0.5)', 'sun-dominated outdoor maps']
    """
    if top_share(lights) < SUNNY:
        return []
    return [f"sun-dominated maps (top 1 % >= {SUNNY:g})"] + (["sun-dominated outdoor maps"]
                                                             if guess_label(name) == "outdoor" else [])


def turned_lights(latlong: torch.Tensor, field: Any, batch: int) -> torch.Tensor:
    """``(batch, N, 3)``: a lat-long map turned to ``batch`` evenly spaced yaws, as light lists in the layout of
    ``field`` (its ``lighting_size`` mirror ball, and its ``light_index`` where the field is compact): the batch
    that the relighting rows (:func:`relight_skips`, ``benchmarks/bench_relight.py``) relight.

    Args:
        latlong: ``(1, 3, H, 2H)`` linear lat-long map.
        field: a :class:`~kornia_ilum_lab.synth.lightstage.ReflectanceField`.
        batch: how many yaws.

    Returns:
        the light lists.

    Examples:
        >>> from types import SimpleNamespace
        >>> field = SimpleNamespace(lighting_size=8, light_index=None)
        >>> tuple(turned_lights(torch.ones(1, 3, 8, 16), field, 4).shape)
        (4, 64, 3)
    """
    turns = [latlong.roll(int(k * latlong.shape[-1] / batch), dims=-1) for k in range(batch)]
    lights = mirror_ball_to_lights(latlong_to_mirror_ball(torch.cat(turns), field.lighting_size))
    return lights[:, field.light_index] if field.light_index is not None else lights


def relight_skips(field: Any, maps: Sequence[Path], quick: bool = False, batch: int = 16) -> list[dict[str, Any]]:
    """The sparse-relighting rows (module docstring): times summed and errors averaged over all ``maps``, over
    the sun-dominated ones (:data:`SUNNY`), and over those of them that are outdoor
    (:func:`~kornia_ilum_lab.synth.environments.guess_label`): issue 24's target.

    Args:
        field: the subject-view to relight.
        maps: the held-out maps (:func:`held_out_maps`).
        quick: the first two maps and fewer timed calls (CI).
        batch: yaws per map (a relit batch).

    Returns:
        one row per group of maps and setting of :data:`RELIGHT_SETTINGS`: ``skip``, ``setting``, ``ms``,
        ``speedup`` (over ``"dense"``) and ``error`` (``l_rec_like``, its mean over the maps, and
        ``l_rec_like_max``, of :func:`lrec_like`; ``lights_kept``; ``maps``).

    Examples:
        >>> [name for name, _, _ in RELIGHT_SETTINGS][:2]  # the baseline first
        ['dense', 'eps 0.005, rank 48']

        The rows need a light-stage cache with an eval subject and two held-out maps:

        >>> field = eval_fields(["lightstage/"])[0]  # doctest: +SKIP
        >>> maps = held_out_maps(["hdri/"])  # doctest: +SKIP
        >>> rows = relight_skips(field, maps, quick=True)  # doctest: +SKIP
        >>> rows[0]["skip"], rows[0]["setting"], rows[0]["speedup"]  # doctest: +SKIP
        ('sparse relighting, all held-out maps', 'dense', 1.0)
    """
    prepared = {r: prepare_sparse(field.field, r) for r in {r for _, r, _ in RELIGHT_SETTINGS if r is not None}}
    groups: dict[str, dict[str, dict[str, Any]]] = {}
    repeats = 3 if quick else 15
    for path in maps[:2] if quick else maps:
        lights = turned_lights(small_latlong(path), field, batch)
        dense_lights = lights.to(field.field.dtype)
        reference = relight_product(field.field, dense_lights).float()
        names = ["all held-out maps"] + relight_groups(lights, path.name)
        calls = [(lambda: relight_product(field.field, dense_lights)) if rank is None else
                 (lambda p=prepared[rank], e=eps: relight_sparse(p, lights, e)) for _, rank, eps in RELIGHT_SETTINGS]
        times = paired_median_seconds(calls, repeats)  # in turns: a slow spell hits every setting alike
        for (setting, rank, eps), seconds in zip(RELIGHT_SETTINGS, times, strict=True):
            ms = 1e3 * seconds
            if rank is None:
                out, kept = reference, float(lights.shape[1])
            else:
                out = relight_sparse(prepared[rank], lights, eps)
                kept = float(sparse_kept(prepared[rank], lights, eps).float().mean())
            for name in names:
                t = groups.setdefault(name, {}).setdefault(setting, {"ms": 0.0, "err": [], "kept": [], "maps": 0})
                t["ms"] += ms
                t["err"].append(lrec_like(out, reference))
                t["kept"].append(kept)
                t["maps"] += 1
    return [{"skip": f"sparse relighting, {name}", "setting": setting, "ms": t["ms"],
             "speedup": totals["dense"]["ms"] / t["ms"],
             "error": {"l_rec_like": float(np.mean(t["err"])), "l_rec_like_max": float(np.max(t["err"])),
                       "lights_kept": float(np.mean(t["kept"])), "maps": t["maps"]}}
            for name, totals in groups.items() for setting, t in totals.items()]
