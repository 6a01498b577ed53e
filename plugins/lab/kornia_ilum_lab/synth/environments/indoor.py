r"""Procedural indoor environments: a lit box room around the camera.

Indoor lighting is where the real maps are thin, so rooms are drawn with the features that shape it:

Geometry:
    An axis-aligned box ``[0, W] x [0, H] x [0, D]`` metres (W 3 to 9, H 2.4 to 3.6, D 3 to 12), turned by a
    random yaw about +Y relative to the camera, with the camera inside it (1.1 to 1.8 m high, at least 0.6 m
    from the walls). Every lat-long pixel's direction is cast from the camera to the box (analytic ray-box
    intersection, vectorised) and shaded where it lands.

Emitters (all in kcd/m^2 and klux, the units of :mod:`~kornia_ilum_lab.synth.environments.sky`):
    - Ceiling panels: Lambertian rectangles, 1.5 to 8 kcd/m^2 (LED panels and troffers), one colour
      temperature per room, 2700 to 6500 K.
    - Windows: rectangles on the walls, split into panes by a frame, showing the outdoor scene of
      :mod:`~kornia_ilum_lab.synth.environments.sky` (its sky, ground and horizon, and the sun or moon when
      the line of sight passes through a pane) times a glass transmittance of 0.55 to 0.85; in lighting the
      room each pane is a Lambertian emitter of radiance ``tau E_out / pi``, ``E_out`` the outdoor sky and
      ground irradiance on its outward plane, and direct sunlight through a pane lights the surfaces it
      reaches (sharp sun patches).
    - Lamps: small isotropic spheres (6 to 18 cm, 150 to 1500 lm, 2200 to 3200 K), as floor or table lamps.
    Colours of colour temperatures are Planckian (:func:`~kornia_ilum_lab.synth.environments.sky.cct_to_rgb`).

Shading:
    Walls, floor, ceiling, door and window frames are Lambertian: ``L = rho / pi (E_direct + E_ambient)``.
    ``E_direct`` sums every emitter with its cosines and inverse-square falloff: panels and windows are cut
    into sub-rectangles of about 0.4 m, at most 3 x 3 (``L A cos_e cos_r / r^2``, with ``r^2 >= A`` against
    the near-field singularity), lamps are points (``I cos_r / r^2``), and the sun adds
    ``tau E_sun cos_r`` where its ray leaves the room through a pane. The room is an empty convex box, so
    no surface shadows another: ignoring occlusion is exact here (lamps and sun are not occluded by
    furniture, as there is none). ``E_ambient`` approximates all further bounces by the enclosure
    (integrating-sphere) formula ``(Phi / A) rho_bar / (1 - rho_bar)`` per channel, with ``Phi`` the flux
    the emitters send into the room, ``A`` the room's area and ``rho_bar`` its area-weighted albedo, so no
    wall is black and coloured walls tint the room.

Energy on the grid:
    Radiance is evaluated at pixel centres, and pixels on an edge of a panel, pane, frame or sun patch
    (whose neighbours see another emitter) are re-evaluated on 4 x 4 sub-pixels weighted by their exact
    solid angles (reusing their pixel's ``E_direct`` where they land on the same face), so a panel keeps
    its energy to 0.4 % at H = 64 and 0.15 % at H = 128 against its exact solid angle. Lamps and the sun
    or moon seen through a pane are disks smaller than or near a pixel; they are added with
    :func:`~kornia_ilum_lab.synth.environments.sky.splat_disk`, which conserves their energy ``I / d^2``
    (``tau E_sun``) exactly, and the mirror ball is resampled with the energy-conserving
    :func:`~kornia_ilum.geometry.latlong_to_mirror_ball`.

Rooms are drawn with 0 to 3 windows (on distinct walls, 1 to 8 panes), a door (60 %), lights on in 60 %
of daytime rooms with windows and always otherwise (1 to 4 panels in 85 % of lit rooms, 0 to 3 lamps, at
least one emitter), and the outdoor conditions clear 35 %, hazy 15 %, overcast 30 %, dusk 10 %, night
10 %. Walls: neutral (55 %), pastel (25 %) or saturated (20 %) colours, with an accent wall in 35 % of
rooms or four different walls in 13 %.

Convention:
    Camera frame and lat-long grid of docs/conventions.rst; float32 maps on the CPU; ``sample(generator)``
    depends only on the generator.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Any

import torch
from kornia.color import hsv_to_rgb

from kornia_ilum.core.check import check_positive_int
from kornia_ilum.core.errors import TypeCheckError
from kornia_ilum.geometry import latlong_to_mirror_ball
from kornia_ilum_lab.synth.environments.base import Environment
from kornia_ilum_lab.synth.environments.procedural import Draw, latlong_pixels
from kornia_ilum_lab.synth.environments.sky import CONDITIONS, SkySource, cct_to_rgb, outdoor_scene, splat_disk

__all__ = ["IndoorSource", "render_room"]

_LUMA = torch.tensor([0.2126729, 0.7151522, 0.0721750])
_WALLS = (0, 1, 4, 5)  # face = 2 * axis + side: x-low, x-high, z-low, z-high; 2 floor, 3 ceiling
_FLOOR, _CEILING = 2, 3
_SUB = 4  # sub-pixels per axis on edges
_EMITTER_CELL = 0.4  # metres: panels and windows are cut into cells about this size for direct lighting
_MAX_CELLS = 3  # ... but at most this many per side
_FRAME = 0.05  # window frame half-width in metres
#: outdoor conditions seen through windows, and their weights
_OUTSIDE = dict(zip(CONDITIONS, (0.35, 0.15, 0.3, 0.1, 0.1), strict=True))


# ----------------------------------------------------------------------------------------------
# geometry


def _face_axes(face: int) -> tuple[int, int, int]:
    """``(normal axis, u axis, v axis)`` of a face: walls use (horizontal, y), floor and ceiling (x, z)."""
    axis = face // 2
    return {0: (0, 2, 1), 1: (1, 0, 2), 2: (2, 0, 1)}[axis]


def _inward(face: int) -> torch.Tensor:
    n = torch.zeros(3)
    n[face // 2] = 1.0 if face % 2 == 0 else -1.0
    return n


def _exit(origin: torch.Tensor, d: torch.Tensor, size: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Where rays from ``origin`` (``(N, 3)`` or ``(3,)``) along ``d (N, 3)`` leave the box: (face, point)."""
    big = torch.full_like(d, math.inf)
    t_hi = torch.where(d > 1e-9, (size - origin) / d.clamp(min=1e-9), big)
    t_lo = torch.where(d < -1e-9, -origin / d.clamp(max=-1e-9), big)
    t_all = torch.minimum(t_hi, t_lo)
    t, axis = t_all.min(-1)
    side = (d.gather(-1, axis[:, None])[:, 0] > 0).long()
    return 2 * axis + side, origin + t[:, None] * d


@lru_cache(maxsize=4)
def _subpixels(height: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Directions ``(H 2H, 16, 3)`` of 4 x 4 sub-pixels and their solid-angle weights ``(H 2H, 16)``."""
    w = 2 * height
    k = _SUB
    edges = math.pi / 2 - math.pi * torch.arange(height * k + 1, dtype=torch.float64) / (height * k)
    el = 0.5 * (edges[:-1] + edges[1:])
    band = (torch.sin(edges[:-1]) - torch.sin(edges[1:])).reshape(height, 1, k, 1).expand(height, w, k, k)
    phi = 2 * math.pi * (torch.arange(w * k, dtype=torch.float64) + 0.5) / (w * k) - math.pi
    el = el.reshape(height, 1, k, 1).expand(height, w, k, k)
    phi = phi.reshape(1, w, 1, k).expand(height, w, k, k)
    d = torch.stack([torch.sin(phi) * torch.cos(el), torch.sin(el), -torch.cos(phi) * torch.cos(el)], -1)
    wts = band / band.sum((-2, -1), keepdim=True)
    return d.reshape(height * w, k * k, 3).float(), wts.reshape(height * w, k * k).float()


# ----------------------------------------------------------------------------------------------
# the room


class _Room:
    """A room built from its parameter set: shading of any direction, and its disks."""

    def __init__(self, params: dict[str, Any]) -> None:
        self.p = params
        self.size = torch.tensor([params["width_m"], params["height_m"], params["depth_m"]])
        self.cam = torch.tensor(params["camera_m"])
        yaw = math.radians(params["yaw_deg"])
        c, s = math.cos(yaw), math.sin(yaw)
        self.rot = torch.tensor([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # camera -> room
        self.albedo = torch.tensor(params["albedo"])  # (6, 3)
        self.outdoor = outdoor_scene(params["outdoor"])
        self.windows = params["windows"]
        self.panels = params["panels"]
        self.lamps = params["lamps"]
        self._build_emitters()

    # --- emitters as point sets for direct lighting
    def _cells(self, face: int, rect: dict[str, float]) -> tuple[torch.Tensor, float]:
        """Centres ``(M, 3)`` of the sub-rectangles of a rectangle on a face, and their area."""
        axis, ua, va = _face_axes(face)
        du, dv = rect["u1"] - rect["u0"], rect["v1"] - rect["v0"]
        nu = min(_MAX_CELLS, max(1, round(du / _EMITTER_CELL)))
        nv = min(_MAX_CELLS, max(1, round(dv / _EMITTER_CELL)))
        u = rect["u0"] + (torch.arange(nu) + 0.5) * du / nu
        v = rect["v0"] + (torch.arange(nv) + 0.5) * dv / nv
        uu, vv = torch.meshgrid(u, v, indexing="ij")
        pts = torch.zeros(nu * nv, 3)
        pts[:, axis] = 0.0 if face % 2 == 0 else float(self.size[axis])
        pts[:, ua], pts[:, va] = uu.flatten(), vv.flatten()
        return pts, du * dv / (nu * nv)

    def _build_emitters(self) -> None:
        """Point sets for direct lighting, and the total flux the emitters send into the room."""
        pos, nrm, power, area, flux = [], [], [], [], torch.zeros(3)

        def add(p: torch.Tensor, n: torch.Tensor, a: float, pw: torch.Tensor) -> None:
            pos.append(p)
            nrm.append(n.expand_as(p))
            area.append(torch.full((len(p),), a))
            power.append(pw.expand_as(p))

        for panel in self.panels:
            rgb = cct_to_rgb(torch.tensor(panel["cct_k"])) * panel["luminance_kcd_m2"]
            pts, a = self._cells(_CEILING, panel)
            add(pts, _inward(_CEILING), a, rgb * a)  # Lambertian cells: intensity L A cos_e
            flux = flux + math.pi * rgb * a * len(pts)
        sun_e = self.outdoor.sun_normal_irradiance.float()
        sun_d = self.outdoor.sun_direction.float()
        for win in self.windows:
            out_n = -_inward(win["face"])
            lw = win["transmittance"] * self.outdoor.irradiance(out_n, include_sun=False) / math.pi
            pts, a = self._cells(win["face"], win)
            add(pts, _inward(win["face"]), a, lw * a)
            a_win = (win["u1"] - win["u0"]) * (win["v1"] - win["v0"])
            sun_in = win["transmittance"] * sun_e * a_win * max(0.0, float(sun_d @ out_n))
            flux = flux + math.pi * lw * a_win + sun_in
        self.lamp_intensity = []
        for lamp in self.lamps:
            intensity = cct_to_rgb(torch.tensor(lamp["cct_k"])) * (
                lamp["flux_lm"] / (4 * math.pi) * 1e-3
            )  # kcd
            self.lamp_intensity.append(intensity)
            add(torch.tensor([lamp["position_m"]]), torch.zeros(3), (2 * lamp["radius_m"]) ** 2, intensity)
            flux = flux + 4 * math.pi * intensity
        self.e_pos = torch.cat(pos) if pos else torch.zeros(0, 3)
        self.e_nrm = torch.cat(nrm) if nrm else torch.zeros(0, 3)
        self.e_area = torch.cat(area) if area else torch.zeros(0)
        self.e_power = torch.cat(power) if power else torch.zeros(0, 3)
        # integrating-sphere estimate of the light after the first bounce (module docstring)
        w, h, d = (float(x) for x in self.size)
        areas = torch.tensor([h * d, h * d, w * d, w * d, w * h, w * h])
        rho = (areas[:, None] * self.albedo).sum(0) / areas.sum()
        self.ambient = flux / areas.sum() * rho / (1 - rho).clamp(min=0.05)

    # --- lookups
    def _rect_at(self, rects: list[dict[str, Any]], face: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
        """Index ``(N,)`` of the rectangle (of ``rects``, each with a ``face``) holding each point, or -1."""
        out = torch.full(face.shape, -1, dtype=torch.long)
        for i, r in enumerate(rects):
            _, ua, va = _face_axes(r["face"])
            inside = (face == r["face"]) & (q[:, ua] >= r["u0"]) & (q[:, ua] < r["u1"])
            inside &= (q[:, va] >= r["v0"]) & (q[:, va] < r["v1"])
            out = torch.where(inside & (out < 0), i, out)
        return out

    def _in_frame(self, win_idx: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
        """Whether points inside windows lie on their frame or mullions."""
        frame = torch.zeros(win_idx.shape, dtype=torch.bool)
        for i, r in enumerate(self.windows):
            sel = win_idx == i
            if not bool(sel.any()):
                continue
            _, ua, va = _face_axes(r["face"])
            for axis, lo, hi, n in (
                (ua, r["u0"], r["u1"], r["panes_u"]),
                (va, r["v0"], r["v1"], r["panes_v"]),
            ):
                t = (q[:, axis] - lo) / (hi - lo) * n  # pane coordinates: frame lines at the integers
                dist = (t - torch.round(t)).abs() * (hi - lo) / n
                frame |= sel & (dist < _FRAME)
        return frame

    def _pane(self, face: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
        """Window index where ``q`` lies on a pane (glass), else -1."""
        idx = self._rect_at(self.windows, face, q)
        return torch.where(self._in_frame(idx, q), -1, idx)

    # --- shading
    def _direct(self, q: torch.Tensor, n: torch.Tensor) -> torch.Tensor:
        """Irradiance ``(N, 3)`` at points ``q`` with normals ``n`` from panels, panes and lamps.

        Every ``(N, M)`` term is a matrix product or an elementwise pass (no ``(N, M, 3)`` temporaries):
        ``|e - q|^2 = |e|^2 + |q|^2 - 2 q.e``, ``(e - q).n = n.e - q.n``, ``(q - e).n_e = q.n_e - e.n_e``.
        """
        if not len(self.e_pos):
            return torch.zeros_like(q)
        e, ne = self.e_pos, self.e_nrm
        dist2 = (q.square().sum(-1, keepdim=True) + e.square().sum(-1)[None] - 2 * q @ e.T).clamp(min=1e-8)
        num_r = (n @ e.T - (q * n).sum(-1, keepdim=True)).clamp(min=0.0)
        lamp = ne.abs().sum(-1) == 0
        num_e = (q @ ne.T - (e * ne).sum(-1)[None]).clamp(min=0.0)
        num_e = torch.where(lamp[None], dist2.sqrt(), num_e)  # isotropic points: cos_e = 1
        geo = num_r * num_e / (dist2 * torch.maximum(dist2, self.e_area[None]))
        return geo @ self.e_power

    def shade(
        self, d_cam: torch.Tensor, ref: tuple[torch.Tensor, torch.Tensor] | None = None
    ) -> tuple[torch.Tensor, torch.Tensor, tuple[torch.Tensor, torch.Tensor]]:
        """Radiance ``(N, 3)`` along camera-frame directions, an id ``(N,)`` of what each sees, and
        ``(face, E_direct)`` per direction.

        ``ref``: the ``(face, E_direct)`` of nearby directions (sub-pixels take their pixel's): the smooth
        direct irradiance of panels, panes and lamps is reused where the face is the same.
        """
        d = d_cam @ self.rot.T
        face, q = _exit(self.cam, d, self.size)
        n = torch.zeros_like(q)
        n.scatter_(1, (face // 2)[:, None], torch.where(face % 2 == 0, 1.0, -1.0)[:, None])
        rho = self.albedo[face]
        door = self.p["door"]
        ident = torch.zeros(face.shape, dtype=torch.long)
        if door is not None:
            on_door = self._rect_at([door], face, q) == 0
            rho = torch.where(on_door[:, None], torch.tensor(door["albedo"]), rho)
            ident = torch.where(on_door, 1, ident)
        win = self._rect_at(self.windows, face, q)
        frame = self._in_frame(win, q)
        if self.windows:
            rho = torch.where(
                frame[:, None],
                torch.tensor([w["frame_albedo"] for w in self.windows])[win.clamp(min=0), None],
                rho,
            )
        pane = torch.where(frame, -1, win)
        if ref is None:
            e_dir = self._direct(q, n)
        else:
            e_dir = ref[1].clone()
            other = (face != ref[0]).nonzero().squeeze(1)
            if len(other):
                e_dir[other] = self._direct(q[other], n[other])
        e = self.ambient + e_dir
        # sun (or moon) through panes
        sun_e = self.outdoor.sun_normal_irradiance.float()
        sunlit = torch.zeros(face.shape, dtype=torch.bool)
        if self.windows and float(sun_e.sum()) > 0:
            s = self.outdoor.sun_direction.float()
            cos_s = (n @ s).clamp(min=0.0)
            f_out, q_out = _exit(q + 1e-4 * n, s.expand_as(q), self.size)
            through = self._pane(f_out, q_out)
            sunlit = (through >= 0) & (cos_s > 0) & (pane < 0)
            tau = torch.tensor([w["transmittance"] for w in self.windows])[through.clamp(min=0)]
            e = e + torch.where(sunlit, tau * cos_s, 0.0)[:, None] * sun_e
        out = rho * e / math.pi
        # emitters seen directly
        for i, panel in enumerate(self.panels):
            on = self._rect_at([dict(panel, face=_CEILING)], face, q) == 0
            rgb = cct_to_rgb(torch.tensor(panel["cct_k"])) * panel["luminance_kcd_m2"]
            out = torch.where(on[:, None], rgb, out)
            ident = torch.where(on, 10 + i, ident)
        if self.windows:
            glass = pane >= 0
            if bool(glass.any()):
                tau = torch.tensor([w["transmittance"] for w in self.windows])[pane[glass]]
                out[glass] = tau[:, None] * self.outdoor.radiance(d[glass])
            ident = torch.where(glass, 20 + pane, torch.where(frame, 30, ident))
        ident = ident + 100 * sunlit.long()
        return out, ident, (face, e_dir)

    def disks(self) -> list[tuple[torch.Tensor, float, torch.Tensor]]:
        """Lamps, and outdoor disks seen through panes: ``(camera-frame direction, radius, irradiance)``."""
        out = []
        for lamp, intensity in zip(self.lamps, self.lamp_intensity, strict=True):
            rel = torch.tensor(lamp["position_m"]) - self.cam
            dist = float(rel.norm())
            out.append(
                (self.rot.T @ (rel / dist), math.asin(min(0.9, lamp["radius_m"] / dist)), intensity / dist**2)
            )
        for direction, radius, irradiance in self.outdoor.disks:
            dr = direction.float()[None]
            f, q = _exit(self.cam, dr, self.size)
            pane = int(self._pane(f, q)[0])
            if pane >= 0:
                out.append((self.rot.T @ dr[0], radius, self.windows[pane]["transmittance"] * irradiance))
        return out


def render_room(params: dict[str, Any], height: int = 128) -> torch.Tensor:
    r"""Render the lat-long map ``(3, H, 2H)`` (float32, kcd/m^2) of a room parameter set.

    Args:
        params: a parameter set of :meth:`IndoorSource.sample_params` (the ``params`` of an indoor
            :class:`~kornia_ilum_lab.synth.environments.Environment`).
        height: the map's height ``H``.

    Returns:
        the lat-long map of docs/conventions.rst, edges supersampled and small emitters splatted (module
        docstring).

    Examples:
        >>> params = IndoorSource().sample_params(torch.Generator().manual_seed(0))
        >>> env = render_room(params, 16)
        >>> env.shape, bool(env.min() > 0)
        (torch.Size([3, 16, 32]), True)
    """
    check_positive_int(height, "height")
    room = _Room(params)
    d, _ = latlong_pixels(height)
    rgb, ident, (face, e_dir) = room.shade(d)
    w = 2 * height
    grid = ident.reshape(height, w)
    edge = torch.zeros_like(grid, dtype=torch.bool)
    for dim, shift in ((0, 1), (0, -1), (1, 1), (1, -1)):
        rolled = torch.roll(grid, shift, dim)
        diff = rolled != grid
        if dim == 0:  # no wrap across the poles
            diff[0 if shift == 1 else -1] = False
        edge |= diff
    idx = edge.flatten().nonzero().squeeze(1)
    if len(idx):
        sub_d, sub_w = _subpixels(height)
        k = sub_d.shape[1]
        ref = (face[idx].repeat_interleave(k), e_dir[idx].repeat_interleave(k, dim=0))
        sub_rgb, _, _ = room.shade(sub_d[idx].reshape(-1, 3), ref)
        rgb[idx] = (sub_rgb.reshape(len(idx), -1, 3) * sub_w[idx, :, None]).sum(1)
    env = rgb.T.reshape(3, height, w).contiguous()
    for direction, radius, irradiance in room.disks():
        splat_disk(env, direction, radius, irradiance)
    return env


# ----------------------------------------------------------------------------------------------
# sampling


def _color(
    draw: Draw, hue: tuple[float, float], sat: tuple[float, float], lum: tuple[float, float]
) -> list[float]:
    """A linear RGB albedo: hue (degrees) and saturation drawn, scaled to a drawn luminance, at most 0.9."""
    hsv = torch.tensor([math.radians(draw.uniform(*hue) % 360.0), draw.uniform(*sat), 1.0]).reshape(3, 1, 1)
    rgb = hsv_to_rgb(hsv).flatten()
    rgb = rgb * (draw.uniform(*lum) / float(rgb @ _LUMA))
    rgb = rgb * min(1.0, 0.9 / float(rgb.max()))
    return [float(v) for v in rgb]


def _wall_color(draw: Draw) -> list[float]:
    style = draw.choice(["neutral", "pastel", "saturated"], [0.55, 0.25, 0.2])
    if style == "neutral":
        return _color(draw, (0.0, 360.0), (0.0, 0.12), (0.35, 0.85))
    if style == "pastel":
        return _color(draw, (0.0, 360.0), (0.15, 0.4), (0.3, 0.75))
    return _color(draw, (0.0, 360.0), (0.45, 0.85), (0.1, 0.45))


def _floor_color(draw: Draw) -> list[float]:
    kind = draw.choice(["wood", "carpet", "tile", "concrete"], [0.4, 0.25, 0.2, 0.15])
    if kind == "wood":
        return _color(draw, (18.0, 40.0), (0.4, 0.75), (0.08, 0.35))
    if kind == "carpet":
        return _color(draw, (0.0, 360.0), (0.1, 0.5), (0.05, 0.3))
    if kind == "tile":
        return _color(draw, (0.0, 360.0), (0.0, 0.15), (0.3, 0.7))
    return _color(draw, (20.0, 50.0), (0.0, 0.08), (0.15, 0.35))


def _wall_length(face: int, size: tuple[float, float, float]) -> float:
    return size[_face_axes(face)[1]]


class IndoorSource:
    r"""Procedural indoor environments: box rooms with panels, windows, lamps and coloured walls.

    The model is in the module docstring (:mod:`kornia_ilum_lab.synth.environments.indoor`).

    Args:
        height: lat-long height ``H`` of the rendered maps (width ``2H``).

    Convention:
        ``sample(generator)`` depends only on the generator's state. Maps are in the camera frame of
        docs/conventions.rst, float32 on the CPU, 1 = 1 kcd/m^2 (as
        :class:`~kornia_ilum_lab.synth.environments.sky.SkySource`).

    Examples:
        >>> env = IndoorSource(height=32).sample(torch.Generator().manual_seed(0))
        >>> env.label, env.source, env.latlong.shape, env.mirror_ball.shape
        ('indoor', 'indoor:room', torch.Size([3, 32, 64]), torch.Size([3, 32, 32]))
    """

    label = "indoor"

    def __init__(self, height: int = 128) -> None:
        check_positive_int(height, "height")
        self.height = height
        self._outside = SkySource(tuple(_OUTSIDE), height=height, weights=tuple(_OUTSIDE.values()))

    def __repr__(self) -> str:
        return f"IndoorSource(height={self.height})"

    def sample_params(self, generator: torch.Generator) -> dict[str, Any]:
        """Draw a JSON-serialisable room: size, camera, materials, panels, windows, door, lamps, outdoors."""
        if not isinstance(generator, torch.Generator):
            raise TypeCheckError(f"generator must be a torch.Generator, got {type(generator).__name__}")
        draw = Draw(generator)
        w, h, d = draw.uniform(3.0, 9.0), draw.uniform(2.4, 3.6), draw.uniform(3.0, 12.0)
        size = (w, h, d)
        cam = [draw.uniform(0.6, w - 0.6), draw.uniform(1.1, min(1.8, h - 0.4)), draw.uniform(0.6, d - 0.6)]
        base = _wall_color(draw)
        walls = [base] * 4
        if draw.bernoulli(0.35):  # an accent wall
            walls[draw.integer(0, 3)] = _color(draw, (0.0, 360.0), (0.35, 0.85), (0.1, 0.5))
        elif draw.bernoulli(0.2):  # every wall its own colour
            walls = [_wall_color(draw) for _ in range(4)]
        ceiling = _color(draw, (0.0, 360.0), (0.0, 0.05), (0.6, 0.85))
        albedo = [walls[0], walls[1], _floor_color(draw), ceiling, walls[2], walls[3]]
        outdoor = self._outside.sample_params(generator)
        night = outdoor["condition"] == "night"
        # windows on distinct walls
        n_win = draw.choice([0, 1, 2, 3], [0.2, 0.4, 0.25, 0.15])
        free = list(_WALLS)
        windows = []
        for _ in range(n_win):
            face = free.pop(draw.integer(0, len(free) - 1))
            length = _wall_length(face, size)
            ww = draw.uniform(0.6, min(3.0, length - 0.4))
            wh = draw.uniform(0.8, min(2.2, h - 0.5))
            u0 = draw.uniform(0.2, length - 0.2 - ww)
            v0 = draw.uniform(0.3, h - 0.15 - wh)
            windows.append(
                {
                    "face": face,
                    "u0": u0,
                    "u1": u0 + ww,
                    "v0": v0,
                    "v1": v0 + wh,
                    "transmittance": draw.uniform(0.55, 0.85),
                    "panes_u": draw.integer(1, max(1, min(4, int(ww / 0.5)))),
                    "panes_v": draw.integer(1, 2),
                    "frame_albedo": draw.uniform(0.6, 0.85)
                    if draw.bernoulli(0.6)
                    else draw.uniform(0.04, 0.15),
                }
            )
        door = None
        if free and draw.bernoulli(0.6):
            face = free[draw.integer(0, len(free) - 1)]
            length = _wall_length(face, size)
            dw, dh = draw.uniform(0.8, 1.0), draw.uniform(2.0, min(2.2, h - 0.1))
            u0 = draw.uniform(0.1, length - 0.1 - dw)
            color = (
                _color(draw, (20.0, 40.0), (0.4, 0.7), (0.08, 0.3))
                if draw.bernoulli(0.5)
                else _wall_color(draw)
            )
            door = {"face": face, "u0": u0, "u1": u0 + dw, "v0": 0.0, "v1": dh, "albedo": color}
        lights_on = night or not windows or draw.bernoulli(0.6)
        panels = []
        if lights_on and draw.bernoulli(0.85):
            cct = draw.uniform(2700.0, 6500.0)
            lum = draw.uniform(1.5, 8.0)
            for _ in range(draw.integer(1, 4)):
                pw, pd = (draw.uniform(0.3, 0.6),) * 2 if draw.bernoulli(0.5) else (0.3, 1.2)
                if draw.bernoulli(0.5):
                    pw, pd = pd, pw
                pw, pd = min(pw, w - 0.6), min(pd, d - 0.6)
                x0, z0 = draw.uniform(0.3, w - 0.3 - pw), draw.uniform(0.3, d - 0.3 - pd)
                panels.append(
                    {"u0": x0, "u1": x0 + pw, "v0": z0, "v1": z0 + pd, "luminance_kcd_m2": lum, "cct_k": cct}
                )
        n_lamps = draw.integer(0, 3) if lights_on else 0
        if lights_on and not panels:
            n_lamps = max(1, n_lamps)
        lamps = []
        for _ in range(n_lamps):
            radius = draw.uniform(0.06, 0.18)
            y = draw.uniform(1.2, min(1.7, h - 0.4)) if draw.bernoulli(0.5) else draw.uniform(0.5, 1.0)
            for _ in range(10):  # keep lamps away from the camera
                pos = [draw.uniform(0.3, w - 0.3), y, draw.uniform(0.3, d - 0.3)]
                if math.dist(pos, cam) > 0.7:
                    lamps.append(
                        {
                            "position_m": pos,
                            "radius_m": radius,
                            "flux_lm": draw.log_uniform(150.0, 1500.0),
                            "cct_k": draw.uniform(2200.0, 3200.0),
                        }
                    )
                    break
        if not (windows or panels or lamps):  # never a black room: one central panel
            panels.append(
                {
                    "u0": w / 2 - 0.3,
                    "u1": w / 2 + 0.3,
                    "v0": d / 2 - 0.3,
                    "v1": d / 2 + 0.3,
                    "luminance_kcd_m2": 4.0,
                    "cct_k": 4000.0,
                }
            )
        return {
            "width_m": w,
            "height_m": h,
            "depth_m": d,
            "camera_m": cam,
            "yaw_deg": draw.uniform(-180.0, 180.0),
            "albedo": albedo,
            "windows": windows,
            "door": door,
            "panels": panels,
            "lamps": lamps,
            "outdoor": outdoor,
        }

    def sample(self, generator: torch.Generator) -> Environment:
        """Draw one indoor environment; it depends only on ``generator``'s state."""
        params = self.sample_params(generator)
        latlong = render_room(params, self.height)
        ball = latlong_to_mirror_ball(latlong[None], 32)[0]
        return Environment(
            latlong=latlong, mirror_ball=ball, label="indoor", source="indoor:room", params=params
        )
