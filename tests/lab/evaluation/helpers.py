"""What the evaluation tests share: tiny reflectance fields written down (no Mitsuba) and caches of them."""

from __future__ import annotations

import json
import math
from pathlib import Path

import torch

from kornia_ilum.geometry import mirror_ball_directions, mirror_ball_solid_angles
from kornia_ilum_lab.synth.lightstage import LANDMARK_NAMES, subject_split
from kornia_ilum_lab.synth.lightstage.cache import field_path, write_field
from kornia_ilum_lab.synth.lightstage.field import ReflectanceField
from kornia_ilum_lab.synth.lightstage.scene import Camera

SIZE = 32  # render side of the tiny fields
N = 24  # eval samples in the tests


def tiny_field(seed: int, tone: int) -> ReflectanceField:
    """A grey Lambertian sphere filling a 32 x 32 view, lit by the 32 x 32 mirror-ball basis, with a ring of
    landmarks (no Mitsuba: the field is written down)."""
    c = (torch.arange(SIZE, dtype=torch.float64) + 0.5) / SIZE * 2 - 1
    y, x = torch.meshgrid(-c, c, indexing="ij")
    r2 = x**2 + y**2
    alpha = (r2 <= 0.9).double()
    normals = torch.stack([x, y, (1 - r2).clamp(min=0).sqrt()], -1).reshape(-1, 3)
    d, valid = mirror_ball_directions(32, dtype=torch.float64)
    omega = mirror_ball_solid_angles(32, dtype=torch.float64).flatten()
    cos = (normals @ d.reshape(-1, 3).T).clamp(min=0) * valid.flatten()
    albedo = torch.tensor([0.5, 0.35, 0.3], dtype=torch.float64)[:, None, None] * (1 + 0.1 * seed % 3)
    field = (albedo * (alpha.flatten()[:, None] * cos * omega / math.pi)).to(torch.bfloat16)
    angles = 2 * math.pi * torch.arange(len(LANDMARK_NAMES)) / len(LANDMARK_NAMES)
    landmarks = torch.stack([16 + 8 * angles.cos(), 17 + 9 * angles.sin()], -1)
    meta = {"landmarks": landmarks.tolist(), "split": subject_split(seed), "skin_tone": tone, "lighting_size": 32}
    camera = Camera(fov_deg=40.0, distance=4.0, yaw_deg=0.0, pitch_deg=0.0, size=SIZE)
    return ReflectanceField(field, alpha[None].float(), torch.tensor([8.0, 8.0, 24.0, 26.0]), camera, seed, meta)


def write_cache(out: Path, seeds_tones: list[tuple[int, int]]) -> Path:
    """A light-stage cache folder of :func:`tiny_field` subjects (seed, Monk tone), one view each."""
    entries = []
    for seed, tone in seeds_tones:
        rf = tiny_field(seed, tone)
        path = field_path(seed, 0)
        write_field(out / path, rf)
        entries.append({"subject_seed": seed, "view_index": 0, "path": path, "split": subject_split(seed),
                        "skin_tone": tone})
    (out / "manifest.json").write_text(json.dumps({"format": "kornia_ilum.olat-cache.v2", "entries": entries}))
    return out
