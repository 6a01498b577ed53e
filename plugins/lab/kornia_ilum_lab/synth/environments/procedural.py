r"""Helpers shared by the procedural sources (:mod:`~kornia_ilum_lab.synth.environments.sky`, ``indoor``,
``portrait``).

:class:`Draw` turns a :class:`torch.Generator` into the scalar draws the scene samplers make (uniform,
log-uniform, integer, weighted choice, coin flip), one draw of the generator each, so that a scene depends
only on the generator's state. :func:`latlong_pixels` is the lat-long grid the scenes are rendered on, flat
and cached per height.

Energy-exact emitters: a light source smaller than a pixel, or one whose edges cut pixels, must keep its
energy ``sum(L Omega)`` on the grid (point sampling at pixel centres misses or multiplies it,
docs/conventions.rst, "Mirror ball"). :func:`splat_directions` adds the energy of small cells to the pixels
that hold their directions, divided by the pixels' exact solid angles; :func:`rectangle_cells` cuts a planar
rectangle into cells with their exact solid angles (Van Oosterom and Strackee's formula for the solid angle
of a triangle, IEEE Trans. Biomed. Eng. 30(2), 1983), and :func:`splat_rectangle` puts a rectangular emitter
(a softbox, a window) on the grid with them. Disks (a sun, a lamp) have
:func:`~kornia_ilum_lab.synth.environments.sky.splat_disk`.

Convention:
    The lat-long grid of docs/conventions.rst ("Lat-long"), in its camera frame ("Frames"); float32 on the
    CPU. Every draw is float64 (or an int) from the generator passed in: no other source of randomness.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from functools import lru_cache
from typing import Any

import torch

from kornia_ilum.core.check import check_tensor
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.geometry import (
    angles_to_latlong_pixel,
    direction_to_latlong,
    latlong_directions,
    latlong_solid_angles,
)

__all__ = ["Draw", "latlong_pixels", "rectangle_cells", "splat_directions", "splat_rectangle"]


@lru_cache(maxsize=8)
def latlong_pixels(height: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Cached float32 pixel directions ``(H W, 3)`` and exact solid angles ``(H W,)`` of the lat-long grid.

    The tensors are shared between calls: do not modify them in place.

    Examples:
        >>> d, om = latlong_pixels(4)
        >>> tuple(d.shape), tuple(om.shape), round(float(om.sum()) / math.pi, 4)
        ((32, 3), (32,), 4.0)
    """
    d = latlong_directions(height, dtype=torch.float32).reshape(-1, 3)
    om = latlong_solid_angles(height, dtype=torch.float32).reshape(-1)
    return d, om


class Draw:
    """Scalar draws from a torch generator (the only source of randomness).

    Args:
        generator: the generator every draw reads from.

    Examples:
        >>> draw = Draw(torch.Generator().manual_seed(0))
        >>> 2.0 <= draw.uniform(2.0, 3.0) < 3.0, draw.integer(1, 1), draw.choice(["a"])
        (True, 1, 'a')
    """

    def __init__(self, generator: torch.Generator) -> None:
        self.g = generator

    def uniform(self, lo: float, hi: float) -> float:
        """Uniform in ``[lo, hi)`` (one float64 draw)."""
        return lo + (hi - lo) * float(torch.rand((), generator=self.g, dtype=torch.float64))

    def log_uniform(self, lo: float, hi: float) -> float:
        """Log-uniform in ``[lo, hi)``, ``lo > 0`` (one float64 draw)."""
        return math.exp(self.uniform(math.log(lo), math.log(hi)))

    def integer(self, lo: int, hi: int) -> int:
        """Uniform in ``[lo, hi]`` inclusive."""
        return int(torch.randint(lo, hi + 1, (), generator=self.g))

    def choice(self, options: Sequence[Any], weights: Sequence[float] | None = None) -> Any:
        """One of ``options``, with probability proportional to ``weights`` (equal when ``None``)."""
        w = (
            torch.ones(len(options), dtype=torch.float64)
            if weights is None
            else torch.tensor(weights, dtype=torch.float64)
        )
        return options[int(torch.multinomial(w, 1, generator=self.g))]

    def bernoulli(self, p: float) -> bool:
        """``True`` with probability ``p`` (one uniform draw)."""
        return self.uniform(0.0, 1.0) < p


def splat_directions(latlong: torch.Tensor, directions: torch.Tensor, energy: torch.Tensor) -> torch.Tensor:
    r"""Add the energy of cells arriving from ``directions`` to the lat-long pixels that hold them, exactly.

    Cell ``k`` adds ``energy[k] / Omega_p`` to the pixel ``p`` whose area holds ``directions[k]``
    (``Omega_p`` its exact solid angle), so ``sum(L Omega)`` per channel grows by ``energy.sum(0)`` to float
    rounding. Cells much smaller than a pixel (several across one) spread an emitter by area.

    Args:
        latlong: ``(C, H, 2H)`` map, updated in place and returned.
        directions: ``(N, 3)`` directions light arrives from (normalised here).
        energy: ``(N, C)`` radiance times solid angle of each cell (``L Omega``).

    Returns:
        ``latlong``.

    Raises:
        ShapeError: mismatched shapes.

    Shape:
        - latlong: :math:`(C, H, 2H)`
        - directions: :math:`(N, 3)`
        - energy: :math:`(N, C)`
        - Output: :math:`(C, H, 2H)` (``latlong`` itself)

    Convention:
        Lat-long grid and frame of docs/conventions.rst; accumulated in float64, added in ``latlong``'s dtype.

    Examples:
        >>> env = torch.zeros(3, 8, 16)
        >>> d = torch.tensor([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]])  # ahead, and behind (the seam)
        >>> _ = splat_directions(env, d, torch.tensor([[1.0, 2.0, 3.0], [1.0, 1.0, 1.0]]))
        >>> (env * latlong_solid_angles(8)).sum((-2, -1)).round(decimals=4)
        tensor([2., 3., 4.])
    """
    check_tensor(latlong, "latlong", ["C", "H", "2H"])
    check_tensor(directions, "directions", ["N", "3"], nonempty=False)
    check_tensor(energy, "energy", ["N", str(latlong.shape[0])], nonempty=False)
    c, h, w = latlong.shape
    if w != 2 * h or energy.shape[0] != directions.shape[0]:
        raise ShapeError(
            f"latlong must be (C, H, 2H) and energy (N, C) for directions (N, 3), got "
            f"{tuple(latlong.shape)}, {tuple(energy.shape)} and {tuple(directions.shape)}"
        )
    if directions.shape[0] == 0:
        return latlong
    phi, el = direction_to_latlong(directions.to(torch.float64))
    px = angles_to_latlong_pixel(phi, el, h)
    col = torch.floor(px[:, 0] + 0.5).long().remainder(w)
    row = torch.floor(px[:, 1] + 0.5).long().clamp(0, h - 1)
    flat = torch.zeros(c, h * w, dtype=torch.float64).index_add_(
        1, row * w + col, energy.to(torch.float64).T.cpu()
    )
    om = latlong_solid_angles(h, dtype=torch.float64).reshape(-1)
    latlong.view(c, -1).add_((flat / om).to(device=latlong.device, dtype=latlong.dtype))
    return latlong


def _triangle_solid_angle(a: torch.Tensor, b: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
    """Solid angle ``(...)`` of triangles with vertices ``(..., 3)`` seen from the origin (Van Oosterom and
    Strackee 1983): ``tan(Omega / 2) = |a . (b x c)| / (|a||b||c| + (a.b)|c| + (a.c)|b| + (b.c)|a|)``."""
    la, lb, lc = a.norm(dim=-1), b.norm(dim=-1), c.norm(dim=-1)
    num = (a * torch.linalg.cross(b, c, dim=-1)).sum(-1).abs()
    den = la * lb * lc + (a * b).sum(-1) * lc + (a * c).sum(-1) * lb + (b * c).sum(-1) * la
    return 2.0 * torch.atan2(num, den)


def rectangle_cells(
    corner: Sequence[float] | torch.Tensor,
    *,
    edge_u: Sequence[float] | torch.Tensor,
    edge_v: Sequence[float] | torch.Tensor,
    nu: int,
    nv: int,
) -> tuple[torch.Tensor, torch.Tensor]:
    r"""A planar rectangle cut into ``nu x nv`` cells: their centres and exact solid angles from the origin.

    The rectangle is ``corner + s edge_u + t edge_v``, ``s, t`` in ``[0, 1]`` (metres, or any unit: only
    directions and solid angles come out); each cell's solid angle is that of its two triangles (Van Oosterom
    and Strackee), so they add up to the rectangle's exactly, wherever it lies (not through the origin).

    Args:
        corner: ``(3,)`` a corner.
        edge_u, edge_v: ``(3,)`` the two edges from it.
        nu, nv: cells along each edge.

    Returns:
        ``(centres (nu nv, 3), solid_angles (nu nv,))``, float64.

    Raises:
        ValueCheckError: ``nu`` or ``nv`` below 1.

    Shape:
        - corner, edge_u, edge_v: :math:`(3,)`
        - Output: :math:`(nu\,nv, 3)` and :math:`(nu\,nv,)`

    Convention:
        Frame of docs/conventions.rst ("Frames"): the centres are points (not normalised); seen from the
        origin (the viewer), their directions are where the cells' light arrives from.

    Examples:
        >>> # a 2 x 2 square 1 unit ahead, centred: 4 asin(1 / 2) = 2 pi / 3 steradians
        >>> _, om = rectangle_cells([-1.0, -1.0, -1.0], edge_u=[2.0, 0.0, 0.0], edge_v=[0.0, 2.0, 0.0],
        ...                        nu=5, nv=3)
        >>> round(float(om.sum()) / math.pi, 6)
        0.666667
    """
    if nu < 1 or nv < 1:
        raise ValueCheckError(f"nu and nv must be at least 1, got {nu} and {nv}")
    p0 = torch.as_tensor(corner, dtype=torch.float64).flatten()
    eu = torch.as_tensor(edge_u, dtype=torch.float64).flatten()
    ev = torch.as_tensor(edge_v, dtype=torch.float64).flatten()
    s = torch.arange(nu + 1, dtype=torch.float64) / nu
    t = torch.arange(nv + 1, dtype=torch.float64) / nv
    grid = p0 + s[:, None, None] * eu + t[None, :, None] * ev  # (nu + 1, nv + 1, 3) cell corners
    a, b = grid[:-1, :-1], grid[1:, :-1]
    c, d = grid[1:, 1:], grid[:-1, 1:]
    om = _triangle_solid_angle(a, b, c) + _triangle_solid_angle(a, c, d)
    centres = (a + c) / 2
    return centres.reshape(-1, 3), om.reshape(-1)


def splat_rectangle(
    latlong: torch.Tensor,
    *,
    corner: Sequence[float] | torch.Tensor,
    edge_u: Sequence[float] | torch.Tensor,
    edge_v: Sequence[float] | torch.Tensor,
    radiance: torch.Tensor | Callable[[torch.Tensor], torch.Tensor],
    cells: tuple[int, int] | None = None,
) -> torch.Tensor:
    r"""Add a planar rectangular emitter to a lat-long map, conserving its energy exactly.

    The rectangle (:func:`rectangle_cells`) is cut into cells, by default about four per pixel across (at
    least 4 and at most 256 per edge, from its angular extent), each adding ``L Omega_cell`` with
    :func:`splat_directions`. With a uniform ``radiance`` the map's ``sum(L Omega)`` grows by exactly
    ``L Omega_rect``; a callable radiance (a window showing the outdoors) is evaluated at the cells' centre
    directions.

    Args:
        latlong: ``(C, H, 2H)`` map, updated in place and returned.
        corner, edge_u, edge_v: the rectangle ``corner + s edge_u + t edge_v`` (:func:`rectangle_cells`).
        radiance: ``(C,)`` uniform radiance, or a callable ``directions (N, 3) float32 -> (N, C)``.
        cells: ``(nu, nv)`` cells along the edges; ``None``: from the angular extent.

    Returns:
        ``latlong``.

    Shape:
        - latlong: :math:`(C, H, 2H)`
        - radiance: :math:`(C,)`
        - Output: :math:`(C, H, 2H)` (``latlong`` itself)

    Convention:
        Lat-long grid and frame of docs/conventions.rst; the rectangle's position is relative to the viewer at
        the origin.

    Examples:
        >>> env = torch.zeros(3, 32, 64)
        >>> rect = {"corner": [-1.0, -1.0, -1.0], "edge_u": [2.0, 0.0, 0.0], "edge_v": [0.0, 2.0, 0.0]}
        >>> _ = splat_rectangle(env, **rect, radiance=torch.ones(3))
        >>> round(float((env[0] * latlong_solid_angles(32)).sum()) / math.pi, 5)  # 2 pi / 3 sr of radiance 1
        0.66667
    """
    h = latlong.shape[-2]
    p0 = torch.as_tensor(corner, dtype=torch.float64).flatten()
    eu = torch.as_tensor(edge_u, dtype=torch.float64).flatten()
    ev = torch.as_tensor(edge_v, dtype=torch.float64).flatten()
    if cells is None:
        dist = max(float((p0 + 0.5 * eu + 0.5 * ev).norm()), 1e-9)
        pixel = math.pi / h
        cells = tuple(  # type: ignore[assignment]
            int(min(256, max(4, math.ceil(4.0 * min(math.pi, float(e.norm()) / dist) / pixel))))
            for e in (eu, ev)
        )
    nu, nv = cells  # type: ignore[misc]
    centres, om = rectangle_cells(p0, edge_u=eu, edge_v=ev, nu=nu, nv=nv)
    dirs = centres / centres.norm(dim=-1, keepdim=True)
    if callable(radiance):
        values = radiance(dirs.float()).to(torch.float64)
    else:
        values = torch.as_tensor(radiance, dtype=torch.float64).flatten()[None].expand(len(om), -1)
    return splat_directions(latlong, dirs, values * om[:, None])
