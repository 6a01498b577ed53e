r"""Quick looks at synthetic subjects: a Mitsuba 3 render under a key light and a contact sheet.

For eyeballing the subjects of :func:`kornia_ilum.synth.lightstage.make_subject`, not for training data (the
light-stage renderer is :mod:`kornia_ilum.synth.lightstage.olat`). Needs Mitsuba 3 (``pip install mitsuba``).

Convention:
    A pinhole camera on the +Z axis looks at the face (SPEC frame); ``yaw_deg`` turns it about +Y around the
    head (positive moves the camera toward +X). Materials are those of the light stage
    (:func:`kornia_ilum.synth.lightstage.olat.material_bsdf`). Lighting: a dim constant sky, a warm key light
    from the camera's upper left and a cool fill from the right. Output: linear RGB, exposure 1.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from kornia_ilum.synth.lightstage.olat import (
    _import_mitsuba,
    _mitsuba_mesh,
    material_bsdf,
    select_mitsuba_variant,
)
from kornia_ilum.synth.lightstage.subjects import Subject

__all__ = ["contact_sheet", "render_preview"]


def _studio_envmap(height: int = 128) -> np.ndarray:
    """A lat-long studio (Mitsuba's envmap layout, +Y up): sky and floor, a warm key and a cool fill light.

    One emitter, so Mitsuba importance-samples the lights (separate emitters would share the samples).
    Texel ``(i, k)`` looks along ``(sin phi sin theta, cos theta, -cos phi sin theta)``, ``theta = pi i /
    (H - 1)``, ``phi = 2 pi (k + 0.5) / W``; the key (irradiance about 3, 6 degrees wide) comes from the
    camera's upper left and front, the fill (about 0.6, 15 degrees) from the right.
    """
    h, w = height, 2 * height
    theta = (np.pi * np.arange(h) / (h - 1))[:, None]
    phi = (2.0 * np.pi * (np.arange(w) + 0.5) / w)[None, :]
    d = np.stack(
        np.broadcast_arrays(np.sin(phi) * np.sin(theta), np.cos(theta), -np.cos(phi) * np.sin(theta)), -1
    )
    img = np.where(d[..., 1:2] > 0.0, np.array([0.13, 0.14, 0.16]), np.array([0.05, 0.05, 0.05])).astype(
        np.float32
    )
    for src, radius_deg, irradiance in (
        ((-0.55, 0.45, 0.7), 6.0, (3.2, 3.0, 2.7)),
        ((0.8, 0.1, 0.5), 15.0, (0.5, 0.6, 0.75)),
    ):
        src_a = np.array(src) / np.linalg.norm(src)
        cos_r = math.cos(math.radians(radius_deg))
        solid = 2.0 * math.pi * (1.0 - cos_r)
        img += np.where((d @ src_a)[..., None] > cos_r, np.array(irradiance) / solid, 0.0).astype(np.float32)
    return img


def render_preview(
    subject: Subject,
    *,
    size: int = 256,
    yaw_deg: float = 0.0,
    fov_deg: float = 24.0,
    spp: int = 32,
    distance: float = 0.9,
    variant: str | None = None,
) -> np.ndarray:
    """Render ``subject`` (linear RGB, ``(size, size, 3)`` float32, exposure 1) under a key and a fill light.

    Examples:
        >>> from kornia_ilum.synth.lightstage import make_subject
        >>> img = render_preview(make_subject(3), size=32, spp=2)
        >>> img.shape, bool(img.max() > 0.05)
        ((32, 32, 3), True)
    """
    select_mitsuba_variant(variant)
    mi = _import_mitsuba()
    scene: dict = {
        "type": "scene",
        "integrator": {"type": "volpath", "max_depth": 8},
        "env": {"type": "envmap", "bitmap": mi.Bitmap(_studio_envmap())},
    }
    for i, part in enumerate(subject.parts):
        bsdf = material_bsdf(part.material)
        scene[f"part{i}"] = _mitsuba_mesh(mi, part.name, part.vertices, part.faces, part.normals, bsdf)
    yaw = math.radians(yaw_deg)
    target = np.array([0.0, -0.02, 0.02])
    origin = target + distance * np.array([math.sin(yaw), 0.0, math.cos(yaw)])
    scene["sensor"] = {
        "type": "perspective",
        "fov": fov_deg,
        "to_world": mi.ScalarTransform4f().look_at(
            origin=origin.tolist(), target=target.tolist(), up=[0, 1, 0]
        ),
        "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "gaussian"}},
        "sampler": {"type": "independent", "sample_count": spp},
    }
    img = mi.render(mi.load_dict(scene), seed=0)
    return np.asarray(img, dtype=np.float32)[..., :3]


def contact_sheet(
    subjects: Sequence[Subject],
    path: str | Path | None = None,
    *,
    size: int = 256,
    columns: int = 4,
    yaw_deg: float = 20.0,
    spp: int = 256,
    distance: float = 0.7,
) -> np.ndarray:
    """Render subjects into a grid of 8-bit sRGB tiles (three-quarter views turning left and right in turn).

    Args:
        subjects: the subjects, one tile each.
        path: where to save the sheet as a PNG (optimised, lossless); ``None`` only returns it.
        size: the tile size in pixels.
        columns: tiles per row.
        yaw_deg: the camera's turn around the head, alternately positive and negative.
        spp: samples per pixel (256 keeps the PNG small: noise does not compress).
        distance: camera distance (metres) from the face.

    Returns:
        ``(rows * size, columns * size, 3)`` uint8 sRGB.

    Examples:
        >>> from kornia_ilum.synth.lightstage import make_subject
        >>> contact_sheet([make_subject(3)], size=16, columns=2, spp=1).shape
        (16, 32, 3)
    """
    import torch
    from PIL import Image

    from kornia_ilum.color import encode_srgb8

    rows = math.ceil(len(subjects) / columns)
    sheet = np.zeros((rows * size, columns * size, 3), np.uint8)
    for k, s in enumerate(subjects):
        yaw = yaw_deg if k % 2 else -yaw_deg
        lin = torch.from_numpy(render_preview(s, size=size, yaw_deg=yaw, spp=spp, distance=distance))
        r, c = divmod(k, columns)
        sheet[r * size : (r + 1) * size, c * size : (c + 1) * size] = encode_srgb8(lin).numpy()
    if path is not None:
        Image.fromarray(sheet).save(str(path), optimize=True)
    return sheet
