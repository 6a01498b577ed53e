r"""Portrait synthesis from cached reflectance fields, and the on-the-fly training dataset.

A training portrait is made the way LeGendre et al. 2020 made theirs from light-stage captures:

1. **Relight** a subject's OLAT reflectance field (:mod:`~kornia_ilum_lab.synth.lightstage.field`) with a lighting
   environment's 32 x 32 mirror ball, in the units of docs/conventions.rst (:func:`relight_portraits`). Half
   of the samples are mirrored left-right: the mirrored subject under the lighting ``L`` is the mirror image
   of the subject under the mirrored lighting (:func:`~kornia_ilum.geometry.flip_lighting_horizontal`), so one
   field serves as two subjects and the ground truth stays exact.
2. **Crop** the square face box expanded by 25 % (:data:`~kornia_ilum.detection.CROP_SCALE`, as at inference),
   with random jitter of position and extent, and resize to 256 (:func:`face_crop_boxes`, :func:`crop_images`).
   The face box comes from the geometry: the projected face landmarks, mapped to the box that OpenCV's Haar
   detector (the default detector at inference) draws around our renders (:data:`DETECTOR_BOX`), so training
   crops are framed like the crops the estimator will see.
3. **Composite** over a background rendered from the same environment, through the same camera, at full
   resolution and with a random depth of field: the frame's rays looked up in the environment's
   full-resolution lat-long map (:func:`environment_background`: a real map's file at 1024 x 512, a procedural
   sky rendered again at 256 rows (rooms stay at 128: they cost much more), with the sampler's augmentation:
   its rotation folded into the frame's lookup, its gains into the map's pyramid; the lighting keeps the
   sampler's 128-row map and its 32-pixel mirror ball), blurred by a Gaussian of 0 to 8 frame pixels (none for
   30 % of the samples; :func:`frame_backgrounds`, on a coarser level of the map's pyramid for strong blurs)
   and cropped with the same sampling grid as the subject, ``I + (1 - alpha) B``.
4. **Expose and photograph**: a centre-weighted auto-exposure (a camera's metering of what its sensor records,
   which saturates at white, so a sun in the crop counts as white and does not make the face a silhouette;
   :func:`auto_exposure`) with a random key, then the phone-camera effects of
   :mod:`kornia_ilum_lab.synth.camera_effects` on the crop (lens blur, vignette, Poisson-Gaussian sensor noise in
   linear, a random tone curve on top of sRGB, 8-bit codes, a JPEG round trip; each with its own probability
   and strength), then the HDR is discarded. The effects act on the 256-pixel crop, not on the frame: the crop
   is the image the estimator sees, so their strengths are in its pixels whatever the crop's scale (a phone's
   noise and JPEG blocks are those of the final image, which at inference is resized to 256 from a face that
   fills a varying part of the photo), and a crop costs no more than a frame. The ground-truth lighting is
   multiplied by the same exposure, so it is in the units of the image (docs/conventions.rst, "Units of
   lighting"): a white Lambertian surface rendered with it gives the recorded linear pixel values.

Ground truth per sample: the 32 x 32 mirror ball in the camera frame, the reference spheres at 4, 8, 16 and
32 pixels as the loss uses them (``softclip(I)^(1/2.2)``, :func:`sphere_targets`), the subject's seed and
skin tone, the view, and the environment's indoor/outdoor label and source.

:class:`PortraitDataset` (settings in :class:`PortraitConfig`) draws samples from cached fields
(:func:`~kornia_ilum_lab.synth.lightstage.build_cache`) deterministically per ``(seed, worker)``, in chunks: each
chunk relights a few fields with several lightings each (one batched matrix product per field, the layout of
:func:`kornia_ilum.render.relight`), from a pool of environments that is refreshed a little at every chunk (a
procedural environment costs several times the budget of a sample, docs/lightstage.rst). Variants: a black
background (as SIPR was trained), random crops that miss the face box, the background alone (no subject), and
pairs of one subject under two lightings (for SIPR).

The package holds :mod:`~kornia_ilum_lab.synth.lightstage.portraits.compose` (the pure steps) and
:mod:`~kornia_ilum_lab.synth.lightstage.portraits.dataset` (the configuration and the dataset).
"""

from kornia_ilum_lab.synth.lightstage.portraits.compose import (
    DETECTOR_BOX,
    PHOTO_ASPECTS,
    aspect_windows,
    auto_exposure,
    background_pyramid,
    crop_images,
    detector_boxes,
    face_crop_boxes,
    frame_background,
    frame_backgrounds,
    inner_crop_boxes,
    random_crop_boxes,
    relight_portraits,
    sphere_targets,
)
from kornia_ilum_lab.synth.lightstage.portraits.dataset import (
    MAX_WORKERS,
    PortraitConfig,
    PortraitDataset,
    environment_background,
    load_fields,
)

__all__ = [
    "DETECTOR_BOX",
    "MAX_WORKERS",
    "PHOTO_ASPECTS",
    "PortraitConfig",
    "PortraitDataset",
    "aspect_windows",
    "auto_exposure",
    "background_pyramid",
    "crop_images",
    "detector_boxes",
    "environment_background",
    "face_crop_boxes",
    "frame_background",
    "frame_backgrounds",
    "inner_crop_boxes",
    "load_fields",
    "random_crop_boxes",
    "relight_portraits",
    "sphere_targets",
]
