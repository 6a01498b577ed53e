r"""Near surfaces lit by the same environment: a wall behind the subject and a floor below.

A face crop cannot tell a dark skin under much light from a light skin under less; what the same light falls
on, whose reflectance has nothing to do with the skin, can (issue 47: on a held-out head in front of a plain
wall lit by the same map, the wall-to-face brightness ratio tells the skin's tone with R^2 0.86, the far
background's with 0.12). The light stage's portraits stand in front of the environment at infinity; this
module puts matte planes near them:

- a **wall** behind the subject, facing the camera: the plane ``z = -d`` (``d`` metres behind the head),
  from the floor up to ``top`` metres above the eyes (above it the environment shows), unbounded sideways;
- a **floor** (or a table top) ``h`` metres below the eyes: the plane ``y = -h``.

Each plane is Lambertian of albedo ``rho`` (RGB) and lit by the environment alone (one bounce: the planes see
the map, not each other, and the subject casts no shadow on them): its radiance is uniform,
``L = rho / pi * E(n)``, with ``E(n) = sum_p L_p Omega_p max(0, omega_p . n)`` the map's irradiance on a
surface of normal ``n`` (``+Z`` for the wall, ``+Y`` for the floor; the lat-long's exact pixel solid angles).

Both the photo and the lighting target change together, as they would in a real room:

- :func:`with_surroundings`: the environment as the subject sees it, the planes in it (every direction
  whose ray from the head meets a plane first shows that plane's radiance). This is the lighting that relights
  the subject and the lighting target: the estimator is asked for the light that reaches the face, wall
  included;
- :func:`surroundings_view`: which pixels of the camera's frame see a plane (rays from the camera, ``D``
  metres in front of the head) and their radiance, for the frame's background.

:func:`draw_surroundings` draws them for training portraits (``PortraitConfig.surroundings``), from what real
portraits stand in front of:

- a wall in 80 % of the draws, 0.3 to 3 m behind the head (log-uniform: against the wall to across a room),
  to the ceiling in half of them, else ending 0.3 to 2 m above the eyes (a garden wall, a partition, a hedge);
  its albedo a grey of 0.05 to 0.85 (log-uniform: black to white paint) tinted by ``exp(N(0, 0.15))`` per
  channel (at most 0.9);
- a floor in 60 % (and wherever there is no wall), 1.1 to 1.7 m below the eyes (seated to standing), or in
  30 % of them a table top 0.25 to 0.5 m below; albedo 0.05 to 0.6 (asphalt, carpet, wood, concrete), tinted
  the same way.

The subject's head is at the origin of the camera frame of docs/conventions.rst (+X right, +Y up, +Z toward
the camera; a direction is where light arrives from). Classification is per pixel centre.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import torch

from kornia_ilum.core.check import check_positive_int, check_tensor
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.geometry import latlong_directions, latlong_solid_angles

__all__ = ["Surroundings", "draw_backdrops", "draw_surroundings", "plane_radiance", "surroundings_view",
           "with_surroundings"]

_WALL_NORMAL = (0.0, 0.0, 1.0)
_TINT = 0.15
_FLOOR_NORMAL = (0.0, 1.0, 0.0)


@dataclass(frozen=True)
class Surroundings:
    """A wall behind the subject and a floor below it (module docstring), each optional.

    Args:
        wall_distance: metres from the head to the wall behind it (``None``: no wall).
        wall_top: metres above the eyes where the wall ends (``math.inf``: a wall to the ceiling).
        wall_albedo: the wall's RGB albedo, each in ``[0, 1]``.
        floor_drop: metres from the eyes down to the floor or table top (``None``: none).
        floor_albedo: the floor's RGB albedo, each in ``[0, 1]``.

    Raises:
        ValueCheckError: a distance that is not positive and finite, an albedo outside ``[0, 1]``, a wall top
            below the floor.

    Examples:
        >>> Surroundings(wall_distance=1.0).has_wall, Surroundings(floor_drop=0.8).has_wall
        (True, False)
    """

    wall_distance: float | None = None
    wall_top: float = math.inf
    wall_albedo: tuple[float, float, float] = (0.5, 0.5, 0.5)
    floor_drop: float | None = None
    floor_albedo: tuple[float, float, float] = (0.3, 0.3, 0.3)

    def __post_init__(self) -> None:
        for name in ("wall_distance", "floor_drop"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, (int, float)) and 0.0 < value < math.inf):
                raise ValueCheckError(f"Surroundings.{name} must be a positive finite number or None, "
                                      f"got {value!r}")
        if not (isinstance(self.wall_top, (int, float)) and not math.isnan(self.wall_top)):
            raise ValueCheckError(f"Surroundings.wall_top must be a number, got {self.wall_top!r}")
        if self.floor_drop is not None and self.wall_top <= -self.floor_drop:
            raise ValueCheckError(f"Surroundings.wall_top ({self.wall_top}) must be above the floor "
                                  f"({-self.floor_drop})")
        for name in ("wall_albedo", "floor_albedo"):
            rho = getattr(self, name)
            if len(rho) != 3 or not all(isinstance(v, (int, float)) and 0.0 <= v <= 1.0 for v in rho):
                raise ValueCheckError(f"Surroundings.{name} must be three numbers in [0, 1], got {rho!r}")

    @property
    def has_wall(self) -> bool:
        """Whether there is a wall behind the subject."""
        return self.wall_distance is not None

    @property
    def has_floor(self) -> bool:
        """Whether there is a floor below the subject."""
        return self.floor_drop is not None


@functools.lru_cache(maxsize=8)
def _directions(height: int) -> torch.Tensor:
    """The lat-long pixels' directions ``(H, 2H, 3)``, float64 (cached: every portrait with surroundings asks;
    read only)."""
    return latlong_directions(height, dtype=torch.float64)


@functools.lru_cache(maxsize=8)
def _cosine_weights(height: int, normal: tuple[float, ...]) -> torch.Tensor:
    """``Omega_p max(0, omega_p . n)`` per lat-long pixel ``(H, 2H)``, float64 (cached; read only)."""
    cos = (_directions(height) @ torch.tensor(normal, dtype=torch.float64)).clamp(min=0.0)
    return latlong_solid_angles(height, dtype=torch.float64) * cos


def plane_radiance(latlong: torch.Tensor, normal: tuple[float, float, float],
                   albedo: tuple[float, float, float]) -> torch.Tensor:
    r"""The radiance ``rho / pi * E(n)`` of a Lambertian plane of normal ``n`` lit by the map ``latlong``.

    Args:
        latlong: ``(3, H, 2H)`` linear lat-long radiance in the camera frame.
        normal: the plane's unit normal (the side that faces the light it reflects).
        albedo: its RGB albedo.

    Returns:
        ``(3,)`` the plane's radiance, float64.

    The cosine is taken at the pixel centres: on a 32-row map a uniform sky's irradiance is ``pi`` to 0.2 %.

    Examples:
        >>> white_sky = torch.ones(3, 32, 64)  # uniform radiance 1: E = pi on any plane, L = rho
        >>> radiance = plane_radiance(white_sky, (0.0, 1.0, 0.0), (0.5, 0.5, 0.5))
        >>> bool(torch.allclose(radiance, torch.full((3,), 0.5, dtype=torch.float64), rtol=2e-3))
        True
    """
    check_tensor(latlong, "latlong", ["3", "H", "W"], nonnegative=True)
    irradiance = (latlong.double().cpu() * _cosine_weights(latlong.shape[-2], tuple(normal))).sum((-2, -1))
    return torch.tensor(albedo, dtype=torch.float64) / math.pi * irradiance


def _hits(origin: torch.Tensor, rays: torch.Tensor, s: Surroundings) -> tuple[torch.Tensor, torch.Tensor]:
    """For rays ``(N, 3)`` from ``origin (3,)``: which meet the wall first and which the floor first."""
    inf = torch.full(rays.shape[:-1], math.inf, dtype=torch.float64)
    t_wall, t_floor = inf, inf.clone()
    if s.has_wall:
        going = rays[..., 2] < 0
        t = torch.where(going, (origin[2] + s.wall_distance) / (-rays[..., 2]).clamp(min=1e-12), inf)
        y = origin[1] + t * rays[..., 1]
        below_floor = y < -s.floor_drop if s.has_floor else torch.zeros_like(going)
        t_wall = torch.where(going & (y <= s.wall_top) & ~below_floor, t, inf)
    if s.has_floor:
        going = rays[..., 1] < 0
        t_floor = torch.where(going, (origin[1] + s.floor_drop) / (-rays[..., 1]).clamp(min=1e-12), inf)
        if s.has_wall:  # the floor ends at the wall
            z = origin[2] + t_floor * rays[..., 2]
            t_floor = torch.where(z >= -s.wall_distance, t_floor, inf)
    wall = torch.isfinite(t_wall) & (t_wall <= t_floor)
    floor = torch.isfinite(t_floor) & (t_floor < t_wall)
    return wall, floor


def _radiances(latlong: torch.Tensor, s: Surroundings) -> tuple[torch.Tensor, torch.Tensor]:
    none = torch.zeros(3, dtype=torch.float64)
    wall = plane_radiance(latlong, _WALL_NORMAL, s.wall_albedo) if s.has_wall else none
    floor = plane_radiance(latlong, _FLOOR_NORMAL, s.floor_albedo) if s.has_floor else none
    return wall, floor


def with_surroundings(latlong: torch.Tensor, surroundings: Surroundings) -> torch.Tensor:
    r"""The environment as the subject sees it with the wall and the floor of ``surroundings`` in it.

    Args:
        latlong: ``(3, H, 2H)`` linear lat-long radiance in the camera frame (the far environment).
        surroundings: the planes.

    Returns:
        ``(3, H, 2H)`` a new map, ``latlong``'s dtype: each direction whose ray from the head meets a plane
        first shows the plane's radiance (:func:`plane_radiance` of the far environment).

    Examples:
        >>> sky = torch.ones(3, 16, 32)
        >>> wall = Surroundings(wall_distance=1.0, wall_top=1.0, wall_albedo=(0.2, 0.2, 0.2))
        >>> room = with_surroundings(sky, wall)
        >>> bool(room[:, 8, 16].lt(1.0).all()), bool(room[:, 0].eq(1.0).all())  # ahead: the wall; up: over it
        (True, True)
    """
    check_tensor(latlong, "latlong", ["3", "H", "W"], nonnegative=True)
    if not (surroundings.has_wall or surroundings.has_floor):
        return latlong.clone()
    wall, floor = _hits(torch.zeros(3, dtype=torch.float64), _directions(latlong.shape[-2]), surroundings)
    l_wall, l_floor = _radiances(latlong, surroundings)
    out = torch.where(wall, l_wall[:, None, None], latlong.double().cpu())  # new: latlong stays
    return torch.where(floor, l_floor[:, None, None], out).to(latlong)


def surroundings_view(latlong: torch.Tensor, surroundings: Surroundings, rays: torch.Tensor,
                      camera_distance: float) -> tuple[torch.Tensor, torch.Tensor]:
    r"""What the camera sees of the planes: which of its ``rays`` meet one, and the radiance there.

    Args:
        latlong: ``(3, H, 2H)`` the far environment in the camera frame (it lights the planes).
        surroundings: the planes.
        rays: ``(..., 3)`` unit ray directions of the camera's pixels (camera frame, looking along ``-Z``).
        camera_distance: metres from the camera to the head (the camera sits at ``(0, 0, D)``).

    Returns:
        ``(mask (...), radiance (3, ...))``: the pixels that see a plane, and their radiance (0 elsewhere),
        float32.

    Examples:
        >>> rays = torch.tensor([[0.0, 0.0, -1.0], [0.0, 0.9, -0.1]])
        >>> rays = rays / rays.norm(dim=-1, keepdim=True)
        >>> wall = Surroundings(wall_distance=1.0, wall_top=1.0)
        >>> mask, radiance = surroundings_view(torch.ones(3, 16, 32), wall, rays, camera_distance=2.0)
        >>> mask.tolist()  # straight ahead: the wall; steeply up: over the wall's top
        [True, False]
    """
    check_tensor(rays, "rays", ["*", "3"])
    if not 0.0 < camera_distance < math.inf:
        raise ValueCheckError(f"camera_distance must be positive and finite, got {camera_distance!r}")
    origin = torch.tensor([0.0, 0.0, float(camera_distance)], dtype=torch.float64)
    wall, floor = _hits(origin, rays.double(), surroundings)
    l_wall, l_floor = _radiances(latlong, surroundings)
    shape = (3,) + tuple(rays.shape[:-1])
    radiance = torch.zeros(shape, dtype=torch.float64)
    radiance = torch.where(wall, l_wall.view(3, *([1] * wall.dim())), radiance)
    radiance = torch.where(floor, l_floor.view(3, *([1] * floor.dim())), radiance)
    return wall | floor, radiance.float()


def _albedo(grey_range: tuple[float, float], u: float, tint: Sequence[float],
            spread: float = _TINT) -> tuple[float, float, float]:
    lo, hi = (math.log(v) for v in grey_range)
    grey = math.exp(lo + (hi - lo) * u)
    return tuple(min(0.9, grey * math.exp(spread * t)) for t in tint)  # type: ignore[return-value]


def draw_surroundings(n: int, share: float, generator: torch.Generator) -> list[Surroundings | None]:
    r"""Near surfaces for ``n`` portraits: :class:`Surroundings` for a ``share`` of them (module docstring),
    ``None`` for the rest.

    Args:
        n: the portraits.
        share: the fraction that get surroundings, in ``[0, 1]``.
        generator: the only source of randomness (the same draws for the same generator state).

    Returns:
        ``n`` entries.

    Raises:
        ValueCheckError: ``share`` outside ``[0, 1]``.

    Examples:
        >>> rooms = draw_surroundings(100, 0.5, torch.Generator().manual_seed(0))
        >>> drawn = [r for r in rooms if r is not None]
        >>> 30 < len(drawn) < 70, all(r.has_wall or r.has_floor for r in drawn)
        (True, True)
    """
    check_positive_int(n, "n")
    if not 0.0 <= share <= 1.0:
        raise ValueCheckError(f"share must be in [0, 1], got {share!r}")
    u = torch.rand(n, 10, generator=generator, dtype=torch.float64)
    tint = torch.randn(n, 6, generator=generator, dtype=torch.float64)
    out: list[Surroundings | None] = []
    for row, t in zip(u.tolist(), tint.tolist(), strict=True):
        if row[0] >= share:
            out.append(None)
            continue
        wall = row[1] < 0.8
        floor = row[2] < 0.6 or not wall
        distance = math.exp(math.log(0.3) + (math.log(3.0) - math.log(0.3)) * row[3]) if wall else None
        top = math.inf if row[4] < 0.5 else 0.3 + 1.7 * row[5]
        drop = None
        if floor:
            drop = 0.25 + 0.25 * row[7] if row[6] < 0.3 else 1.1 + 0.6 * row[7]
            top = max(top, 0.05 - drop)
        out.append(Surroundings(wall_distance=distance, wall_top=top,
                                wall_albedo=_albedo((0.05, 0.85), row[8], t[:3]),
                                floor_drop=drop, floor_albedo=_albedo((0.05, 0.6), row[9], t[3:])))
    return out


def draw_backdrops(n: int, share: float, generator: torch.Generator,
                   albedo: tuple[float, float] = (0.02, 0.9)) -> list[Surroundings | None]:
    r"""Studio backdrops for ``n`` portraits: a plain matte wall for a ``share`` of them, ``None`` for the rest.

    A backdrop is a wall to the ceiling 0.5 to 3 m behind the head (log-uniform), no floor in view, so the
    camera sees it in every background pixel: a uniform colour whose brightness is the light's times the
    backdrop's own albedo, whatever the skin in front of it (``PortraitConfig.plain_background``). Its albedo is
    a grey log-uniform in ``albedo`` (black velvet to white seamless paper) tinted by ``exp(N(0, 0.1))`` per
    channel (at most 0.9); it reflects onto the subject as any wall of :func:`draw_surroundings` does.

    Args:
        n: the portraits.
        share: the fraction that stand in front of a backdrop, in ``[0, 1]``.
        generator: the only source of randomness.
        albedo: the range of the backdrop's grey albedo, ``0 < low <= high <= 0.9``.

    Returns:
        ``n`` entries.

    Raises:
        ValueCheckError: ``share`` outside ``[0, 1]`` or ``albedo`` out of its range.

    Examples:
        >>> drops = draw_backdrops(100, 1.0, torch.Generator().manual_seed(0))
        >>> all(d.has_wall and not d.has_floor and d.wall_top == math.inf for d in drops)
        True
    """
    check_positive_int(n, "n")
    if not 0.0 <= share <= 1.0:
        raise ValueCheckError(f"share must be in [0, 1], got {share!r}")
    if not (len(albedo) == 2 and 0.0 < albedo[0] <= albedo[1] <= 0.9):
        raise ValueCheckError(f"albedo must be a pair 0 < low <= high <= 0.9, got {albedo!r}")
    u = torch.rand(n, 3, generator=generator, dtype=torch.float64)
    tint = torch.randn(n, 3, generator=generator, dtype=torch.float64)
    return [Surroundings(wall_distance=math.exp(math.log(0.5) + math.log(6.0) * row[1]),
                         wall_albedo=_albedo(albedo, row[2], t, spread=0.1)) if row[0] < share else None
            for row, t in zip(u.tolist(), tint.tolist(), strict=True)]
