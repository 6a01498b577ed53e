"""Tests of the procedural indoor environments (box rooms with panels, windows, lamps)."""

from __future__ import annotations

import copy
import json
import math

import pytest
import torch

from kornia_ilum.core.errors import TypeCheckError, ValueCheckError
from kornia_ilum.geometry import latlong_directions, latlong_solid_angles, mirror_ball_solid_angles
from kornia_ilum_lab.synth.environments import EnvironmentSource
from kornia_ilum_lab.synth.environments.indoor import IndoorSource, _Room, render_room
from kornia_ilum_lab.synth.environments.sky import cct_to_rgb

F64 = torch.float64
LUMA = torch.tensor([0.2126729, 0.7151522, 0.0721750])
H = 64


def gen(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def energy(latlong: torch.Tensor) -> torch.Tensor:
    return (latlong.double() * latlong_solid_angles(latlong.shape[-2], dtype=F64)).sum((-2, -1))


def luminance(x: torch.Tensor, dim: int = 0) -> torch.Tensor:
    return (x.movedim(dim, -1) * LUMA.to(x.dtype)).sum(-1)


def rect_solid_angle(corners: torch.Tensor) -> float:
    """Solid angle of a planar quadrilateral ``(4, 3)`` (relative to the viewer), by two triangles
    (Van Oosterom and Strackee, IEEE Trans. Biomed. Eng. 1983)."""
    total = 0.0
    for i, j, k in ((0, 1, 2), (0, 2, 3)):
        a, b, c = corners[i], corners[j], corners[k]
        la, lb, lc = a.norm(), b.norm(), c.norm()
        num = torch.dot(a, torch.linalg.cross(b, c)).abs()
        den = la * lb * lc + torch.dot(a, b) * lc + torch.dot(a, c) * lb + torch.dot(b, c) * la
        total += 2 * float(torch.atan2(num, den))
    return total


def black_room(seed: int) -> dict:
    """A sampled room with black surfaces and no emitters (tests add their own)."""
    p = IndoorSource().sample_params(gen(seed))
    p.update(albedo=[[0.0] * 3] * 6, windows=[], door=None, lamps=[], panels=[])
    return p


class TestIndoorSource:
    def test_protocol_labels_params(self):
        source = IndoorSource(height=H)
        assert isinstance(source, EnvironmentSource) and source.label == "indoor"
        env = source.sample(gen(0))
        assert env.label == "indoor" and env.source == "indoor:room"
        assert {
            "width_m",
            "height_m",
            "depth_m",
            "camera_m",
            "albedo",
            "windows",
            "panels",
            "lamps",
            "outdoor",
        } <= set(env.params)
        json.dumps(env.params)
        assert env.latlong.shape == (3, H, 2 * H) and env.mirror_ball.shape == (3, 32, 32)

    def test_reproducible(self):
        source = IndoorSource(height=H)
        a, b, c = source.sample(gen(4)), source.sample(gen(4)), source.sample(gen(5))
        assert torch.equal(a.latlong, b.latlong) and torch.equal(a.mirror_ball, b.mirror_ball)
        assert a.params == b.params and not torch.equal(a.latlong, c.latlong)
        assert torch.equal(render_room(a.params, H), a.latlong)

    def test_nonnegative_finite_lit_and_energy_into_ball(self):
        source = IndoorSource(height=H)
        for seed in range(5):
            env = source.sample(gen(seed))
            assert bool(env.latlong.isfinite().all())
            y = luminance(env.latlong)
            assert float(y.min()) > 0.0  # no black region: every surface gets direct or ambient light
            assert float(y.median()) > 1e-4 * float(y.max())
            ball = (env.mirror_ball.double() * mirror_ball_solid_angles(32, dtype=F64)).sum((-2, -1))
            torch.testing.assert_close(ball, energy(env.latlong), rtol=1e-4, atol=0)

    def test_emitters_are_brightest(self):
        """Surfaces lit by the room's emitters (not direct-sun patches) are dimmer than its brightest one."""
        d = latlong_directions(H).reshape(-1, 3)
        for seed in range(5):
            params = IndoorSource().sample_params(gen(seed))
            room = _Room(params)
            rgb, ident, _ = room.shade(d)
            y = luminance(rgb, -1)
            emitter = (ident % 100 >= 10) & (ident % 100 < 30)  # panels and window panes
            surface = ~emitter & (ident < 100)  # walls, floor, ceiling, door, frames; not sun patches
            lamps = [
                float(luminance(cct_to_rgb(torch.tensor(lp["cct_k"])), -1))
                * lp["flux_lm"]
                * 1e-3
                / (4 * math.pi * math.pi * lp["radius_m"] ** 2)
                for lp in params["lamps"]
            ]  # sphere radiance I / (pi r^2)
            brightest = max([float(y[emitter].max()) if emitter.any() else 0.0, *lamps])
            assert float(y[surface].max()) < brightest

    def test_coloured_walls(self):
        """Accent walls exist, and a wall's rendered colour follows its albedo."""
        found = 0
        d = latlong_directions(H).reshape(-1, 3)
        for seed in range(40):
            p = IndoorSource().sample_params(gen(seed))
            walls = [p["albedo"][f] for f in (0, 1, 4, 5)]
            chroma = [max(w) / max(min(w), 1e-6) for w in walls]
            if max(chroma) < 3 or min(chroma) > 1.5:
                continue
            found += 1
            p = copy.deepcopy(p)
            p.update(windows=[], door=None)  # plain faces
            rgb, ident, (face, _) = _Room(p).shade(d)
            accent, plain = (0, 1, 4, 5)[chroma.index(max(chroma))], (0, 1, 4, 5)[chroma.index(min(chroma))]
            mean_a, mean_p = (rgb[(face == f) & (ident == 0)].mean(0) for f in (accent, plain))
            ratio = (mean_a / mean_p) / (torch.tensor(p["albedo"][accent]) / torch.tensor(p["albedo"][plain]))
            assert float(ratio.max() / ratio.min()) < 1.3  # same light colour on both walls
            if found == 3:
                break
        assert found >= 2

    def test_panel_energy_matches_its_solid_angle(self):
        for seed in range(3):
            p = black_room(seed)
            w, h, d = p["width_m"], p["height_m"], p["depth_m"]
            x0, z0 = w / 2 - 0.3 + 0.2 * seed, d / 2 - 0.7
            p["panels"] = [
                {"u0": x0, "u1": x0 + 0.6, "v0": z0, "v1": z0 + 1.2, "luminance_kcd_m2": 3.0, "cct_k": 6500.0}
            ]
            corners = torch.tensor(
                [[x0, h, z0], [x0 + 0.6, h, z0], [x0 + 0.6, h, z0 + 1.2], [x0, h, z0 + 1.2]], dtype=F64
            ) - torch.tensor(p["camera_m"], dtype=F64)
            want = 3.0 * cct_to_rgb(torch.tensor(6500.0, dtype=F64)) * rect_solid_angle(corners)
            torch.testing.assert_close(energy(render_room(p, H)), want, rtol=5e-3, atol=0)

    def test_lamp_energy_is_exact(self):
        p = black_room(1)
        cam = p["camera_m"]
        p["lamps"] = [
            {
                "position_m": [cam[0] + 1.5, cam[1] - 0.4, cam[2] + 0.3],
                "radius_m": 0.02,
                "flux_lm": 600.0,
                "cct_k": 2700.0,
            },
            {
                "position_m": [cam[0] - 0.5, cam[1] + 0.2, cam[2] - 0.6],
                "radius_m": 0.15,
                "flux_lm": 300.0,
                "cct_k": 3000.0,
            },
        ]
        want = sum(
            cct_to_rgb(torch.tensor(lp["cct_k"], dtype=F64))
            * lp["flux_lm"]
            * 1e-3
            / (4 * math.pi)
            / sum((a - b) ** 2 for a, b in zip(lp["position_m"], cam, strict=True))
            for lp in p["lamps"]
        )  # I / d^2 each, in klux
        torch.testing.assert_close(energy(render_room(p, H)), want, rtol=1e-5, atol=0)

    def test_sun_through_a_window(self):
        """A window on the wall the sun shines through: sun patches inside, and the sun seen through it."""
        p = IndoorSource().sample_params(gen(2))
        p["outdoor"] = {
            "condition": "clear",
            "sun_azimuth_deg": 0.0,
            "sun_elevation_deg": 12.0,
            "turbidity": 2.5,
            "ground": {"type": "grass", "albedo": [0.08, 0.12, 0.04]},
            "occluders": [],
            "horizon_blur_deg": 1.0,
        }
        w, h = p["width_m"], p["height_m"]
        # the sun (azimuth 0: toward -Z) shines in through the z-low wall (face 4), which spans x and y
        p["windows"] = [
            {
                "face": 4,
                "u0": 0.1,
                "u1": w - 0.1,
                "v0": 0.1,
                "v1": h - 0.1,
                "transmittance": 0.8,
                "panes_u": 1,
                "panes_v": 1,
                "frame_albedo": 0.7,
            }
        ]
        p["yaw_deg"] = 0.0
        p["door"] = None
        p["lamps"] = []
        p["camera_m"] = [w / 2, 1.5, 1.0]  # 1 m from that wall: the sun's ray leaves through the window
        room = _Room(p)
        _, ident, _ = room.shade(latlong_directions(H).reshape(-1, 3))
        assert int((ident >= 100).sum()) > 0  # a sunlit patch
        disks = room.disks()
        assert len(disks) == 1  # the sun, through the glass
        scene_sun = room.outdoor.disks[0][2]
        torch.testing.assert_close(disks[0][2], 0.8 * scene_sun)
        y = luminance(render_room(p, H))
        assert float(y.max()) > 1e3  # the sun through the glass dominates the map

    def test_exception(self):
        with pytest.raises(ValueCheckError, match="height must be positive"):
            IndoorSource(height=0)
        with pytest.raises(TypeCheckError, match="generator must be a torch.Generator, got NoneType"):
            IndoorSource().sample(None)
