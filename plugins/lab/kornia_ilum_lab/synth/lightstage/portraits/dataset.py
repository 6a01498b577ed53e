r"""The on-the-fly training dataset of portraits: :class:`PortraitConfig` and :class:`PortraitDataset`.

The recipe is in the package docstring (:mod:`kornia_ilum_lab.synth.lightstage.portraits`); the steps are the pure
functions of :mod:`~kornia_ilum_lab.synth.lightstage.portraits.compose` and the camera effects of
:mod:`kornia_ilum_lab.synth.camera_effects`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
from collections import OrderedDict
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from torch.utils.data import IterableDataset, get_worker_info

from kornia_ilum.core.check import check_choice, check_positive_int, trusted
from kornia_ilum.core.errors import TypeCheckError, ValueCheckError
from kornia_ilum.core.seeding import hashed_generator
from kornia_ilum.detection.crop import CROP_SCALE
from kornia_ilum.geometry import flip_lighting_horizontal, latlong_directions, latlong_to_mirror_ball
from kornia_ilum.io import read_hdr
from kornia_ilum.render import SparseField, check_eps
from kornia_ilum_lab.synth.background import camera_rays, latlong_grid, lookup_latlong
from kornia_ilum_lab.synth.camera_effects import LINEAR_RESPONSE_GAMMA, CameraEffects
from kornia_ilum_lab.synth.colour_looks import apply_looks, draw_looks
from kornia_ilum_lab.synth.environments import (
    Environment,
    EnvironmentSampler,
    HDRFolderSource,
    IndoorSource,
    SkySource,
    render_outdoor,
    render_room,
    resize_latlong,
)
from kornia_ilum_lab.synth.lightstage.cache import read_field, read_manifest
from kornia_ilum_lab.synth.lightstage.field import ReflectanceField
from kornia_ilum_lab.synth.lightstage.portraits.compose import (
    add_relit,
    aspect_windows,
    auto_exposure,
    background_pyramid,
    crop_images,
    detector_boxes,
    face_crop_boxes,
    frame_backgrounds,
    inner_crop_boxes,
    random_crop_boxes,
    sphere_targets,
    uniform_draws,
)
from kornia_ilum_lab.synth.lightstage.sparse import read_sparse
from kornia_ilum_lab.synth.surroundings import (
    Surroundings,
    draw_backdrops,
    draw_surroundings,
    surroundings_view,
    with_surroundings,
)

__all__ = ["MAX_WORKERS", "PortraitConfig", "PortraitDataset", "environment_background", "load_fields"]

#: Workers per dataset at most: worker ``w`` draws environment ``j`` of its own stream as the sampler's index
#: ``j * MAX_WORKERS + w``, so workers never draw the same environment.
MAX_WORKERS = 1024


@functools.lru_cache(maxsize=16)
def _camera_rays(size: int, fov_deg: float) -> torch.Tensor:
    """The rays of an unrotated square camera (:func:`~kornia_ilum_lab.synth.background.camera_rays`), cached
    per view's camera as :func:`frame_backgrounds` caches its lookups (read only)."""
    return camera_rays((size, size), fov_deg, torch.eye(3, dtype=torch.float64))


def _paint_surroundings(frame: torch.Tensor, far: torch.Tensor, rooms: Sequence[Surroundings | None],
                        camera: Any) -> None:
    """Put the near surfaces of ``rooms`` into the backgrounds ``frame (B, 3, S, S)``, in place, where the
    camera's rays meet them (lit by the far environments ``far``); the planes are symmetric left-right, so a
    mirrored background sees them where an unmirrored one does."""
    if all(r is None for r in rooms):
        return
    rays = _camera_rays(camera.size, float(camera.fov_deg))
    for j, room in enumerate(rooms):
        if room is not None:
            mask, radiance = surroundings_view(far[j], room, rays, float(camera.distance))
            frame[j] = torch.where(mask, radiance.to(frame), frame[j])


def _generator(seed: int, *key: int) -> torch.Generator:
    return hashed_generator("kornia_ilum.portraits:" + ":".join(str(int(k)) for k in (seed, *key)))


def _pair(value: Any, name: str, lo: float, strict: bool = False) -> tuple[float, float]:
    if not (isinstance(value, (tuple, list)) and len(value) == 2):
        raise TypeCheckError(f"{name} must be a pair (low, high), got {value!r}")
    a, b = (float(v) for v in value)
    if not (math.isfinite(a) and math.isfinite(b) and (a > lo if strict else a >= lo) and a <= b):
        raise ValueCheckError(f"{name} must be an increasing pair of {'positive' if strict else 'non-negative'} "
                              f"numbers, got {value!r}")
    return a, b


def _probability(value: Any, name: str) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 <= value <= 1.0:
        raise ValueCheckError(f"{name} must be in [0, 1], got {value!r}")


@dataclass(frozen=True)
class PortraitConfig:
    r"""Everything :class:`PortraitDataset` draws and how (vary with :func:`dataclasses.replace`).

    Args:
        split: the subjects to use (``"train"``, ``"eval"`` or ``None`` for all).
        environments: the environment sampler; ``None``: :class:`~kornia_ilum_lab.synth.environments.EnvironmentSampler`
            with its procedural sources and the dataset's seed.
        size: the output side (256).
        background: ``"environment"`` (the matching background) or ``"black"`` (as SIPR was trained).
        crop: ``"face"`` (the jittered face crop) or ``"random"`` (:func:`random_crop_boxes`, missing the face).
        subject: ``False`` renders the background alone (no face), framed as with the subject.
        pairs: also render each sample's subject, view, crop and flip under a second lighting, as
            ``sample["pair"]``, and give the subject's matte in the crop, ``sample["alpha"]`` (for SIPR: a
            relit target and the mask of its loss).
        matte: give the subject's matte in the crop, ``sample["alpha"]``, without a second lighting (what the
            evaluation's transfer check composites the face over black and grey with); it draws nothing, so
            every other field of a sample is the same, bit for bit, with and without it.
        plain_background: the fraction of samples whose background is a plain backdrop instead of the
            environment's (training sets it: the model then has to read the light from the face, not from what is
            behind it): a matte wall lit by the same environment, behind the subject and filling the frame
            (:func:`~kornia_ilum_lab.synth.surroundings.draw_backdrops`), its brightness the light's times its
            own albedo; it is in the lighting and the lighting target as a wall of ``surroundings`` is, and
            replaces the sample's surroundings and companion. Drawn from a stream of its own, so every other
            sample is what it was without the option; ``sample["plain"]`` says which.
        plain_albedo: the range of the backdrop's grey albedo (log-uniform; black velvet to white paper).
        second_crop: also give a second, jittered crop of each sample's face as a box inside its crop,
            ``sample["second_crop"]`` ``(4,)`` in the crop's pixels (:func:`inner_crop_boxes` with
            ``crop_position`` and ``crop_extent``; training's crop-consistency term cuts it,
            :attr:`~kornia_ilum_lab.train.TrainConfig.lambda_crop`). Drawn last and only when asked for, so every
            other field of a sample is what it was without it.
        colour_looks: the fraction of samples whose photo goes through a random colour look after the camera
            (:func:`~kornia_ilum_lab.synth.colour_looks.draw_looks`: greyscale, desaturated, a toned black and
            white or a colour grade), with the lighting target changed as the look changes the photo's units
            (:func:`~kornia_ilum_lab.synth.colour_looks.apply_looks`; ``sample["look"]`` is the look's kind, 0
            for none): where the light comes from must then be read from the shading, not from the colours.
            Drawn last and only when positive, so at 0 every sample is what it was without the option.
        linear_response: the fraction of samples taken by a camera with a linear response (machine-vision and
            scientific cameras, raw dumps: codes proportional to the light, no tone curve, no highlight roll-off;
            the camera of the real-flash photographs is one): their tone curve undoes the sRGB curve
            (:data:`~kornia_ilum_lab.synth.camera_effects.LINEAR_RESPONSE_GAMMA`) and their roll-off is off.
            Drawn from a stream of its own, so every other draw of a sample is what it was without the option.
        surroundings: the fraction of samples with near surfaces lit by the same environment, a wall behind the
            subject and a floor or table below (:func:`~kornia_ilum_lab.synth.surroundings.draw_surroundings`):
            the subject is relit, and the lighting target is, the environment with them in it
            (:func:`~kornia_ilum_lab.synth.surroundings.with_surroundings`), and the frame's background shows
            them where the camera sees them (:func:`~kornia_ilum_lab.synth.surroundings.surroundings_view`); not
            with a plain backdrop. ``sample["surroundings"]`` says which. Drawn from a stream of its own, so
            every other draw of a sample is what it was without the option.
        companions: the fraction of samples with a second person in the frame beside the subject (a group
            photo: FAIR's design of several people under one light): another subject-view of the set, relit by
            the same lighting, at the same distance, standing 0.3 to 0.5 m to the subject's side (centre to
            centre, as people stand in a group photo), behind the subject where they overlap: at the light stage's
            tight framing (the face half the frame's height) the companion is at the frame's edge; wider views
            (``kornia-ilum synth subjects --face-fraction``) show them whole. The lighting target stays the
            environment's (the companion's shadow on the subject and the light they block are left out). Not
            with a plain backdrop; ``sample["companion"]`` says which.
            Drawn from a stream of its own, so every other draw of a sample is what it was without the option.
        frame: also give the whole rendered frame around each sample's crop, shrunk to ``frame`` pixels a side
            (area-averaged), exposed by the crop's exposure and through the same camera without its per-pixel
            effects (no sensor noise, lens blur or JPEG, which the shrinking averages away), mirrored and with the
            colour look as the crop: ``sample["frame"]`` ``(3, frame, frame)`` uint8 sRGB codes and
            ``sample["frame_box"]`` ``(4,)``, the face box in its pixels (the scene branch's input,
            :func:`kornia_ilum.estimators.scene.scene_input`), and ``sample["frame_window"]`` ``(4,)``, a window
            of a common photo's aspect around the face (:func:`aspect_windows`: what a photo of that shape would
            show; training's scene branch reads it). Its draws are a stream of its own: 0 (off) or not, every
            other field of a sample is the same, bit for bit.
        flip_probability: the fraction of samples mirrored left-right.
        crop_scale, crop_position, crop_extent: the face crop's expansion and jitter (:func:`face_crop_boxes`).
        exposure_key: the range of the auto-exposure's key (log-uniform).
        camera: the phone-camera effects (:class:`~kornia_ilum_lab.synth.camera_effects.CameraEffects`: lens blur,
            vignette, sensor noise, tone curve, JPEG); :meth:`CameraEffects.off` for the plain sRGB encoding
            without noise.
        background_height: the height of the real maps' backgrounds (their files are read at full resolution,
            and shrunk by area averaging if taller); ``None``: the files' own.
        procedural_background_height: the height at which procedural skies are rendered again for their
            backgrounds (their lighting uses the sampler's maps); at most the sampler's height turns it off.
        room_background_height: the same for procedural rooms; by default the sampler's 128 rows (off): a room
            costs several times a sky to render at 256 rows, more per sample (at one new environment per chunk
            of 64) than the data rate can afford (docs/lightstage.rst, "Measured").
        background_sharp_probability: the fraction of backgrounds without depth of field.
        background_blur: the range of the depth of field's Gaussian (uniform, pixels of the rendered frame) for
            the others (:func:`frame_backgrounds`).
        sphere_sizes: the sizes of the sphere targets.
        fields_per_chunk, lightings_per_field, env_pool, env_refresh: the batching (:class:`PortraitDataset`).
        shuffle: iteration shuffles the samples of every ``shuffle`` consecutive chunks together, so a batch of
            a data loader mixes ``shuffle * fields_per_chunk`` subject-views.
        length: samples per worker and pass (``None``: endless).
        relight_eps: ``0`` relights exactly (the dense product); above 0, sparsely
            (:func:`~kornia_ilum.render.relight_sparse`: the lights carrying more than this fraction of an image's
            energy exactly, the rest through the field at a low rank), from the fields' sidecars
            (:func:`~kornia_ilum_lab.synth.lightstage.write_sparse_cache`): faster, within about 1 % of ``L_rec`` on
            sunny maps (docs/skipping.rst). Needs fields loaded from a cache folder.

    Examples:
        >>> config = dataclasses.replace(PortraitConfig(), size=128, camera=CameraEffects.off())
        >>> config.size, config.camera.jpeg_p
        (128, 0.0)
    """

    split: str | None = "train"
    environments: EnvironmentSampler | None = None
    size: int = 256
    background: str = "environment"
    crop: str = "face"
    subject: bool = True
    pairs: bool = False
    matte: bool = False
    plain_background: float = 0.0
    plain_albedo: tuple[float, float] = (0.02, 0.9)
    second_crop: bool = False
    colour_looks: float = 0.0
    linear_response: float = 0.0
    surroundings: float = 0.0
    companions: float = 0.0
    frame: int = 0
    flip_probability: float = 0.5
    crop_scale: float = CROP_SCALE
    crop_position: float = 0.06
    crop_extent: float = 0.15
    exposure_key: tuple[float, float] = (0.1, 0.3)
    camera: CameraEffects = CameraEffects()  # noqa: RUF009 - frozen, so shared safely
    background_height: int | None = 512
    procedural_background_height: int = 256
    room_background_height: int = 128
    background_sharp_probability: float = 0.3
    background_blur: tuple[float, float] = (0.0, 8.0)
    sphere_sizes: tuple[int, ...] = (4, 8, 16, 32)
    fields_per_chunk: int = 4
    lightings_per_field: int = 16
    env_pool: int = 32
    env_refresh: int = 1
    shuffle: int = 4
    length: int | None = None
    relight_eps: float = 0.0

    def __post_init__(self) -> None:
        if self.split not in (None, "train", "eval"):
            raise ValueCheckError(f"split must be 'train', 'eval' or None, got {self.split!r}")
        if self.environments is not None and not isinstance(self.environments, EnvironmentSampler):
            raise TypeCheckError(
                f"environments must be an EnvironmentSampler, got {type(self.environments).__name__}"
            )
        if not isinstance(self.camera, CameraEffects):
            raise TypeCheckError(f"camera must be a CameraEffects, got {type(self.camera).__name__}")
        check_choice(self.background, "background", ("environment", "black"))
        check_choice(self.crop, "crop", ("face", "random"))
        for name in ("size", "fields_per_chunk", "lightings_per_field", "env_pool", "env_refresh", "shuffle",
                     "procedural_background_height", "room_background_height"):
            check_positive_int(getattr(self, name), name)
        for name in ("length", "background_height"):
            if getattr(self, name) is not None:
                check_positive_int(getattr(self, name), name)
        check_eps(self.relight_eps, "relight_eps")
        if self.env_refresh > self.env_pool:
            raise ValueCheckError(f"env_refresh ({self.env_refresh}) must not exceed env_pool ({self.env_pool})")
        _probability(self.flip_probability, "flip_probability")
        _probability(self.background_sharp_probability, "background_sharp_probability")
        _probability(self.plain_background, "plain_background")
        _probability(self.colour_looks, "colour_looks")
        _probability(self.linear_response, "linear_response")
        _probability(self.surroundings, "surroundings")
        _probability(self.companions, "companions")
        if isinstance(self.frame, bool) or not isinstance(self.frame, int) or self.frame < 0:
            raise ValueCheckError(f"frame must be a non-negative int (0: off), got {self.frame!r}")
        _pair(self.plain_albedo, "plain_albedo", 0.0, strict=True)
        if self.plain_albedo[1] > 0.9:
            raise ValueCheckError(f"plain_albedo must be at most 0.9, got {self.plain_albedo!r}")
        object.__setattr__(self, "plain_albedo", tuple(float(v) for v in self.plain_albedo))
        _pair(self.exposure_key, "exposure_key", 0.0, strict=True)
        _pair(self.background_blur, "background_blur", 0.0)
        if not (self.crop_scale > 0 and self.crop_position >= 0 and self.crop_extent >= 0):
            raise ValueCheckError("crop_scale must be positive, crop_position and crop_extent non-negative")
        object.__setattr__(self, "sphere_sizes", tuple(int(s) for s in self.sphere_sizes))
        object.__setattr__(self, "exposure_key", tuple(float(v) for v in self.exposure_key))
        object.__setattr__(self, "background_blur", tuple(float(v) for v in self.background_blur))


def load_fields(source: str | os.PathLike | Sequence[ReflectanceField], split: str | None = None
                ) -> list[ReflectanceField]:
    r"""Reflectance fields from a cache folder (:func:`~kornia_ilum_lab.synth.lightstage.build_cache`) or a list.

    Args:
        source: a cache folder (its manifest's entries, sorted by seed and view, in the compact layout and
            memory-mapped: :func:`~kornia_ilum_lab.synth.lightstage.read_field` with ``mmap=True``) or a sequence
            of :class:`~kornia_ilum_lab.synth.lightstage.ReflectanceField`.
        split: keep only the subjects of this split (``"train"`` or ``"eval"``,
            :func:`~kornia_ilum_lab.synth.lightstage.subject_split`); ``None``: all.

    Returns:
        the fields of ``split``, in the cache's order (or the sequence's).

    Raises:
        ValueCheckError: no field is left, fields of different lighting sizes, or an unknown split.

    Examples:
        >>> from kornia_ilum_lab.synth.lightstage.scene import Camera
        >>> rf = ReflectanceField(torch.zeros(3, 4, 16, dtype=torch.bfloat16), torch.ones(1, 2, 2),
        ...                       torch.tensor([0.0, 0.0, 2.0, 2.0]), Camera(30.0, 1.0, 0.0, 0.0, size=2), 1,
        ...                       {"landmarks": [[1.0, 1.0, 0.0]], "split": "eval"})
        >>> [f.subject_seed for f in load_fields([rf], split="eval")]
        [1]
        >>> fields = load_fields("lightstage/", split="train")  # a cache built by kornia-ilum synth  # doctest: +SKIP
    """
    if split not in (None, "train", "eval"):
        raise ValueCheckError(f"split must be 'train', 'eval' or None, got {split!r}")
    if isinstance(source, (str, os.PathLike)):
        entries = read_manifest(source)["entries"]
        entries = [e for e in entries if split is None or e.get("split") == split]
        fields = [read_field(Path(source) / e["path"], dense=False, mmap=True) for e in entries]
        for f, e in zip(fields, entries, strict=True):
            f.meta.setdefault("view_index", e["view_index"])
            f.meta.setdefault("path", str(Path(source) / e["path"]))  # where its sparse sidecar lies
    else:
        fields = list(source)
        if not all(isinstance(f, ReflectanceField) for f in fields):
            raise TypeCheckError("source must be a cache folder or a sequence of ReflectanceField")
        fields = [f for f in fields if split is None or f.meta.get("split") == split]
    if not fields:
        raise ValueCheckError(f"no reflectance field in {source!r} for split {split!r}")
    if len({f.lighting_size for f in fields}) != 1:
        raise ValueCheckError("all fields must share one lighting size")
    if any("landmarks" not in f.meta for f in fields):
        raise ValueCheckError("every field needs meta['landmarks'] (rendered by render_olat)")
    return fields




@functools.lru_cache(maxsize=4)
def _latlong_directions(rows: int) -> torch.Tensor:
    return latlong_directions(rows, dtype=torch.float64)


@functools.lru_cache(maxsize=16)
def _read_full(path: str, height: int | None) -> torch.Tensor:
    image = read_hdr(path).float()
    if height is not None and image.shape[-2] > height:
        image = resize_latlong(image, height)
    return image


def _background_source(
    env: Environment,
    sampler: EnvironmentSampler,
    *,
    height: int | None,
    procedural_height: int,
    room_height: int | None,
) -> tuple[torch.Tensor, torch.Tensor | None, torch.Tensor | None]:
    """:func:`environment_background` before the augmentation: ``(map, M, gains)``, float32 (``M`` float64); the
    map is ``env.latlong`` itself (already augmented) with ``M`` and ``gains`` ``None`` when nothing is finer."""
    params = env.params
    k = params.get("sampler", {}).get("source")
    source = sampler.sources[k] if isinstance(k, int) and 0 <= k < len(sampler.sources) else None
    rows = env.latlong.shape[-2]
    full = None
    if isinstance(source, HDRFolderSource) and "map" in params and (height is None or height > rows):
        full = _read_full(str(source.folder / params["map"]), height)
    elif isinstance(source, SkySource) and procedural_height > rows:
        full = render_outdoor(params, procedural_height)
    elif isinstance(source, IndoorSource) and (room_height or procedural_height) > rows:
        full = render_room(params, room_height or procedural_height)
    if full is None or full.shape[-2] <= rows:
        return env.latlong.float(), None, None
    augment = params.get("augment")
    if augment is None:
        return full.float(), None, None
    return (full.float(), torch.tensor(augment["direction_map"], dtype=torch.float64),
            torch.tensor(augment["gains"], dtype=torch.float32))


def environment_background(
    env: Environment,
    sampler: EnvironmentSampler,
    *,
    height: int | None = 512,
    procedural_height: int = 256,
    room_height: int | None = None,
) -> torch.Tensor:
    r"""The environment's lat-long map at a background's resolution, in its (augmented) camera frame.

    An environment's ``latlong`` is at the sampler's working height (128 rows, 1.4 degrees a pixel), enough
    for lighting but blurrier than the frame's pixels (0.1 to 0.3 degrees at 192 to 256 pixels and 25 to 70
    degrees of field of view). This goes back to its source: a real map
    (:class:`~kornia_ilum_lab.synth.environments.HDRFolderSource`) is read again at its file's resolution (1024 x
    512 for the shared maps; shrunk to ``height`` rows when taller), a procedural sky or room is rendered again
    from its parameters at ``procedural_height`` rows; then the sampler's augmentation (rotation, flip,
    exposure and white balance, ``params["augment"]``) is applied by a bilinear lookup of every pixel's
    direction (a picture, not lighting: no energy bookkeeping needed). Other sources, and heights not above the
    working height, give ``env.latlong`` itself.

    :class:`PortraitDataset` does not resample the whole map (costly at 512 rows): it keeps the source map,
    applies the gains to its :func:`background_pyramid` and folds the rotation into the frame's lookup
    (``rotation`` of :func:`frame_backgrounds`), which sees the same background up to interpolation.

    Args:
        env: an environment drawn by ``sampler`` (``params["sampler"]`` names its source).
        sampler: the sampler that drew it.
        height: the most rows of a real map (``None``: the file's own).
        procedural_height: the rows of a procedural environment's background.
        room_height: the rows of a procedural room's background (``None``: ``procedural_height``).

    Returns:
        ``(3, H, 2H)`` float32 linear.

    Convention:
        Lat-long grid and camera frame of docs/conventions.rst; the units of the environment's lighting.

    Examples:
        >>> sampler = EnvironmentSampler([SkySource(height=16)], augment=None)
        >>> env = sampler.sample(0)  # a procedural sky of 16 rows
        >>> environment_background(env, sampler, procedural_height=32).shape  # rendered again at 32 rows
        torch.Size([3, 32, 64])
        >>> environment_background(env, sampler, procedural_height=8) is env.latlong  # not above: itself
        True
    """
    full, m, gains = _background_source(env, sampler, height=height, procedural_height=procedural_height,
                                        room_height=room_height)
    if m is None or gains is None:
        return full
    h = full.shape[-2]
    grid = latlong_grid(_latlong_directions(h) @ m, h).float()  # A(r) = g L(M^T r); (M^T r)^T = r^T M
    return (lookup_latlong(full[None], grid[None])[0] * gains[:, None, None]).clamp_(min=0.0)


def _source_boxes(boxes: torch.Tensor, flip: torch.Tensor, size: int) -> torch.Tensor:
    """Crop boxes given in the mirrored image (where ``flip``) as boxes of the unmirrored ``size`` render."""
    source = boxes.clone()
    source[flip, 0], source[flip, 2] = size - boxes[flip, 2], size - boxes[flip, 0]
    return source


class PortraitDataset(IterableDataset):
    r"""Training portraits synthesised on the fly from cached reflectance fields (package docstring).

    Iteration yields sample dicts, deterministically per ``(seed, worker)``: worker ``w`` of a
    :class:`~torch.utils.data.DataLoader` yields the samples of :meth:`chunk` ``(w, 0)``, ``(w, 1)``, ... (without
    workers, ``w = 0``), shuffled within groups of ``config.shuffle`` chunks. A chunk takes
    ``fields_per_chunk`` fields at random and relights each with ``lightings_per_field`` lightings in one batched
    product. Lightings come from a pool of the last ``env_pool`` environments of the worker's stream,
    ``env_refresh`` of them new at every chunk, each used with a random rotation about the vertical axis (a
    whole number of lat-long columns, exact; the background turns with it; none for an environment whose
    lights are placed relative to the camera, ``params["camera_anchored"]``). Each environment of the pool keeps
    a full-resolution background (:func:`environment_background`, :func:`background_pyramid`): 3 to 8 MB per
    environment at 256 to 512 rows, so up to ``(env_pool + env_refresh)`` times that per worker.

    Args:
        fields: a cache folder or a list of fields (:func:`load_fields`).
        config: the settings (:class:`PortraitConfig`); default ``PortraitConfig()``.
        seed: the seed of everything random.
        **overrides: fields of :class:`PortraitConfig` to replace (``dataclasses.replace(config, **overrides)``).

    Sample keys:
        ``image`` ``(3, size, size)`` ``uint8`` sRGB codes (after the camera effects); ``mirror_ball``
        ``(3, S, S)`` linear lighting in image units, camera frame; ``spheres`` ``{f"{brdf}_{s}": (3, s, s)}``
        (:func:`sphere_targets`); ``exposure`` (the gain applied to the HDR render and to ``mirror_ball``);
        ``crop_box`` and ``face_box`` ``(4,)`` in the render's pixels (after the flip); ``subject_seed``,
        ``skin_tone``, ``view_index``, ``flip``; ``label`` (``"indoor"``/``"outdoor"``) and ``source`` of the
        environment; ``background_blur`` (the depth of field's sigma, frame pixels); ``camera`` (the effects'
        parameters: ``blur``, ``vignette``, ``noise``, ``jpeg`` and ``tone`` ``(2,)``, identity values where off);
        ``chunk`` ``(worker, index)``; with ``pairs``, ``pair`` holds ``image``, ``mirror_ball``, ``spheres``,
        ``exposure``, ``label``, ``source``, ``background_blur`` and ``camera`` of the second lighting; with
        ``pairs`` or ``matte``, ``alpha`` ``(1, size, size)`` ``uint8`` is the subject's coverage of each crop
        pixel (255: subject); with ``second_crop``, ``second_crop`` ``(4,)`` (a box in the crop's pixels).

    Examples:
        >>> from kornia_ilum_lab.synth.lightstage.scene import Camera
        >>> rf = ReflectanceField(torch.ones(3, 16, 64, dtype=torch.bfloat16) / 64, torch.ones(1, 4, 4),
        ...                       torch.tensor([1.0, 1.0, 3.0, 3.0]), Camera(30.0, 1.0, 0.0, 0.0, size=4), 7,
        ...                       {"landmarks": [[1.0 + i % 3, 1.0 + i % 2] for i in range(20)]})
        >>> config = PortraitConfig(split=None, size=16, sphere_sizes=(4, 8), env_pool=2, env_refresh=1,
        ...                         lightings_per_field=2, shuffle=1, length=3)
        >>> samples = list(PortraitDataset([rf], config))
        >>> len(samples), tuple(samples[0]["image"].shape), tuple(samples[0]["mirror_ball"].shape)
        (3, (3, 16, 16), (3, 8, 8))
    """

    def __init__(
        self,
        fields: str | os.PathLike | Sequence[ReflectanceField],
        config: PortraitConfig | None = None,
        seed: int = 0,
        **overrides: Any,
    ) -> None:
        super().__init__()
        if config is None:
            config = PortraitConfig()
        if not isinstance(config, PortraitConfig):
            raise TypeCheckError(f"config must be a PortraitConfig, got {type(config).__name__}")
        if overrides:
            config = dataclasses.replace(config, **overrides)
        if isinstance(seed, bool) or not isinstance(seed, int):
            raise TypeCheckError(f"seed must be an int, got {type(seed).__name__}")
        self.fields = load_fields(fields, config.split)
        self.lighting_size = self.fields[0].lighting_size
        if any(s > self.lighting_size for s in config.sphere_sizes):
            raise ValueCheckError(
                f"sphere_sizes {config.sphere_sizes} exceed the lighting size {self.lighting_size}"
            )
        self.environments = EnvironmentSampler(seed=seed) if config.environments is None else config.environments
        self.config = config
        self.seed = seed
        self.length = config.length
        self.shuffle = config.shuffle
        self._envs: OrderedDict[int, Environment] = OrderedDict()
        self._backgrounds: OrderedDict[int, tuple[tuple[torch.Tensor, ...], torch.Tensor]] = OrderedDict()
        self._noise_bank: torch.Tensor | None = None
        self._sparse: dict[str, SparseField] = {}  # the fields' sparse sidecars, mapped once per process
        if config.relight_eps > 0 and not all("path" in f.meta for f in self.fields):
            raise ValueCheckError("relight_eps > 0 needs fields loaded from a cache folder (their sparse sidecars "
                                  "lie beside them: write_sparse_cache)")

    def __getstate__(self) -> dict[str, Any]:  # workers start with empty caches
        state = self.__dict__.copy()
        state["_envs"], state["_backgrounds"], state["_noise_bank"] = OrderedDict(), OrderedDict(), None
        state["_sparse"] = {}
        return state

    def _sparse_of(self, rf: ReflectanceField) -> SparseField | None:
        """The field's sparse sidecar where ``relight_eps > 0`` (mapped on first use), else ``None``."""
        if self.config.relight_eps == 0:
            return None
        path = rf.meta["path"]
        if path not in self._sparse:
            self._sparse[path] = read_sparse(path)
        return self._sparse[path]

    def __repr__(self) -> str:
        subjects = len({f.subject_seed for f in self.fields})
        changed = {f.name: getattr(self.config, f.name) for f in dataclasses.fields(PortraitConfig)
                   if f.name != "environments" and getattr(self.config, f.name) != f.default}
        return (f"PortraitDataset({len(self.fields)} fields of {subjects} subjects, seed={self.seed}, "
                f"{', '.join(f'{k}={v}' for k, v in changed.items()) or 'default config'})")

    def __iter__(self) -> Iterator[dict[str, Any]]:
        info = get_worker_info()
        worker = 0 if info is None else info.id
        if worker >= MAX_WORKERS:
            raise ValueCheckError(f"at most {MAX_WORKERS} workers, got worker {worker}")
        for count, sample in enumerate(self.samples(worker)):
            if self.length is not None and count >= self.length:
                return
            yield sample

    def samples(self, worker: int, start: int = 0) -> Iterator[dict[str, Any]]:
        """The endless sample stream of ``worker`` (what iteration yields, ignoring ``length``) from sample
        ``start`` on; only the group of chunks that ``start`` falls in is made again (training resumes here)."""
        cfg = self.config
        per_group = self.shuffle * cfg.fields_per_chunk * cfg.lightings_per_field
        group, skip = divmod(int(start), per_group)
        while True:
            samples = [s for index in range(group * self.shuffle, (group + 1) * self.shuffle)
                       for s in self.chunk(worker, index)]
            order = torch.randperm(len(samples), generator=_generator(self.seed, worker, group, -2)).tolist()
            for k in order[skip:]:
                yield samples[k]
            skip = 0
            group += 1

    def _environment(self, worker: int, j: int) -> tuple[int, Environment]:
        key = j * MAX_WORKERS + worker
        env = self._envs.get(key)
        if env is None:
            env = self.environments.sample(key)
            self._envs[key] = env
            while len(self._envs) > 2 * self.config.env_pool:
                self._envs.popitem(last=False)
        return key, env

    def _background(self, key: int, env: Environment) -> tuple[tuple[torch.Tensor, ...], torch.Tensor]:
        """The background pyramid of environment ``key`` and its direction map ``(3, 3)`` (cached for the pool's
        environments).

        The pyramid is that of the source map (:func:`environment_background` before the augmentation) times the
        augmentation's gains (on the pyramid's levels: a third fewer values than the 64 frames that use it); the
        augmentation's rotation is left to the frame's lookup (:func:`frame_backgrounds`).
        """
        entry = self._backgrounds.get(key)
        if entry is None:
            cfg = self.config
            latlong, m, gains = _background_source(env, self.environments, height=cfg.background_height,
                                                   procedural_height=cfg.procedural_background_height,
                                                   room_height=cfg.room_background_height)
            pyramid = background_pyramid(latlong)  # new tensors: scaled in place
            if gains is not None:
                for level in pyramid:
                    level.mul_(gains[:, None, None])
            entry = pyramid, torch.eye(3, dtype=torch.float64) if m is None else m
            self._backgrounds[key] = entry
            while len(self._backgrounds) > cfg.env_pool + cfg.env_refresh:
                self._backgrounds.popitem(last=False)
        else:
            self._backgrounds.move_to_end(key)
        return entry

    def _lightings(self, worker: int, index: int, n: int, g: torch.Generator
                   ) -> tuple[torch.Tensor, list[Environment], list[int], torch.Tensor]:
        """``n`` lat-long maps from the pool of chunk ``index``, each turned by a random whole column count;
        their environments, keys and turns (fractions of a turn)."""
        pool, refresh = self.config.env_pool, self.config.env_refresh
        last = (index + 1) * refresh
        window = list(range(max(0, last - pool), last))
        picks = torch.randint(len(window), (n,), generator=g).tolist()
        keyed = [self._environment(worker, window[p]) for p in picks]
        keys, envs = [k for k, _ in keyed], [e for _, e in keyed]
        width = envs[0].latlong.shape[-1]
        shifts = torch.randint(width, (n,), generator=g).tolist()
        # lights placed relative to the camera (the portrait lights' flash, studio and window) are not turned
        shifts = [0 if e.params.get("camera_anchored") else k for e, k in zip(envs, shifts, strict=True)]
        latlongs = torch.empty(n, *envs[0].latlong.shape)
        for out, env, k in zip(latlongs, envs, shifts, strict=True):  # out = env.latlong.roll(k, dims=-1)
            x = env.latlong.float()
            torch.cat([x[..., width - k :], x[..., : width - k]], -1, out=out)  # two block copies
        return latlongs, envs, keys, torch.tensor(shifts, dtype=torch.float64) / width

    def chunk(self, worker: int, index: int) -> list[dict[str, Any]]:
        """The samples of chunk ``index`` of ``worker``: a pure function of ``(seed, worker, index)``."""
        with trusted():  # no value scans: its inputs are the loaded fields and the sampler's checked environments
            return self._chunk(worker, index)

    def _chunk(self, worker: int, index: int) -> list[dict[str, Any]]:
        cfg = self.config
        g = _generator(self.seed, worker, index)
        nf, nl = cfg.fields_per_chunk, cfg.lightings_per_field
        n = nf * nl
        field_ids = torch.randint(len(self.fields), (nf,), generator=g).tolist()
        flips = torch.rand(n, generator=g) < cfg.flip_probability
        lightings = [self._lightings(worker, index, n, g) for _ in range(2 if cfg.pairs else 1)]
        keys = [torch.exp(uniform_draws(n, *map(math.log, cfg.exposure_key), g)) for _ in lightings]
        blurs = []
        for _ in lightings:
            sharp = torch.rand(n, generator=g, dtype=torch.float64) < cfg.background_sharp_probability
            blurs.append(torch.where(sharp, 0.0, uniform_draws(n, *cfg.background_blur, g)))
        effects = [cfg.camera.draw(n, g) for _ in lightings]
        if cfg.linear_response > 0:  # from a stream of its own: every other draw stays what it was
            linear = torch.rand(n, generator=_generator(self.seed, worker, index, -2)) < cfg.linear_response
            for fx in effects:
                fx["tone"][linear] = torch.tensor([0.0, LINEAR_RESPONSE_GAMMA], dtype=fx["tone"].dtype)
                fx["rolloff"][linear] = 0.0
        rooms: list[Surroundings | None] | None = None
        if cfg.surroundings > 0:  # from a stream of its own: every other draw stays what it was
            rooms = draw_surroundings(n, cfg.surroundings, _generator(self.seed, worker, index, -3))
        mates: list[tuple[int, float] | None] | None = None
        if cfg.companions > 0:  # from a stream of its own: every other draw stays what it was
            mates = self._companions(n, field_ids, _generator(self.seed, worker, index, -4))
        plain: list[bool] | None = None
        if cfg.plain_background > 0:  # from a stream of its own: every other draw stays what it was
            drops = draw_backdrops(n, cfg.plain_background, _generator(self.seed, worker, index, -5),
                                   cfg.plain_albedo)
            plain = [d is not None for d in drops]
            # a plain backdrop is a studio's: its wall instead of the surroundings, one sitter
            rooms = [d if d is not None else (None if rooms is None else rooms[j]) for j, d in enumerate(drops)]
            if mates is not None:
                mates = [None if p else m for m, p in zip(mates, plain, strict=True)]
        boxes, faces, alphas, renders = [], [], [], [[] for _ in lightings]
        for k, fid in enumerate(field_ids):
            rows = slice(k * nl, (k + 1) * nl)
            rf = self.fields[fid]
            landmarks = torch.tensor(rf.meta["landmarks"], dtype=torch.float64).expand(nl, -1, -1).clone()
            landmarks[flips[rows], :, 0] = rf.size - landmarks[flips[rows], :, 0]  # in the mirrored image
            faces.append(detector_boxes(landmarks))
            if cfg.crop == "face":
                boxes.append(face_crop_boxes(faces[-1], rf.size, generator=g, scale=cfg.crop_scale,
                                             position=cfg.crop_position, extent=cfg.crop_extent))
            else:
                boxes.append(random_crop_boxes(faces[-1], rf.size, generator=g))
            if cfg.pairs or cfg.matte:
                alpha = crop_images(rf.alpha.float()[None], _source_boxes(boxes[-1], flips[rows], rf.size),
                                    cfg.size, flips[rows])
                alphas.append(alpha.mul_(255.0).round_().to(torch.uint8))
            for out, (latlong, envs, env_keys, turns), key, blur, fx in zip(
                renders, lightings, keys, blurs, effects, strict=True
            ):
                backgrounds = None
                if cfg.background == "environment":
                    backgrounds = [self._background(kk, e) for kk, e in zip(env_keys[rows], envs[rows], strict=True)]
                params = {name: v[rows] for name, v in fx.items()}
                out.append(self._render(rf, latlong[rows], backgrounds=backgrounds, turn=turns[rows],
                                        blur=blur[rows], flip=flips[rows], boxes=boxes[-1], key=key[rows],
                                        effects=params, g=g,
                                        rooms=None if rooms is None else rooms[rows],
                                        mates=None if mates is None else mates[rows]))
        views = []
        for out, (_, envs, _, _), blur, fx in zip(renders, lightings, blurs, effects, strict=True):
            image, truth, gain, *whole = (torch.cat(parts) for parts in zip(*out, strict=True))
            views.append({"image": image, "mirror_ball": truth, "exposure": gain,
                          "spheres": sphere_targets(truth, cfg.sphere_sizes),
                          "label": [e.label for e in envs], "source": [e.source for e in envs],
                          "background_blur": blur.float(), "camera": {k: v.float() for k, v in fx.items()}})
            if whole:
                views[-1]["frame"] = whole[0]
        boxes, faces = torch.cat(boxes).float(), torch.cat(faces).float()
        frame_boxes = windows = None
        if cfg.frame:
            sides = torch.tensor([float(self.fields[f].size) for f in field_ids]).repeat_interleave(nl)
            frame_boxes = faces * (cfg.frame / sides)[:, None]
            windows = aspect_windows(frame_boxes, cfg.frame, generator=_generator(self.seed, worker, index, -6))
        second = None
        if cfg.second_crop:  # the chunk's last draws, and only when asked for: the others stay what they were
            second = inner_crop_boxes(n, cfg.size, generator=g, position=cfg.crop_position,
                                      extent=cfg.crop_extent).float()
        look = None
        if cfg.colour_looks > 0:  # drawn after everything else, and only when asked for
            look = draw_looks(n, cfg.colour_looks, g)
            for view in views:
                if "frame" in view:  # the same look on the whole frame (its lighting target is the crop's)
                    view["frame"], _ = apply_looks(view["frame"], view["mirror_ball"], look)
                view["image"], view["mirror_ball"] = apply_looks(view["image"], view["mirror_ball"], look)
                view["spheres"] = sphere_targets(view["mirror_ball"], cfg.sphere_sizes)
        samples = []
        for j in range(n):
            rf = self.fields[field_ids[j // nl]]
            one = [{**{k: v[j] for k, v in view.items() if k not in ("spheres", "camera")},
                    "spheres": {k: v[j] for k, v in view["spheres"].items()},
                    "camera": {k: v[j] for k, v in view["camera"].items()}} for view in views]
            sample = {
                **one[0],
                "crop_box": boxes[j],
                "face_box": faces[j],
                "subject_seed": rf.subject_seed,
                "skin_tone": int(rf.meta.get("skin_tone", -1)),
                "view_index": int(rf.meta.get("view_index", -1)),
                "flip": bool(flips[j]),
                "chunk": (worker, index),
            }
            if cfg.surroundings > 0:
                sample["surroundings"] = rooms[j] is not None and not (plain is not None and plain[j])
            if plain is not None:
                sample["plain"] = plain[j]
            if mates is not None:
                sample["companion"] = mates[j] is not None
            if frame_boxes is not None:
                sample["frame_box"], sample["frame_window"] = frame_boxes[j], windows[j]
            if cfg.pairs:
                sample["pair"] = one[1]
            if second is not None:
                sample["second_crop"] = second[j]
            if look is not None:
                sample["look"] = int(look.kind[j])
            if cfg.pairs or cfg.matte:
                sample["alpha"] = alphas[j // nl][j % nl]
            samples.append(sample)
        return samples

    def _companions(self, n: int, field_ids: list[int], g: torch.Generator) -> list[tuple[int, float] | None]:
        """Who stands beside each of ``n`` samples (``PortraitConfig.companions``): ``(field index, metres to the
        right)`` or ``None``; never the sample's own subject."""
        cfg = self.config
        has = (torch.rand(n, generator=g) < cfg.companions).tolist()
        picks = torch.randint(len(self.fields), (n,), generator=g).tolist()
        shifts = (uniform_draws(n, 0.3, 0.5, g) * torch.where(torch.rand(n, generator=g) < 0.5, -1.0, 1.0)).tolist()
        nl = cfg.lightings_per_field
        others = {fid: [k for k, f in enumerate(self.fields) if f.subject_seed != self.fields[fid].subject_seed]
                  for fid in set(field_ids)}  # once per subject-view of the chunk, not per sample
        out: list[tuple[int, float] | None] = []
        for j in range(n):
            pool = others[field_ids[j // nl]]
            out.append((pool[picks[j] % len(pool)], shifts[j]) if has[j] and pool else None)
        return out

    def _paint_companions(self, frame: torch.Tensor, mates: list[tuple[int, float] | None],
                          lighting: torch.Tensor, camera: Any) -> None:
        """Put each sample's companion (:meth:`_companions`) into its background ``frame`` ``(B, 3, S, S)``, in
        place: relit by the sample's ``lighting``, shifted sideways by their distance seen through ``camera``
        (at the subject's distance), over the background."""
        size = frame.shape[-1]
        width_m = 2.0 * float(camera.distance) * math.tan(math.radians(float(camera.fov_deg)) / 2.0)
        for j, mate in enumerate(mates):
            if mate is None:
                continue
            other = self.fields[mate[0]]
            relit = frame.new_zeros(1, 3, other.size, other.size)
            add_relit(relit, other, lighting=lighting[j : j + 1], sparse=self._sparse_of(other),
                      eps=self.config.relight_eps)
            layer = torch.cat([relit[0], other.alpha.float().to(frame)])
            if other.size != size:
                layer = torch.nn.functional.interpolate(layer[None], size=(size, size), mode="area")[0]
            dx = max(-size, min(size, round(mate[1] / width_m * size)))
            moved = torch.zeros_like(layer)
            if dx >= 0:
                moved[..., dx:] = layer[..., : size - dx]
            else:
                moved[..., :dx] = layer[..., -dx:]
            frame[j].mul_(1.0 - moved[3:]).add_(moved[:3])

    def _noise(self, n: int, size: int, g: torch.Generator, needed: bool) -> list[torch.Tensor] | None:
        """``n`` standard normal images ``(3, size, size)``, cheaply (``None`` unless ``needed``; the draws from
        ``g`` are made either way, so switching the noise off changes no other draw).

        Drawing fresh Gaussian noise for every pixel costs more than the rest of the encoding; windows at random
        offsets of one ``(3, size + 64, size + 64)`` Gaussian texture (seeded by the dataset's seed), with random
        signs, look the same and cost nothing: they are views of the texture or of its negation (kept beside
        it), read in place by :meth:`CameraEffects.apply`.
        """
        offsets = torch.randint(65, (n, 2), generator=g).tolist()
        signs = (torch.rand(n, generator=g) < 0.5).tolist()  # True: negated
        if not needed:
            return None
        if self._noise_bank is None or self._noise_bank.shape[-1] != size + 64:
            bank = torch.randn(3, size + 64, size + 64, generator=_generator(self.seed, -1))
            self._noise_bank = torch.stack([bank, -bank])
        return [self._noise_bank[int(neg), :, i : i + size, j : j + size] for (i, j), neg in zip(offsets, signs,
                                                                                                   strict=True)]

    def _render(self, rf: ReflectanceField, latlong: torch.Tensor, *, backgrounds: list | None,
                turn: torch.Tensor, blur: torch.Tensor, flip: torch.Tensor, boxes: torch.Tensor,
                key: torch.Tensor, effects: dict[str, torch.Tensor], g: torch.Generator,
                rooms: list[Surroundings | None] | None = None,
                mates: list[tuple[int, float] | None] | None = None) -> tuple[torch.Tensor, ...]:
        """``(image, mirror_ball, exposure)`` of one field under a batch of lightings (package docstring), and
        the whole frame (``PortraitConfig.frame``) where asked for.

        ``backgrounds`` are :meth:`_background` pairs (pyramid, direction map) or ``None`` (black);
        ``rooms`` are the samples' near surfaces or plain backdrops (``None``: none), in the lighting and in the
        background;
        ``mates`` the samples' companions ``(field index, shift as a fraction of the width)`` or ``None``;
        ``boxes`` are in the mirrored image for the mirrored samples. A mirrored sample is the subject relit
        with the mirrored lighting over the mirrored environment's background (mirrored rays), cropped through
        the mirrored box and flipped (in the crop's sampling grid): the mirrored subject under the true lighting.
        """
        cfg = self.config
        size = cfg.size
        far = latlong
        if rooms is not None and any(r is not None for r in rooms):
            latlong = torch.stack([x if r is None else with_surroundings(x, r) for x, r in zip(far, rooms,
                                                                                                 strict=True)])
        lighting = latlong_to_mirror_ball(latlong, self.lighting_size)
        flipped = torch.where(flip[:, None, None, None], flip_lighting_horizontal(lighting), lighting)
        source_boxes = _source_boxes(boxes, flip, rf.size)
        if backgrounds is not None:
            pyramids, rotations = zip(*backgrounds, strict=True)
            frame = frame_backgrounds(pyramids, rf.camera, mirror=flip, turn=turn, sigma=blur,
                                      rotation=torch.stack(rotations))
            if rooms is not None:
                _paint_surroundings(frame, far, rooms, rf.camera)
            if mates is not None:
                self._paint_companions(frame, mates, flipped, rf.camera)
            if cfg.subject:
                frame.mul_(1.0 - rf.alpha.float())  # I + (1 - alpha) B, I added below
        else:
            frame = latlong.new_zeros(len(latlong), 3, rf.size, rf.size)
        if cfg.subject:
            add_relit(frame, rf, lighting=flipped, sparse=self._sparse_of(rf), eps=cfg.relight_eps)
        linear = crop_images(frame, source_boxes, size, flip)
        step = max(1, size // 64)  # meter on a 64 x 64 subsample
        gain = auto_exposure(linear[:, :, step // 2 :: step, step // 2 :: step].clamp(min=0.0), key)
        noise = self._noise(len(linear), size, g, bool((effects["noise"] > 0).any()))
        image = cfg.camera.apply(linear, effects, noise=noise, gain=gain)  # exposes, fused with the effects
        out = (image, lighting * gain[:, None, None, None].to(lighting), gain.float())
        if not cfg.frame:
            return out
        whole = torch.nn.functional.interpolate(frame, size=(cfg.frame, cfg.frame), mode="area")
        whole = torch.where(flip[:, None, None, None], whole.flip(-1), whole)
        calm = {**effects, **{k: torch.zeros_like(effects[k]) for k in ("noise", "blur", "jpeg")}}
        return (*out, cfg.camera.apply(whole.contiguous(), calm, gain=gain))
