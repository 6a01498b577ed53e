r"""Quick looks at synthetic subjects and at the training portraits of a cache.

:func:`render_preview` and :func:`contact_sheet`: a Mitsuba 3 render of subjects (any source: textured
MakeHuman heads or mannequins) under a studio light, for eyeballing, not for training data (the light-stage
renderer is :mod:`kornia_ilum_lab.synth.lightstage.olat`). Textures: the material's ``albedo_texture`` and
``roughness_texture`` through :func:`~kornia_ilum_lab.synth.lightstage.materials.material_bsdf`, looked up with
the part's ``uvs``; its ``opacity_texture`` (hair cards, brows, lashes) as a Mitsuba ``mask`` BSDF around it.

:func:`compose_portrait` and :func:`training_sheet`: training portraits from cached reflectance fields, made
as the training data is (relit by an environment, composited over the environment seen through the view's
camera, auto-exposed, 8-bit sRGB, cropped to the face box expanded 1.25 x), with their ground-truth spheres;
the sheet's grid is drawn by :func:`kornia_ilum_lab.synth.sheets.write_grid`.

Convention:
    A pinhole camera on the +Z axis looks at the face (docs/conventions.rst, "Frames"); ``yaw_deg`` turns it
    about +Y around the head (positive moves the camera toward +X). Materials are those of the light stage
    (:func:`kornia_ilum_lab.synth.lightstage.materials.material_bsdf`). Lighting: a dim constant sky, a warm key
    light from the camera's upper left and a cool fill from the right. Output: linear RGB, exposure 1.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from kornia_ilum.color import encode_srgb8, gamma_encode
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.detection.crop import CROP_SCALE, crop_faces, square_crop_boxes
from kornia_ilum.filters import soft_clip
from kornia_ilum.geometry import latlong_to_mirror_ball
from kornia_ilum.render import BRDFS, render_spheres
from kornia_ilum_lab.synth.environments import EnvironmentSampler, default_sources
from kornia_ilum_lab.synth.environments.real import HDRFolderSource
from kornia_ilum_lab.synth.lightstage.cache import read_field, read_manifest
from kornia_ilum_lab.synth.lightstage.materials import import_mitsuba, material_bsdf, select_mitsuba_variant
from kornia_ilum_lab.synth.lightstage.portraits import auto_exposure, frame_background, relight_portraits
from kornia_ilum_lab.synth.lightstage.scene import Camera, camera_transform, subject_pivot
from kornia_ilum_lab.synth.lightstage.subjects import Subject
from kornia_ilum_lab.synth.sheets import write_grid

__all__ = ["compose_portrait", "contact_sheet", "preview_bsdf", "render_preview", "training_sheet"]


def _bitmap(data: np.ndarray) -> dict:
    """A raw (linear) bilinear bitmap texture; row 0 of ``data`` is the top of the image (``v = 1``)."""
    mi = import_mitsuba()
    arr = np.ascontiguousarray(data if data.ndim == 3 else data[..., None], dtype=np.float32)
    return {"type": "bitmap", "bitmap": mi.Bitmap(arr), "raw": True}


def _has_bitmap(d: object) -> bool:
    if isinstance(d, dict):
        return d.get("type") == "bitmap" or any(_has_bitmap(v) for v in d.values())
    return False


def preview_bsdf(material, textured: bool = True) -> dict:
    """The Mitsuba BSDF dict of a :class:`~.subjects.Material` with its textures.

    :func:`~kornia_ilum_lab.synth.lightstage.materials.material_bsdf` (which maps ``albedo_texture`` and
    ``roughness_texture``; where it does not, the albedo texture is added here), wrapped in a ``mask`` of the
    ``opacity_texture`` when there is one. ``textured=False`` (a part without ``uvs``) gives the plain BSDF.

    Args:
        material: a subject :class:`~.subjects.Material` (or anything with its attributes).
        textured: whether the part has texture coordinates, so that its textures can be used.

    Returns:
        the BSDF as a dict for ``mitsuba.load_dict``: a ``mask`` around the BSDF of
        :func:`~kornia_ilum_lab.synth.lightstage.materials.material_bsdf` when there is an opacity texture, else
        that BSDF.

    Examples:
        >>> from types import SimpleNamespace
        >>> mat = SimpleNamespace(kind="diffuse", albedo=(0.5, 0.5, 0.5),
        ...                       opacity_texture=np.ones((2, 2), np.float32))
        >>> preview_bsdf(mat)["type"]
        'mask'
    """
    bsdf = material_bsdf(material)
    if not textured:
        return material_bsdf(_untextured(material))
    tex = getattr(material, "albedo_texture", None)
    if tex is not None and not _has_bitmap(bsdf) and bsdf.get("type") == "twosided":
        inner = dict(bsdf["bsdf"])
        key = "reflectance" if inner["type"] == "diffuse" else "base_color"
        inner[key] = _bitmap(np.clip(np.asarray(tex, np.float32), 0.0, 1.0))
        bsdf = {"type": "twosided", "bsdf": inner}
    opacity = getattr(material, "opacity_texture", None)
    if opacity is not None:
        bsdf = {"type": "mask", "opacity": _bitmap(np.clip(np.asarray(opacity, np.float32), 0.0, 1.0)),
                "bsdf": bsdf}
    return bsdf


def _untextured(material):
    if dataclasses.is_dataclass(material):
        return dataclasses.replace(material, albedo_texture=None, opacity_texture=None,
                                   roughness_texture=None)
    return material


def _preview_mesh(mi, part) -> object:
    """A Mitsuba mesh of a :class:`~.subjects.MeshPart`, with its texture coordinates (stored
    ``(u, 1 - v)``)."""
    uvs = getattr(part, "uvs", None)
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(preview_bsdf(part.material, textured=uvs is not None))
    v, f = np.asarray(part.vertices, np.float32), np.asarray(part.faces, np.uint32)
    mesh = mi.Mesh(part.name, vertex_count=len(v), face_count=len(f), has_vertex_normals=True,
                   has_vertex_texcoords=uvs is not None, props=props)
    params = mi.traverse(mesh)
    params["vertex_positions"] = type(params["vertex_positions"])(v.ravel())
    params["faces"] = type(params["faces"])(f.ravel())
    normals = getattr(part, "normals", None)
    if normals is not None:
        params["vertex_normals"] = type(params["vertex_normals"])(np.asarray(normals, np.float32).ravel())
    if uvs is not None:
        uv = np.asarray(uvs, dtype=np.float32).copy()
        uv[:, 1] = 1.0 - uv[:, 1]
        params["vertex_texcoords"] = type(params["vertex_texcoords"])(uv.ravel())
    params.update()
    return mesh


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
    camera: Camera | None = None,
) -> np.ndarray:
    """Render ``subject`` (linear RGB, ``(size, size, 3)`` float32, exposure 1) under a key and a fill light.

    Textured materials show their textures (:func:`preview_bsdf`). With ``camera`` (a light-stage
    :class:`~.scene.Camera`, e.g. of :func:`~.scene.sample_views`) the subject is framed exactly as the light
    stage frames it, and ``size``, ``yaw_deg``, ``fov_deg`` and ``distance`` are ignored.

    Args:
        subject: the subject (:class:`~kornia_ilum_lab.synth.lightstage.Subject`).
        size: the image side in pixels.
        yaw_deg: the camera's turn around the head in degrees (positive moves the camera toward +X).
        fov_deg: the camera's field of view in degrees.
        spp: samples per pixel.
        distance: camera distance (metres) from the face.
        variant: the Mitsuba variant (:func:`~kornia_ilum_lab.synth.lightstage.materials.select_mitsuba_variant`;
            ``None``: the default).
        camera: a light-stage camera, which overrides the four framing arguments.

    Returns:
        ``(size, size, 3)`` float32 linear RGB (``(camera.size, camera.size, 3)`` with ``camera``), exposure 1.

    Examples:
        >>> from kornia_ilum_lab.synth.lightstage import make_subject
        >>> img = render_preview(make_subject(3), size=32, spp=2)
        >>> img.shape, bool(img.max() > 0.05)
        ((32, 32, 3), True)
    """
    select_mitsuba_variant(variant)
    mi = import_mitsuba()
    scene: dict = {
        "type": "scene",
        "integrator": {"type": "volpath", "max_depth": 8},
        "env": {"type": "envmap", "bitmap": mi.Bitmap(_studio_envmap())},
    }
    for i, part in enumerate(subject.parts):
        scene[f"part{i}"] = _preview_mesh(mi, part)
    if camera is not None:
        t = camera_transform(camera, subject_pivot(subject))
        inv = np.linalg.inv(t)  # camera -> subject: the camera sits at the origin looking along -Z
        to_world = mi.ScalarTransform4f(inv.tolist()) @ mi.ScalarTransform4f().scale([-1.0, 1.0, -1.0])
        scene["sensor"] = {
            "type": "perspective", "fov": camera.fov_deg, "fov_axis": "x", "to_world": to_world,
            "film": {"type": "hdrfilm", "width": camera.size, "height": camera.size,
                     "rfilter": {"type": "gaussian"}},
            "sampler": {"type": "independent", "sample_count": spp},
        }
        return np.asarray(mi.render(mi.load_dict(scene), seed=0), dtype=np.float32)[..., :3]
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
        >>> from kornia_ilum_lab.synth.lightstage import make_subject
        >>> contact_sheet([make_subject(3)], size=16, columns=2, spp=1).shape
        (16, 32, 3)
    """
    from PIL import Image  # lazy: Pillow (an optional dependency) is needed only to save a sheet

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


# ----------------------------------------------------------------------------------------------
# training portraits from a cache


def _lighting_for(env, size: int) -> torch.Tensor:
    """The environment's mirror ball at the field's lighting size ``(1, 3, size, size)``."""
    if env.mirror_ball.shape[-1] == size:
        return env.mirror_ball[None].float()
    return latlong_to_mirror_ball(env.latlong[None].float(), size).clamp(min=0.0)


def compose_portrait(field, env, *, key: float = 0.18) -> dict:
    r"""One full-frame training portrait: a cached field relit by ``env`` over its background, 8-bit sRGB.

    Relight (:func:`~kornia_ilum_lab.synth.lightstage.portraits.relight_portraits`), composite over what the
    view's camera sees of the environment (:func:`~kornia_ilum_lab.synth.lightstage.portraits.frame_background`,
    ``I + (1 - alpha) B``), auto-expose (:func:`~kornia_ilum_lab.synth.lightstage.portraits.auto_exposure`, key
    ``key``) metered over the face crop (the face box expanded 1.25 x), as
    :class:`~kornia_ilum_lab.synth.lightstage.portraits.PortraitDataset` meters its crops and as a phone's
    face-priority exposure does, and encode (:func:`~kornia_ilum.color.encode_srgb8`).

    Args:
        field: a :class:`~kornia_ilum_lab.synth.lightstage.ReflectanceField` (dense or compact).
        env: an :class:`~kornia_ilum_lab.synth.environments.Environment` (in the camera frame).
        key: the exposure's target mean.

    Returns:
        a dict: ``"image"`` ``(3, H, W)`` uint8, ``"lighting"`` the ``(3, 32, 32)`` mirror ball in image
        units (times the exposure), ``"gain"`` a float, ``"face_box"`` the ``(4,)`` landmark box.

    Convention:
        Lighting in the camera frame and the units of docs/conventions.rst ("Units of lighting"): times the
        gain, ``"lighting"`` is the ground truth of ``"image"``.

    Examples:
        >>> from kornia_ilum.geometry import mirror_ball_valid
        >>> from kornia_ilum_lab.synth.environments import Environment
        >>> from kornia_ilum_lab.synth.lightstage import ReflectanceField
        >>> rf = ReflectanceField(torch.full((3, 16, 16), 0.05, dtype=torch.bfloat16), torch.ones(1, 4, 4),
        ...                       torch.tensor([1.0, 1.0, 3.0, 3.0]), Camera(30.0, 1.0, 0.0, 0.0, size=4), 7)
        >>> white = Environment(torch.ones(3, 8, 16), mirror_ball_valid(4).float().expand(3, 4, 4), "indoor", "white")
        >>> out = compose_portrait(rf, white)  # the face reads 12 x 0.05 = 0.6, exposed to 0.18
        >>> out["image"].shape, out["image"].dtype, round(out["gain"], 2), out["image"][0, 0, 0].item()
        (torch.Size([3, 4, 4]), torch.uint8, 0.3, 118)
    """
    lighting = _lighting_for(env, field.lighting_size)
    image, alpha = relight_portraits(field, lighting)
    linear = image + (1.0 - alpha) * frame_background(env.latlong[None].float(), field.camera)
    gain = float(auto_exposure(_crop(linear[0], field.face_box, 64)[None].clamp(min=0.0), key)[0])
    return {
        "image": encode_srgb8((linear[0] * gain).clamp(min=0.0)),
        "lighting": env.mirror_ball.float() * gain,
        "gain": gain,
        "face_box": field.face_box.float(),
    }


def _crop(image: torch.Tensor, box: torch.Tensor, size: int) -> torch.Tensor:
    """The square crop (face box expanded 1.25 x) of a ``(3, H, W)`` float image, resized to ``size``."""
    square = square_crop_boxes(box[None].float(), CROP_SCALE)
    return crop_faces(image[None], square, size=size)[0]


def _sphere_strip(lighting: torch.Tensor, side: int) -> torch.Tensor:
    """The diffuse, matte-silver and mirror spheres of ``lighting`` as the loss sees them
    (``softclip(I)^(1/2.2)``), side by side, 3-pixel white gaps."""
    spheres = render_spheres(lighting[None], size=32)
    gap = torch.ones(3, side, 3)
    parts = []
    for brdf in BRDFS:
        s = gamma_encode(soft_clip(spheres[brdf]), 2.2).clamp(0, 1)
        parts += [F.interpolate(s, size=(side, side), mode="area")[0], gap]
    return torch.cat(parts[:-1], -1)


def training_sheet(
    cache_dir: str | Path,
    path: str | Path,
    *,
    count: int = 64,
    split: str | None = "train",
    folder: str | Path | Sequence[str | Path] | None = None,
    seed: int = 0,
    columns: int = 8,
    size: int = 120,
) -> int:
    r"""A PNG of ``count`` training portraits from a cache, each above its ground-truth spheres.

    Portraits as training makes them (:func:`compose_portrait`: relit by a random environment of
    :class:`~kornia_ilum_lab.synth.environments.EnvironmentSampler`, procedural skies and rooms plus the real maps
    of ``folder``, randomly rotated; composited, exposed, 8-bit sRGB), cropped to the face box expanded 1.25 x
    and shown at ``size``; under each, the diffuse, matte-silver and mirror spheres of its lighting in the
    image's units. Fields are taken in a shuffled order (``seed``), cycling when ``count`` exceeds them;
    captions: seed, Monk skin tone, view yaw, environment.

    Args:
        cache_dir: a cache folder (:func:`~kornia_ilum_lab.synth.lightstage.build_cache`).
        path: the PNG to write.
        count: portraits.
        split: ``"train"``, ``"eval"`` or ``None`` (all); falls back to all when the split has no field.
        folder: one or more folders of real HDR maps to add to the environments.
        seed: the environments' and the order's seed.
        columns: portraits per row.
        size: portrait side on the sheet, pixels.

    Returns:
        the number of portraits drawn.

    Raises:
        ValueCheckError: the cache has no field.
        ImportError: matplotlib (needed to draw the sheet) is not installed.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as d:  # an empty folder: no field
        ...     training_sheet(d, f"{d}/sheet.png")  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: the cache ... has no field
        >>> training_sheet("lightstage/", "sheet.png", count=16)  # a cache of kornia-ilum synth  # doctest: +SKIP
        16
    """
    entries = read_manifest(cache_dir)["entries"]
    chosen = [e for e in entries if split is None or e.get("split") == split] or entries
    if not chosen:
        raise ValueCheckError(f"the cache {cache_dir} has no field")
    order = np.random.default_rng(seed).permutation(len(chosen))
    sources = default_sources()
    folders = [] if folder is None else [folder] if isinstance(folder, (str, Path)) else list(folder)
    sources += [HDRFolderSource(f) for f in folders]
    sampler = EnvironmentSampler(sources, seed=seed)
    tiles, captions = [], []
    side = (size - 6) // 3
    for i in range(count):
        entry = chosen[order[i % len(chosen)]]
        field = read_field(Path(cache_dir) / entry["path"], dense=False)
        env = sampler.sample(i)
        out = compose_portrait(field, env)
        portrait = _crop(out["image"].float() / 255.0, out["face_box"], size)
        tile = torch.ones(3, size + 3 + side, size)
        tile[:, :size] = portrait.clamp(0, 1)
        strip = _sphere_strip(out["lighting"], side)
        left = (size - strip.shape[-1]) // 2
        tile[:, size + 3 :, left : left + strip.shape[-1]] = strip
        tiles.append(tile)
        captions.append(f"s{entry['subject_seed']} MST {entry.get('skin_tone')} "
                        f"yaw {entry['camera']['yaw_deg']:+.0f}\n{env.label}: {env.source.split(':')[-1]}")
    title = (f"light-stage training portraits (face crop 1.25 x, shown at {size}) | ground truth: diffuse, "
             "matte silver, mirror")
    cell = (1.45, 1.45 * (size + 3 + side) / size + 0.3)
    write_grid(tiles, captions, title=title, path=path, columns=columns, cell=cell, fontsize=5.5, dpi=100,
               palette=True)
    return count
