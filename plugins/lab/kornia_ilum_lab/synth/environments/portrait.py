r"""Procedural portrait lighting: on-camera flash, studio lights, a window, night street light, a screen.

Portraits are taken most often under a handful of lights that the skies and rooms of
:mod:`~kornia_ilum_lab.synth.environments.sky` and :mod:`~kornia_ilum_lab.synth.environments.indoor` never make: a
flash on the camera, one or two studio lights or a lamp in a dark room, a window as the only source, a street
lamp at night, the screen of a phone or a computer in a dim room. Two of them light a face from below, which
skies, rooms and real maps hardly do (their main light is more than 15 degrees below the eyes in 0 to 4 % of
their draws; ``benchmarks/colour_tells_direction.py``): the studio's uplight and reflector, and the screen.
:class:`PortraitLightSource` draws them, each kind with its share of the draws (:data:`PORTRAIT_KINDS`,
:data:`PORTRAIT_KIND_WEIGHTS`):

``flash`` (30 %): on-camera flash
    The most common portrait light that the rest of the set lacks (events, parties, night snapshots, phones),
    and the one the project's transfer check found missing (real flash photos read 32 degrees off). Three
    variants: a speedlight or pop-up flash (40 %: its Fresnel window, 3.5-5 x 6-9 cm, is a disk of equivalent
    radius 2.5 to 4 cm: 1 to 4.6 degrees across at 1 to 3 m), the same with a dome or small on-camera softbox
    (25 %, 10 to 25 cm: 2 to 14 degrees) and a phone's LED (35 %, a 4 to 8 mm lens at 0.5 to 2 m: 0.1 to 0.9
    degrees).
    It sits 6 to 12 cm above the lens axis (hot shoe, pop-up; 1.1 to 6.8 degrees up at 1 to 3 m, up to 2 cm
    sideways), or 0.5 to 2 cm from a phone's lens (under 2.3 degrees): "+Z", the centre of the mirror ball,
    is the camera (docs/conventions.rst). Colour on the CIE daylight locus: xenon tubes 5500 to 6000 K,
    behind a diffuser 5300 to 5800 K, phone LEDs 5000 to 6000 K. Around it a dim room (see "Rooms") whose
    light on a diffuse surface facing the flash is **1/500 to 1/20** of the flash's (log-uniform): a flash
    exposing f/4 to f/16 at ISO 100 gives ``E t = 2.5 N^2`` lux seconds (an incident meter's calibration
    ``C = 250``), about 10 to 100 klux over a shutter of 1/60 to 1/250 second, against 50 to 500 lux in lit
    rooms (EN 12464-1: homes, restaurants, offices), 1/20 to 1/2000; the flash's own light bounced by the
    room adds ``(Omega_beam d^2 / A) rho / (1 - rho)`` of it (the enclosure formula: a 1 sr
    beam, 1 to 3 m, 40 to 150 m^2 of walls of albedo 0.2 to 0.5), 1/300 to 1/20. The key is drawn at 10 to
    100 klux (continuous equivalent).
``studio`` (28 %): one or two studio lights or a lamp in a dark or dim room
    Strobes in softboxes (70 %): a rectangle (aspect 1 to 1.5, vertical) of 0.6 to 1.5 m at 1 to 3 m, its
    longer side drawn to span 15 to 45 degrees (within what those sizes and distances allow), 5200 to 5800 K
    (daylight locus), key at 5 to 50 klux (continuous equivalent, as the flash). Or a bare lamp (30 %): a bulb
    or small shade of radius 3 to 15 cm at 0.7 to 2.5 m (1.4 to 24 degrees across), tungsten 2700 to 3200 K
    (Planckian), 20 to 300 lux. The key is placed by the classic patterns: butterfly (18 %: 0 to 10 degrees
    off the camera axis, 35 to 50 up), loop (27 %: 30 to 40 off, 20 to 35 up), Rembrandt (27 %: 40 to 60 off,
    30 to 50 up), split (18 %: 75 to 95 off, 10 to 30 up) and under (10 %: 0 to 45 off, 10 to 45 *below*:
    the footlight or uplight of stage, fashion and horror portraits, a lamp on a low table), on either side.
    A fill light of the same kind (60 % of the strobes, 30 % of the lamps) on the other side, 20 to 60
    degrees off and 0 to 25 up; under a butterfly or loop key, 40 % of the fills are a reflector or a second
    softbox below the chin instead ("clamshell": 0 to 20 degrees off, 15 to 40 below), at a lighting ratio
    ``(E_key + E_fill) : E_fill`` of 2:1 to 8:1 (log-uniform; from "high key" to dramatic, each at normal
    incidence to its own light). The room's light on a surface facing the key is **1/300 to 1/8**
    of the key's: the enclosure estimate ``pi D^2 / A rho / (1 - rho)`` for a Lambertian source of intensity
    ``I`` (``E_key = I / D^2``, flux ``pi I``) runs from about 1/2000 in a black studio (albedo 0.05, 300 m^2)
    to 1/5 in a small white room (albedo 0.5, 60 m^2, ``D`` = 2 m); the dark and dim studios of portraits sit
    within 1/300 to 1/8.
``window`` (18 %): a window as the only source
    A window of 0.8 to 2.5 x 1.0 to 2.2 m, its sill 0.3 to 1 m above the floor, on a wall 0.6 to 2.5 m from
    the subject whose direction is 30 to 120 degrees off the camera axis (on one side), glass transmittance
    0.55 to 0.85, showing the outdoor scene of :mod:`~kornia_ilum_lab.synth.environments.sky` (sky, ground,
    horizon; overcast 50 %, hazy 20 %, clear 30 %) with the sun behind the window's wall (north light: no sun
    patch).
    Its radiance is the outdoor scene's (kcd/m^2), so it is brightest where it shows sky. The room is
    otherwise dark to dim: its light on a surface facing the window is **1/200 to 1/4** of the window's
    (the enclosure estimate above for a window of radiance ``L`` and area ``A_w`` at ``D``: ``pi D^2 / A
    rho / (1 - rho)``, from 1/500 next to the window of a large dark room to near 1 in a small white one).
``street`` (12 %): night street light, label ``"outdoor"``
    The night sky of :class:`~kornia_ilum_lab.synth.environments.SkySource` (moon in 60 %, urban sky glow, a
    ground lit by the lamps, horizon occluders) with a key street lamp near the subject: 4 to 10 m high, 1 to
    8 m away horizontally (17 to 83 degrees above the horizon at eye height, 1.6 m), a head of radius 0.1 to
    0.3 m, giving 10 to 100 lux on the ground below it (EN 13201's road classes average 2 to 50 lux, 2 to 3
    times that under a luminaire), high-pressure sodium (50 %, 1950 to 2200 K) or LED (3500 to 4500 K),
    Planckian.
    Zero to five more lamps, 12 to 80 m away, together at most an eighth of the key's illuminance at normal
    incidence (the key is the light the portrait is taken under). The rest (sky glow, moon, the ground and its
    pools of light, the other lamps) on a surface facing the key is physical, not drawn, and measured in
    ``params["ambient_ratio"]``: over 1500 draws a median of 1/32 of the key, 1/250 to 1/11 from the 10th to
    the 90th percentile, at most 1/3 (a snowy street lit from low down), so below 1/2.
``screen`` (12 %): the screen of a phone, laptop or monitor in a dim room
    Selfies, video calls and night snapshots lit by the screen the subject looks at: a phone (40 %: 6.5 to 7.5
    x 14 to 16 cm, held upright at 0.25 to 0.45 m, 0.2 to 0.8 kcd/m^2), a laptop (35 %: 30 to 36 x 19 to 23
    cm at 0.45 to 0.7 m, 0.15 to 0.4 kcd/m^2) or a monitor (25 %: 50 to 70 x 30 to 40 cm at 0.5 to 0.9 m, 0.1
    to 0.3 kcd/m^2; maximum luminances of current panels, set lower at night), facing the subject, 0 to 25
    degrees off the camera axis and 35 degrees below to 5 above the eyes (phones and laptops are held or
    set below them; ergonomic monitor heights reach eye level). White on the daylight locus, 5500 to 9000 K
    (panels are set to D65, often bluer). That is 20 to 100 lux on the face; a room at night gives 5 to 100
    lux (a lamp or two), so the room's light on a surface facing the screen is **1/20 to 1/2** of the
    screen's, its pattern that of 1 or 2 practical lamps (``room_share`` 0.5 to 1) and the screen's bounce.

Rooms (``flash``, ``studio``, ``window``, ``screen``):
    A box (2.4 to 3.6 m high, the subject's eyes 1.2 to 1.7 m above the floor, walls 0.8 to 5 m away and
    enlarged to hold the lights and the camera, turned by up to 25 degrees), Lambertian: a home (walls of
    albedo 0.3 to 0.8), a dark venue (0.04 to 0.25) or a studio (walls 0.03 to 0.12 or 0.5 to 0.8, a black,
    grey or white backdrop behind the subject). Each wall point is lit by the lights (cut into 3 x 3 cells,
    ``L A cos_e cos_r / r^2``, the room being an empty convex box: no shadows) and by the enclosure formula
    ``(Phi / A) rho_bar / (1 - rho_bar)`` for the further bounces, as in
    :mod:`~kornia_ilum_lab.synth.environments.indoor`, and hidden where a light covers it. ``flash`` rooms also
    have 1 to 3 practical lamps, ``screen`` rooms 1 or 2, and 30 % of the studios 1 or 2 (isotropic spheres of
    radius 6 to 20 cm, 150 to 1500 lm, tungsten 2700 to 3200 K; in 35 % of the flash rooms one of them is a
    cool 4000 to 6500 K source: mixed light), seen as small disks and lighting the walls. The ambient is the
    room lit by the key and fill and the room lit by the practicals, each normalised to unit irradiance on the
    key-facing surface and mixed with the drawn ``room_share`` of the practicals (flash 0.3 to 0.9, screen 0.5
    to 1, studio 0.1 to 0.5 when they are there, else 0), then scaled to the drawn ``ambient_ratio`` of the
    key's irradiance: the light's pattern is the room's (falloff, wall colours, lamps), its level the drawn
    ratio.

Units:
    Linear sRGB radiance, 1 = 1 kcd/m^2 (as :mod:`~kornia_ilum_lab.synth.environments.sky`), irradiances in klux;
    a flash or strobe is its continuous equivalent over the exposure. Absolute levels matter little (portraits
    are auto-exposed); the ratios between the key, the fill and the ambient are the physics above. A light's
    ``irradiance_klux`` (``params["lights"]``; drawn, or for a window computed from the outdoor scene) is its
    luminance ``Y`` irradiance on a surface facing its centre, independent of the grid: ``pi L sin^2 r`` for
    a disk of angular radius ``r``, a sum over 32 x 32 cells of exact solid angles for a rectangle. On a grid
    it reads the same up to the cosines at the pixel centres (within a percent or two at 32 rows).

Energy on the grid:
    Every light is put on the lat-long grid energy-exactly: disks (flashes, bulbs, street lamps, practicals)
    with :func:`~kornia_ilum_lab.synth.environments.sky.splat_disk`, rectangles (softboxes, windows) with
    :func:`~kornia_ilum_lab.synth.environments.procedural.splat_rectangle` (cells with exact solid angles), so
    ``sum(L Omega)`` holds each source's energy to float rounding, and the mirror ball is resampled with the
    energy-conserving :func:`~kornia_ilum.geometry.latlong_to_mirror_ball`.

Camera-anchored:
    The flash, studio, window and screen lights are placed relative to the camera, so their environments carry
    ``params["camera_anchored"] = True``: :class:`~kornia_ilum_lab.synth.environments.Augment` does not turn them
    (flip, exposure and white balance still apply) and the portraits keep them where the camera put them.
    Street lamps stand anywhere (drawn over the full circle) and are turned like any outdoor scene.

Convention:
    Camera frame and lat-long grid of docs/conventions.rst (+X right, +Y up, +Z toward the camera; a direction
    is where light comes *from*); the subject's head at the origin; maps float32 on the CPU;
    ``sample(generator)`` depends only on the generator.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import torch

from kornia_ilum.core.check import check_positive_int
from kornia_ilum.core.errors import TypeCheckError, ValueCheckError
from kornia_ilum.geometry import latlong_to_mirror_ball
from kornia_ilum_lab.synth.environments.base import Environment
from kornia_ilum_lab.synth.environments.procedural import Draw, latlong_pixels, rectangle_cells, splat_rectangle
from kornia_ilum_lab.synth.environments.sky import (
    CONDITIONS,
    OutdoorScene,
    SkySource,
    cct_to_rgb,
    outdoor_scene,
    splat_disk,
)

__all__ = [
    "AMBIENT_RATIOS",
    "PORTRAIT_KINDS",
    "PORTRAIT_KIND_WEIGHTS",
    "PORTRAIT_SHARE",
    "PortraitLightSource",
    "key_direction",
    "render_portrait",
]

#: The kinds of portrait lighting, in the order :class:`PortraitLightSource` lists them by default.
PORTRAIT_KINDS = ("flash", "studio", "window", "street", "screen")
#: Their default shares of the draws (module docstring).
PORTRAIT_KIND_WEIGHTS = (0.30, 0.28, 0.18, 0.12, 0.12)
#: The share of an :class:`~kornia_ilum_lab.synth.environments.EnvironmentSampler`'s draws that the portrait
#: lights take under :func:`~kornia_ilum_lab.synth.environments.default_weights` (its docstring says why).
PORTRAIT_SHARE = 0.25
#: The range of the ambient's irradiance on a surface facing the key, over the key's (module docstring):
#: drawn log-uniformly in it for the rooms; for the street a bound of what the night scene gives.
AMBIENT_RATIOS: dict[str, tuple[float, float]] = {
    "flash": (1 / 500, 1 / 20),
    "studio": (1 / 300, 1 / 8),
    "window": (1 / 200, 1 / 4),
    "street": (0.0, 1 / 2),
    "screen": (1 / 20, 1 / 2),
}

_LUMA = torch.tensor([0.2126729, 0.7151522, 0.0721750], dtype=torch.float64)
_EYE_HEIGHT_M = 1.6  # the night sky's eye height (sky.py): where the street lamps' heights are measured from
_PATTERNS = {  # key light: (off-axis degrees, elevation degrees)
    "butterfly": ((0.0, 10.0), (35.0, 50.0)),
    "loop": ((30.0, 40.0), (20.0, 35.0)),
    "rembrandt": ((40.0, 60.0), (30.0, 50.0)),
    "split": ((75.0, 95.0), (10.0, 30.0)),
    "under": ((0.0, 45.0), (-45.0, -10.0)),
}
_PATTERN_WEIGHTS = (0.18, 0.27, 0.27, 0.18, 0.10)
_CLAMSHELL = 0.4  # the share of fills below the chin under a butterfly or loop key
# screens: (width m, height m, distance m, luminance kcd/m^2) ranges
_SCREENS = {
    "phone": ((0.065, 0.075), (0.14, 0.16), (0.25, 0.45), (0.2, 0.8)),
    "laptop": ((0.30, 0.36), (0.19, 0.23), (0.45, 0.7), (0.15, 0.4)),
    "monitor": ((0.50, 0.70), (0.30, 0.40), (0.5, 0.9), (0.1, 0.3)),
}
_WINDOW_OUTSIDE = {"overcast": 0.5, "hazy": 0.2, "clear": 0.3}
_CELLS = 3  # rectangles light the walls as 3 x 3 cells


# ----------------------------------------------------------------------------------------------
# geometry


def _toward(off_axis_deg: float, elevation_deg: float) -> list[float]:
    """Unit direction ``off_axis_deg`` from the camera axis (+Z) toward +X, ``elevation_deg`` up."""
    a, e = math.radians(off_axis_deg), math.radians(elevation_deg)
    return [math.sin(a) * math.cos(e), math.sin(e), math.cos(a) * math.cos(e)]


def _unit(v: torch.Tensor) -> torch.Tensor:
    return v / v.norm().clamp(min=1e-12)


def _yaw_matrix(yaw_deg: float) -> torch.Tensor:
    """Camera frame -> room frame, ``p_room = M p_cam`` (as :mod:`~kornia_ilum_lab.synth.environments.indoor`)."""
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    return torch.tensor([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]], dtype=torch.float64)


def _rect_frame(light: dict[str, Any]) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Corner, edges ``u`` (horizontal) and ``v`` (up, along the surface) and the emitting normal of a
    rectangle: a softbox faces the subject, a window faces into the room."""
    p = torch.tensor(light["position_m"], dtype=torch.float64)
    if light["shape"] == "window":
        n = -torch.tensor(light["outward"], dtype=torch.float64)
    else:
        n = _unit(-p)
    up = torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64)
    u = _unit(torch.linalg.cross(up, n))
    v = torch.linalg.cross(n, u)
    w, h = light["width_m"], light["height_m"]
    return p - 0.5 * w * u - 0.5 * h * v, w * u, h * v, n


def key_direction(params: dict[str, Any]) -> torch.Tensor:
    """The direction ``(3,)`` (float64, unit) of the key light of a parameter set of
    :meth:`PortraitLightSource.sample_params`: the centre of the flash, softbox, lamp, window, screen or street
    lamp.

    Args:
        params: the parameters of one portrait light (:meth:`PortraitLightSource.sample_params`), before any
            augmentation.

    Returns:
        the unit direction ``(3,)``, float64, from the subject toward the key light.

    Convention:
        Camera frame of docs/conventions.rst ("Frames"): a direction light arrives from, +Z toward the camera.

    Examples:
        >>> params = PortraitLightSource(("flash",)).sample_params(torch.Generator().manual_seed(0))
        >>> bool(key_direction(params)[2] > 0.99)  # toward the camera
        True
    """
    if params["kind"] == "street":
        lamp = params["outdoor"]["lamps"][0]
        phi = math.radians(lamp["azimuth_deg"])
        rel = torch.tensor(
            [math.sin(phi) * lamp["distance_m"], lamp["height_m"] - _EYE_HEIGHT_M,
             -math.cos(phi) * lamp["distance_m"]], dtype=torch.float64)  # fmt: skip
        return _unit(rel)
    return _unit(torch.tensor(params["lights"][0]["position_m"], dtype=torch.float64))


def _exit(d_room: torch.Tensor, lo: torch.Tensor, hi: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Where rays from the origin along ``d_room (N, 3)`` leave the box ``[lo, hi]``: face index and point."""
    big = torch.full_like(d_room, math.inf)
    t_hi = torch.where(d_room > 1e-12, hi / d_room.clamp(min=1e-12), big)
    t_lo = torch.where(d_room < -1e-12, lo / d_room.clamp(max=-1e-12), big)
    t, axis = torch.minimum(t_hi, t_lo).min(-1)
    side = (d_room.gather(-1, axis[:, None])[:, 0] > 0).long()
    return 2 * axis + side, t[:, None] * d_room


# ----------------------------------------------------------------------------------------------
# rendering


def _irradiance(latlong: torch.Tensor, normal: torch.Tensor) -> float:
    """Luminance irradiance ``sum(Y Omega max(0, d . n))`` of a lat-long map on a surface facing ``n``."""
    h = latlong.shape[-2]
    d, om = latlong_pixels(h)
    cos = (d.double() @ normal.double()).clamp(min=0.0)
    lum = _LUMA @ latlong.double().reshape(3, -1)
    return float((lum * om.double() * cos).sum())


def _color(light: dict[str, Any]) -> torch.Tensor:
    kelvin = torch.tensor(float(light["cct_k"]), dtype=torch.float64)
    return cct_to_rgb(kelvin, light.get("locus", "planckian"))


def _splat_light(env: torch.Tensor, light: dict[str, Any], radiance: Any) -> None:
    """Add a light of the given radiance (``(3,)`` or a callable of directions) to ``env``, energy-exactly."""
    if light["shape"] == "disk":
        p = torch.tensor(light["position_m"], dtype=torch.float64)
        dist = float(p.norm())
        radius = math.asin(min(0.9, light["radius_m"] / dist))
        solid = 2 * math.pi * (1 - math.cos(radius))
        splat_disk(env, p / dist, radius, torch.as_tensor(radiance, dtype=torch.float64) * solid)
    else:
        corner, eu, ev, _ = _rect_frame(light)
        splat_rectangle(env, corner=corner, edge_u=eu, edge_v=ev, radiance=radiance)


class _Room:
    """The box room of a parameter set: what each direction sees, and the light its walls reflect."""

    def __init__(self, room: dict[str, Any], height: int) -> None:
        self.m = _yaw_matrix(room["yaw_deg"])
        lo = torch.tensor(room["lo_m"], dtype=torch.float64)
        hi = torch.tensor(room["hi_m"], dtype=torch.float64)
        self.albedo = torch.tensor(room["albedo"], dtype=torch.float64)  # (6, 3)
        d, _ = latlong_pixels(height)
        face, q_room = _exit(d.double() @ self.m.T, lo, hi)
        n_room = torch.zeros_like(q_room)
        n_room.scatter_(1, (face // 2)[:, None], torch.where(face % 2 == 0, 1.0, -1.0).double()[:, None])
        self.q = q_room @ self.m  # camera frame: p_cam = M^T p_room
        self.n = n_room @ self.m
        self.rho = self.albedo[face]  # (N, 3)
        size = hi - lo
        areas = torch.stack([size[1] * size[2]] * 2 + [size[0] * size[2]] * 2 + [size[0] * size[1]] * 2)
        self.area = float(areas.sum())
        self.rho_bar = (areas[:, None] * self.albedo).sum(0) / self.area

    def walls(self, emitters: list[tuple[torch.Tensor, torch.Tensor, float, torch.Tensor]]) -> torch.Tensor:
        """Wall radiance ``(3, N)`` lit by ``emitters``: ``(position, normal or 0 for isotropic, area,
        power)`` with power ``L A`` (Lambertian cells) or the intensity (isotropic), plus the bounces."""
        if not emitters:
            return torch.zeros(3, self.q.shape[0], dtype=torch.float64)
        e = torch.stack([x[0] for x in emitters])
        ne = torch.stack([x[1] for x in emitters])
        area = torch.tensor([x[2] for x in emitters], dtype=torch.float64)
        power = torch.stack([x[3] for x in emitters])
        iso = ne.abs().sum(-1) == 0
        q, n = self.q, self.n
        dist2 = (q.square().sum(-1, keepdim=True) + e.square().sum(-1)[None] - 2 * q @ e.T).clamp(min=1e-8)
        num_r = (n @ e.T - (q * n).sum(-1, keepdim=True)).clamp(min=0.0)
        num_e = (q @ ne.T - (e * ne).sum(-1)[None]).clamp(min=0.0)
        num_e = torch.where(iso[None], dist2.sqrt(), num_e)
        direct = (num_r * num_e / (dist2 * torch.maximum(dist2, area[None]))) @ power  # (N, 3)
        flux = torch.where(iso[:, None], 4 * math.pi * power, math.pi * power).sum(0)
        bounce = flux / self.area * self.rho_bar / (1 - self.rho_bar).clamp(min=0.05)
        return (self.rho * (direct + bounce) / math.pi).T


def _emitter_cells(light: dict[str, Any], radiance: torch.Tensor) -> list:
    """A light as wall-lighting emitters: 3 x 3 Lambertian cells for a rectangle, one cell for a disk."""
    if light["shape"] == "disk":
        p = torch.tensor(light["position_m"], dtype=torch.float64)
        a = math.pi * light["radius_m"] ** 2
        return [(p, _unit(-p), a, radiance * a)]
    corner, eu, ev, n = _rect_frame(light)
    a = float(eu.norm() * ev.norm()) / _CELLS**2
    out = []
    for i in range(_CELLS):
        for j in range(_CELLS):
            p = corner + (i + 0.5) / _CELLS * eu + (j + 0.5) / _CELLS * ev
            out.append((p, n, a, radiance * a))
    return out


def _light_irradiance(light: dict[str, Any], radiance: Any) -> float:
    """Luminance irradiance of a light on a surface facing its centre, independent of any grid: ``pi L
    sin^2 r`` for a disk (a spherical cap of angular radius ``r``), 32 x 32 cells of exact solid angles for a
    rectangle (``radiance``: ``(3,)`` or a callable of directions)."""
    p = torch.tensor(light["position_m"], dtype=torch.float64)
    if light["shape"] == "disk":
        radius = math.asin(min(0.9, light["radius_m"] / float(p.norm())))
        return math.pi * math.sin(radius) ** 2 * float(torch.as_tensor(radiance, dtype=torch.float64) @ _LUMA)
    corner, eu, ev, _ = _rect_frame(light)
    centres, om = rectangle_cells(corner, edge_u=eu, edge_v=ev, nu=32, nv=32)
    dirs = centres / centres.norm(dim=-1, keepdim=True)
    if callable(radiance):
        lum = radiance(dirs.float()).double() @ _LUMA
    else:
        lum = torch.full_like(om, float(torch.as_tensor(radiance, dtype=torch.float64) @ _LUMA))
    return float((lum * om * (dirs @ _unit(p)).clamp(min=0.0)).sum())


def _window_radiance(light: dict[str, Any], outdoor: OutdoorScene) -> Any:
    """The radiance a window shows: the outdoor scene through the glass."""
    tau = light["transmittance"]
    return lambda d: tau * outdoor.radiance(d)


def _render_room_kind(params: dict[str, Any], height: int, parts: Sequence[str]) -> torch.Tensor:
    room = _Room(params["room"], height)
    w = 2 * height
    n_key = key_direction(params)
    cover = torch.zeros(3, height, w)
    maps: dict[str, torch.Tensor] = {"key": torch.zeros(3, height, w), "fill": torch.zeros(3, height, w)}
    emitters = []
    for light in params["lights"]:
        _splat_light(cover, light, torch.ones(3, dtype=torch.float64))
        if light["shape"] == "window":
            outdoor = outdoor_scene(params["outdoor"])
            _splat_light(maps[light["role"]], light, _window_radiance(light, outdoor))
            out_n = torch.tensor(light["outward"], dtype=torch.float32)
            e_out = outdoor.irradiance(out_n, include_sun=False).double()
            emitters += _emitter_cells(light, light["transmittance"] * e_out / math.pi)
            continue
        rgb = _color(light)
        radiance = rgb * (light["irradiance_klux"] / _light_irradiance(light, rgb))
        _splat_light(maps[light["role"]], light, radiance)
        emitters += _emitter_cells(light, radiance)
    open_wall = (1 - cover.clamp(0.0, 1.0)).reshape(3, -1)[:1]
    lit = (room.walls(emitters) * open_wall).float().reshape(3, height, w)
    ambient = torch.zeros(3, height, w)
    share = params["room_share"] if params["practicals"] else 0.0
    if share < 1:
        ambient += (1 - share) * lit / max(_irradiance(lit, n_key), 1e-30)
    if share > 0:
        lamps, disks = [], []
        for lamp in params["practicals"]:
            p = torch.tensor(lamp["position_m"], dtype=torch.float64)
            kelvin = torch.tensor(float(lamp["cct_k"]), dtype=torch.float64)
            intensity = cct_to_rgb(kelvin) * (lamp["flux_lm"] / (4 * math.pi) * 1e-3)  # kcd
            lamps.append((p, torch.zeros(3, dtype=torch.float64), (2 * lamp["radius_m"]) ** 2, intensity))
            disks.append((p, lamp["radius_m"], intensity))
        practical = (room.walls(lamps) * open_wall).float().reshape(3, height, w)
        for p, radius, intensity in disks:
            dist = float(p.norm())
            splat_disk(practical, p / dist, math.asin(min(0.9, radius / dist)), intensity / dist**2)
        ambient += share * practical / max(_irradiance(practical, n_key), 1e-30)
    maps["ambient"] = ambient * (params["ambient_ratio"] * params["lights"][0]["irradiance_klux"])
    return sum((maps[p] for p in parts), torch.zeros(3, height, w))


def render_portrait(
    params: dict[str, Any], height: int = 128, parts: Sequence[str] = ("key", "fill", "ambient")
) -> torch.Tensor:
    r"""Render the lat-long map ``(3, H, 2H)`` (float32, kcd/m^2) of a portrait-light parameter set.

    Args:
        params: a parameter set of :meth:`PortraitLightSource.sample_params` (the ``params`` of its
            :class:`~kornia_ilum_lab.synth.environments.Environment`).
        height: the map's height ``H``.
        parts: the components to render, of ``"key"``, ``"fill"`` and ``"ambient"`` (everything else: the
            room, its practical lamps, the night sky, ground and other lamps); all by default.

    Returns:
        the lat-long map of docs/conventions.rst, every light energy-exact (module docstring).

    Raises:
        ValueCheckError: an unknown part.

    Examples:
        >>> params = PortraitLightSource(("studio",)).sample_params(torch.Generator().manual_seed(1))
        >>> env = render_portrait(params, 16)
        >>> env.shape, bool(env.min() >= 0)
        (torch.Size([3, 16, 32]), True)
    """
    check_positive_int(height, "height")
    unknown = [p for p in parts if p not in ("key", "fill", "ambient")]
    if unknown or isinstance(parts, str):
        raise ValueCheckError(f"parts must be a sequence of 'key', 'fill', 'ambient', got {parts!r}")
    if params["kind"] != "street":
        return _render_room_kind(params, height, parts)
    return _render_street(params["outdoor"], height, parts)


def _render_street(night: dict[str, Any], height: int, parts: Sequence[str]) -> torch.Tensor:
    """:func:`~kornia_ilum_lab.synth.environments.sky.render_outdoor` split into the key lamp's disk (the first
    lamp) and the rest (sky, ground and its pools of light, occluders, moon and the other lamps)."""
    scene = outdoor_scene(night)
    env = torch.zeros(3, height, 2 * height)
    if "ambient" in parts:
        d, _ = latlong_pixels(height)
        env += scene.radiance(d).T.reshape(3, height, 2 * height)
    key_index = 0 if night["moon"] is None else 1  # the disks: the moon, then the lamps in order
    for k, (direction, radius, irradiance) in enumerate(scene.disks):
        if ("key" if k == key_index else "ambient") in parts:
            splat_disk(env, direction, radius, irradiance)
    return env


# ----------------------------------------------------------------------------------------------
# sampling


def _albedo(draw: Draw, lo: float, hi: float, tint: float = 0.1) -> list[float]:
    """A linear RGB albedo of luminance drawn in ``[lo, hi]``, tinted by up to ``tint`` per channel."""
    rgb = torch.tensor([draw.uniform(1 - tint, 1 + tint) for _ in range(3)], dtype=torch.float64)
    rgb = rgb * (draw.uniform(lo, hi) / float(rgb @ _LUMA))
    return [min(0.95, float(v)) for v in rgb]


def _room(draw: Draw, style: str, points: list[list[float]], yaw_deg: float | None = None) -> dict[str, Any]:
    """A box room around the subject (at the origin) holding ``points`` (camera frame), in a style."""
    yaw = draw.uniform(-25.0, 25.0) if yaw_deg is None else yaw_deg
    m = _yaw_matrix(yaw)
    eye = draw.uniform(1.2, 1.7)
    lo = [-draw.uniform(0.8, 4.0), -eye, -draw.uniform(0.8, 4.0)]
    hi = [draw.uniform(0.8, 4.0), draw.uniform(2.4, 3.6) - eye, draw.uniform(0.8, 5.0)]
    for p in points:
        q = (m @ torch.tensor(p, dtype=torch.float64)).tolist()
        for k in range(3):
            lo[k], hi[k] = min(lo[k], q[k] - 0.3), max(hi[k], q[k] + 0.3)
    if style == "home":
        walls = [_albedo(draw, 0.3, 0.8, 0.12)] * 4
        floor, ceiling = _albedo(draw, 0.08, 0.35, 0.2), _albedo(draw, 0.6, 0.85, 0.03)
    elif style == "venue":
        walls = [_albedo(draw, 0.04, 0.25, 0.25)] * 4
        floor, ceiling = _albedo(draw, 0.05, 0.2, 0.15), _albedo(draw, 0.05, 0.5, 0.1)
    else:  # studio: dark or white walls, a backdrop behind the subject
        dark = draw.bernoulli(0.6)
        walls = [_albedo(draw, 0.03, 0.12, 0.05) if dark else _albedo(draw, 0.5, 0.8, 0.05)] * 4
        floor, ceiling = _albedo(draw, 0.03, 0.2, 0.05), _albedo(draw, 0.03, 0.6, 0.05)
        backdrop = draw.choice([(0.02, 0.06), (0.12, 0.3), (0.6, 0.85)], [0.35, 0.35, 0.3])
        walls = [walls[0], walls[1], _albedo(draw, *backdrop, 0.15), walls[3]]
    albedo = [walls[0], walls[1], floor, ceiling, walls[2], walls[3]]
    return {"style": style, "yaw_deg": yaw, "lo_m": lo, "hi_m": hi, "albedo": albedo}


def _practicals(draw: Draw, room: dict[str, Any], count: int, mixed: bool) -> list[dict[str, Any]]:
    """Practical lamps in the room: away from the subject, inside the box."""
    m = _yaw_matrix(room["yaw_deg"])
    lo, hi = room["lo_m"], room["hi_m"]
    out = []
    for i in range(count):
        radius = draw.uniform(0.06, 0.2)
        y = lo[1] + draw.uniform(0.5, min(1.9, hi[1] - lo[1] - 0.3))
        cool = mixed and i == count - 1
        cct = draw.uniform(4000.0, 6500.0) if cool else draw.uniform(2700.0, 3200.0)
        flux = draw.log_uniform(150.0, 1500.0)
        for _ in range(10):
            q = [draw.uniform(lo[0] + 0.3, hi[0] - 0.3), y, draw.uniform(lo[2] + 0.3, hi[2] - 0.3)]
            p = (m.T @ torch.tensor(q, dtype=torch.float64)).tolist()
            if math.dist(p, [0.0, 0.0, 0.0]) > 1.0:
                out.append({"position_m": p, "radius_m": radius, "flux_lm": flux, "cct_k": cct})
                break
    return out


def _softbox_angle(draw: Draw, distance: float) -> float:
    """The angle (degrees) spanned by a softbox's longer side: 15 to 45 degrees, within 0.6 to 1.5 m at
    ``distance``."""
    span = [2 * math.degrees(math.atan(s / (2 * distance))) for s in (0.6, 1.5)]
    return draw.uniform(max(15.0, span[0]), min(45.0, span[1]))


def _softbox(draw: Draw, role: str, *, off: float, elev: float, cct: float, irradiance: float
             ) -> dict[str, Any]:
    distance = draw.uniform(1.0, 3.0)
    side = 2 * distance * math.tan(math.radians(_softbox_angle(draw, distance)) / 2)
    aspect = draw.uniform(1.0, 1.5)
    return {
        "role": role,
        "shape": "rect",
        "position_m": [distance * c for c in _toward(off, elev)],
        "width_m": side / aspect,
        "height_m": side,
        "cct_k": cct,
        "locus": "daylight",
        "irradiance_klux": irradiance,
    }


def _lamp(draw: Draw, role: str, *, off: float, elev: float, cct: float, irradiance: float) -> dict[str, Any]:
    distance = draw.uniform(0.7, 2.5)
    return {
        "role": role,
        "shape": "disk",
        "position_m": [distance * c for c in _toward(off, elev)],
        "radius_m": draw.uniform(0.03, 0.15),
        "cct_k": cct,
        "locus": "planckian",
        "irradiance_klux": irradiance,
    }


def _sample_flash(draw: Draw) -> dict[str, Any]:
    variant = draw.choice(["speedlight", "diffused", "phone"], [0.4, 0.25, 0.35])
    if variant == "phone":
        distance = draw.uniform(0.5, 2.0)
        r, a = draw.uniform(0.005, 0.02), draw.uniform(0.0, 2 * math.pi)
        x, y = r * math.cos(a), r * math.sin(a)
        radius, cct = draw.uniform(0.002, 0.004), draw.uniform(5000.0, 6000.0)
    else:
        distance = draw.uniform(1.0, 3.0)
        x, y = draw.uniform(-0.02, 0.02), draw.uniform(0.06, 0.12)
        if variant == "speedlight":
            radius, cct = draw.uniform(0.025, 0.04), draw.uniform(5500.0, 6000.0)
        else:
            radius, cct = draw.uniform(0.05, 0.125), draw.uniform(5300.0, 5800.0)
    key = {
        "role": "key",
        "shape": "disk",
        "position_m": [x, y, distance],
        "radius_m": radius,
        "cct_k": cct,
        "locus": "daylight",
        "irradiance_klux": draw.log_uniform(10.0, 100.0),
    }
    room = _room(draw, draw.choice(["home", "venue"], [0.6, 0.4]), [key["position_m"]])
    practicals = _practicals(draw, room, draw.integer(1, 3), draw.bernoulli(0.35))
    return {
        "variant": variant,
        "lights": [key],
        "room": room,
        "practicals": practicals,
        "room_share": draw.uniform(0.3, 0.9),
        "ambient_ratio": draw.log_uniform(*AMBIENT_RATIOS["flash"]),
        "camera_distance_m": distance,
    }


def _sample_studio(draw: Draw) -> dict[str, Any]:
    variant = draw.choice(["strobes", "lamp"], [0.7, 0.3])
    pattern = draw.choice(list(_PATTERNS), _PATTERN_WEIGHTS)
    (off_lo, off_hi), (el_lo, el_hi) = _PATTERNS[pattern]
    side = draw.choice([-1.0, 1.0])
    off, elev = side * draw.uniform(off_lo, off_hi), draw.uniform(el_lo, el_hi)
    if variant == "strobes":
        cct, make, fill_p = draw.uniform(5200.0, 5800.0), _softbox, 0.6
        key = _softbox(draw, "key", off=off, elev=elev, cct=cct, irradiance=draw.log_uniform(5.0, 50.0))
    else:
        cct, make, fill_p = draw.uniform(2700.0, 3200.0), _lamp, 0.3
        key = _lamp(draw, "key", off=off, elev=elev, cct=cct, irradiance=draw.log_uniform(0.02, 0.3))
    lights = [key]
    ratio = None
    if draw.bernoulli(fill_p):
        ratio = draw.log_uniform(2.0, 8.0)
        if pattern in ("butterfly", "loop") and draw.bernoulli(_CLAMSHELL):
            fill_off, fill_el = -side * draw.uniform(0.0, 20.0), draw.uniform(-40.0, -15.0)
        else:
            fill_off, fill_el = -side * draw.uniform(20.0, 60.0), draw.uniform(0.0, 25.0)
        irradiance = key["irradiance_klux"] / (ratio - 1)
        lights.append(make(draw, "fill", off=fill_off, elev=fill_el, cct=cct, irradiance=irradiance))
    camera = [0.0, 0.0, draw.uniform(1.0, 3.0)]
    style = draw.choice(["studio", "home"], [0.6, 0.4] if variant == "strobes" else [0.3, 0.7])
    room = _room(draw, style, [camera] + [light["position_m"] for light in lights])
    practicals = _practicals(draw, room, draw.integer(1, 2), False) if draw.bernoulli(0.3) else []
    return {
        "variant": variant,
        "pattern": pattern,
        "lighting_ratio": ratio,
        "lights": lights,
        "room": room,
        "practicals": practicals,
        "room_share": draw.uniform(0.1, 0.5) if practicals else 0.0,
        "ambient_ratio": draw.log_uniform(*AMBIENT_RATIOS["studio"]),
        "camera_distance_m": camera[2],
    }


def _sample_screen(draw: Draw) -> dict[str, Any]:
    variant = draw.choice(list(_SCREENS), [0.4, 0.35, 0.25])
    width, height, distance, luminance = (draw.uniform(*r) for r in _SCREENS[variant])
    off, elev = draw.choice([-1.0, 1.0]) * draw.uniform(0.0, 25.0), draw.uniform(-35.0, 5.0)
    key = {
        "role": "key",
        "shape": "rect",
        "position_m": [distance * c for c in _toward(off, elev)],
        "width_m": width,
        "height_m": height,
        "cct_k": draw.uniform(5500.0, 9000.0),
        "locus": "daylight",
    }
    rgb = _color(key)
    key["irradiance_klux"] = _light_irradiance(key, luminance * rgb / float(rgb @ _LUMA))
    camera = [0.0, 0.0, distance]
    room = _room(draw, "home", [camera, key["position_m"]])
    return {
        "variant": variant,
        "lights": [key],
        "room": room,
        "practicals": _practicals(draw, room, draw.integer(1, 2), False),
        "room_share": draw.uniform(0.5, 1.0),
        "ambient_ratio": draw.log_uniform(*AMBIENT_RATIOS["screen"]),
        "camera_distance_m": distance,
    }


def _sample_window(draw: Draw, outside: SkySource) -> dict[str, Any]:
    off = draw.choice([-1.0, 1.0]) * draw.uniform(30.0, 120.0)
    outward = _toward(off, 0.0)
    distance = draw.uniform(0.6, 2.5)
    eye = draw.uniform(1.2, 1.7)
    ceiling = draw.uniform(2.4, 3.6)
    width = draw.uniform(0.8, 2.5)
    sill = draw.uniform(0.3, 1.0)
    height = draw.uniform(1.0, max(1.0, min(2.2, ceiling - 0.3 - sill)))
    lateral = draw.uniform(-0.6, 0.6)
    # the room's x axis is the window's outward normal: (cos yaw, 0, sin yaw) = (sin off, 0, cos off)
    yaw = math.degrees(math.atan2(outward[2], outward[0]))
    along = [-outward[2], 0.0, outward[0]]  # horizontal, along the wall
    y_mid = sill - eye + height / 2
    centre = [distance * outward[k] + lateral * along[k] for k in range(3)]
    centre[1] = y_mid
    room = _room(draw, "home", [], yaw_deg=yaw)
    room["lo_m"][1], room["hi_m"][1] = -eye, ceiling - eye
    room["hi_m"][0] = distance
    room["lo_m"][0] = min(room["lo_m"][0], distance - 3.0)
    room["lo_m"][2] = min(room["lo_m"][2], -abs(lateral) - width / 2 - 0.3)
    room["hi_m"][2] = max(room["hi_m"][2], abs(lateral) + width / 2 + 0.3)
    condition = draw.choice(list(_WINDOW_OUTSIDE), list(_WINDOW_OUTSIDE.values()))
    outdoor = outside.sample_params(draw.g, condition=condition)
    # the sun behind the window's wall (north light): 120 to 240 degrees of azimuth from its outward normal
    phi_out = math.degrees(math.atan2(outward[0], -outward[2]))
    outdoor["sun_azimuth_deg"] = (phi_out + 180.0 + draw.uniform(-60.0, 60.0) + 180.0) % 360.0 - 180.0
    window = {
        "role": "key",
        "shape": "window",
        "position_m": centre,
        "outward": outward,
        "width_m": width,
        "height_m": height,
        "transmittance": draw.uniform(0.55, 0.85),
    }
    window["irradiance_klux"] = _light_irradiance(window, _window_radiance(window, outdoor_scene(outdoor)))
    return {
        "variant": condition,
        "lights": [window],
        "room": room,
        "practicals": [],
        "room_share": 0.0,
        "ambient_ratio": draw.log_uniform(*AMBIENT_RATIOS["window"]),
        "outdoor": outdoor,
    }


def _street_lamp(draw: Draw, near: bool, sodium: bool) -> dict[str, Any]:
    """A street lamp in the format of the night sky's (:class:`~kornia_ilum_lab.synth.environments.SkySource`):
    the key (``near``: 1 to 8 m away) or another one (12 to 80 m, log-uniform)."""
    height = draw.uniform(4.0, 10.0)
    ground_lux = draw.log_uniform(10.0, 100.0)
    return {
        "azimuth_deg": draw.uniform(-180.0, 180.0),
        "distance_m": draw.uniform(1.0, 8.0) if near else draw.log_uniform(12.0, 80.0),
        "height_m": height,
        "radius_m": draw.uniform(0.1, 0.3),
        "intensity_kcd": ground_lux * height**2 * 1e-3,  # E below the lamp = I / h^2
        "cct_k": draw.uniform(1950.0, 2200.0) if sodium else draw.uniform(3500.0, 4500.0),
    }


def _lamp_irradiance(lamp: dict[str, Any]) -> float:
    return lamp["intensity_kcd"] / (lamp["distance_m"] ** 2 + (lamp["height_m"] - _EYE_HEIGHT_M) ** 2)


def _sample_street(draw: Draw, night: SkySource) -> dict[str, Any]:
    outdoor = night.sample_params(draw.g, condition="night")
    sodium = draw.bernoulli(0.5)
    key = _street_lamp(draw, True, sodium)
    others = [
        _street_lamp(draw, False, sodium if draw.bernoulli(0.7) else not sodium)
        for _ in range(draw.integer(0, 5))
    ]
    total = sum(_lamp_irradiance(lamp) for lamp in others)
    cap = _lamp_irradiance(key) / 8
    if total > cap:  # the key dominates: the others together give at most an eighth of its light
        for lamp in others:
            lamp["intensity_kcd"] *= cap / total
    outdoor["lamps"] = [key, *others]
    return {"variant": "sodium" if sodium else "led", "outdoor": outdoor}


class PortraitLightSource:
    r"""Procedural portrait lighting: on-camera flash, studio lights or a lamp, a window, night street light,
    a screen.

    The model, its ranges and their reasons are in the module docstring
    (:mod:`kornia_ilum_lab.synth.environments.portrait`). Environments are labelled ``"indoor"`` (flash,
    studio, window, screen) or ``"outdoor"`` (street); ``source`` is ``"portrait:<kind>"``.

    Args:
        kinds: the kinds to draw from, a subset of :data:`PORTRAIT_KINDS`.
        height: lat-long height ``H`` of the rendered maps (width ``2H``).
        weights: relative probability of each kind (default: :data:`PORTRAIT_KIND_WEIGHTS` of the kinds).
        share: the fraction of an :class:`~kornia_ilum_lab.synth.environments.EnvironmentSampler`'s draws that
            :func:`~kornia_ilum_lab.synth.environments.default_weights` gives this source (``default_share``),
            in ``(0, 1)``; :data:`PORTRAIT_SHARE` by default.

    Attributes:
        label: ``"indoor"``, the label of most of its environments (each carries its own).
        default_share: ``share``.

    Raises:
        ValueCheckError: unknown kinds, bad weights or share.

    Convention:
        ``sample(generator)`` depends only on the generator's state. Maps are in the camera frame of
        docs/conventions.rst, float32 on the CPU, 1 = 1 kcd/m^2.

    Examples:
        >>> source = PortraitLightSource(height=32)
        >>> env = source.sample(torch.Generator().manual_seed(0))
        >>> env.latlong.shape, env.mirror_ball.shape, env.source in {f"portrait:{k}" for k in PORTRAIT_KINDS}
        (torch.Size([3, 32, 64]), torch.Size([3, 32, 32]), True)
    """

    label = "indoor"

    def __init__(
        self,
        kinds: Sequence[str] = PORTRAIT_KINDS,
        height: int = 128,
        weights: Sequence[float] | None = None,
        share: float = PORTRAIT_SHARE,
    ) -> None:
        kinds = (kinds,) if isinstance(kinds, str) else tuple(kinds)
        unknown = [k for k in kinds if k not in PORTRAIT_KINDS]
        if not kinds or unknown:
            raise ValueCheckError(f"kinds must be a non-empty subset of {PORTRAIT_KINDS}, got {kinds}")
        check_positive_int(height, "height")
        if weights is None:
            weights = tuple(PORTRAIT_KIND_WEIGHTS[PORTRAIT_KINDS.index(k)] for k in kinds)
        weights = tuple(float(w) for w in weights)
        bad = any(not math.isfinite(w) or w < 0 for w in weights) or sum(weights) <= 0
        if len(weights) != len(kinds) or bad:
            raise ValueCheckError(
                f"weights must be {len(kinds)} finite non-negative numbers, not all zero, got {weights}"
            )
        if isinstance(share, bool) or not isinstance(share, (int, float)) or not 0.0 < share < 1.0:
            raise ValueCheckError(f"share must be a number in (0, 1), got {share!r}")
        self.kinds, self.height, self.weights = kinds, height, weights
        self.default_share = float(share)
        self._outside = SkySource(CONDITIONS, height=height)

    def __repr__(self) -> str:
        return (
            f"PortraitLightSource(kinds={self.kinds}, height={self.height}, weights={self.weights}, "
            f"share={self.default_share})"
        )

    def sample_params(self, generator: torch.Generator, kind: str | None = None) -> dict[str, Any]:
        """Draw a JSON-serialisable parameter set (kind, lights, room or night sky, ratios).

        Args:
            generator: the only source of randomness.
            kind: force a kind (default: drawn with ``weights``).
        """
        if not isinstance(generator, torch.Generator):
            raise TypeCheckError(f"generator must be a torch.Generator, got {type(generator).__name__}")
        draw = Draw(generator)
        kind = kind if kind is not None else draw.choice(self.kinds, self.weights)
        if kind not in PORTRAIT_KINDS:
            raise ValueCheckError(f"unknown kind {kind!r}; valid ones are {PORTRAIT_KINDS}")
        if kind == "flash":
            p = _sample_flash(draw)
        elif kind == "studio":
            p = _sample_studio(draw)
        elif kind == "window":
            p = _sample_window(draw, self._outside)
        elif kind == "screen":
            p = _sample_screen(draw)
        else:
            p = _sample_street(draw, self._outside)
        return {"kind": kind, **p, "camera_anchored": kind != "street"}

    def sample(self, generator: torch.Generator) -> Environment:
        """Draw one environment; it depends only on ``generator``'s state.

        For the street, ``params["ambient_ratio"]`` is measured on the rendered map (everything but the key
        lamp's disk, on a surface facing it, over the key's irradiance there).
        """
        params = self.sample_params(generator)
        latlong = render_portrait(params, self.height)
        if params["kind"] == "street":
            n = key_direction(params)
            key = _irradiance(render_portrait(params, self.height, ("key",)), n)
            params["ambient_ratio"] = (_irradiance(latlong, n) - key) / key
        ball = latlong_to_mirror_ball(latlong[None], 32)[0]
        label = "outdoor" if params["kind"] == "street" else "indoor"
        return Environment(
            latlong=latlong, mirror_ball=ball, label=label, source=f"portrait:{params['kind']}", params=params
        )
