r"""Build the held-out eval set, run estimators and oracles on it, and score them.

The eval set (:func:`build_eval_set`) is ``N`` portraits of
:class:`~kornia_ilum_lab.synth.lightstage.portraits.PortraitDataset` (split ``"eval"``) from the eval subjects, lit by
environments of the eval sources (:func:`~kornia_ilum_lab.evaluation.split.eval_environment_sources`) drawn with the seed
:data:`~kornia_ilum_lab.evaluation.split.EVAL_SEED`, with the training recipe's crops, flips, backgrounds, exposure
and phone-camera effects. Each chunk of the dataset takes ``fields_per_chunk`` fields and relights each with
``lightings_per_field`` lightings picked from ``env_pool`` environments that are all new at every chunk, so the
set holds about as many environments as samples.

Scores per sample (:func:`score`): ``L_rec`` per reference sphere
(:func:`kornia_ilum.metrics.reconstruction_loss`, 32-pixel spheres, the metric form) and the relative radiance
per channel (:func:`kornia_ilum.metrics.relative_radiance`). Oracles (:func:`oracle_predictions`):

- ``"SH of GT"``: the order-2 SH projection of the ground truth, reconstructed on the mirror ball **unclamped**
  (as in the paper; negative lobes render as 0 through the metric's soft clip);
- ``"mean of GT"``: a constant lighting with the ground truth's energy (solid-angle weighted mean per channel).
"""

from __future__ import annotations

import copy
import dataclasses
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import torch

from kornia_ilum.core.check import check_positive_int, check_tensor
from kornia_ilum.core.errors import MissingWeightsError, ValueCheckError
from kornia_ilum.core.progress import progress as bar
from kornia_ilum.detection.crop import CROP_SCALE
from kornia_ilum.estimators import (
    LightingEstimator,
    TestTimeAugmented,
    create_estimator,
    estimator_registry,
    list_estimators,
    read_weights,
    runtime_available,
    with_runtime,
)
from kornia_ilum.estimators.probe import CHECK, fit_crops, load_probe, probe_digest
from kornia_ilum_lab.evaluation.split import EVAL_SEED, eval_environment_sources, eval_fields
from kornia_ilum.geometry import mirror_ball_solid_angles, mirror_ball_valid
from kornia_ilum.metrics import reconstruction_loss, relative_radiance
from kornia_ilum.sh import sh_project, sh_reconstruct
from kornia_ilum_lab.synth.environments import EnvironmentSampler
from kornia_ilum_lab.synth.environments.real import HDRFolderSource
from kornia_ilum_lab.synth.lightstage.portraits import PortraitConfig, PortraitDataset, face_crop_boxes

__all__ = [
    "BRDF_NAMES",
    "DEFAULT_SAMPLES",
    "ORACLES",
    "EvalSet",
    "build_eval_set",
    "probe_eval_set",
    "fit_crops",
    "evaluate",
    "load_checkpoint",
    "load_estimator",
    "oracle_predictions",
    "predict",
    "score",
]

#: The reference spheres of Table 1, in order.
BRDF_NAMES: tuple[str, ...] = ("diffuse", "matte_silver", "mirror")
#: Samples of the default eval set.
DEFAULT_SAMPLES = 512
#: The oracle names.
ORACLES: tuple[str, ...] = ("SH of GT", "mean of GT")


@dataclasses.dataclass
class EvalSet:
    r"""The eval samples, stacked.

    Attributes:
        images: ``(N, 3, S, S)`` uint8 sRGB crops, as the dataset made them.
        mirror_ball: ``(N, 3, 32, 32)`` float32 linear ground-truth lighting in image units.
        label: ``"indoor"`` / ``"outdoor"`` per sample.
        skin_tone: the subject's Monk skin tone per sample (``-1`` unknown).
        subject_seed: the subject's seed per sample.
        source: the environment's source per sample (``"real:<name>"``, ``"sky"``, ...).
        alpha: ``(N, 1, S, S)`` uint8, the subject's matte in each crop (255: subject), or ``None``.
        nominal_boxes: for a set of context crops (:func:`build_eval_set` with ``context``), ``(N, 4)``
            float64 ``(x0, y0, x1, y1)``: where the nominal face crop (side 1.25 times the face box, no
            jitter) lies in each crop's pixels; ``None`` for the usual crops.
        frames: with ``portraits={"frame": F}``, ``(N, 3, F, F)`` uint8: the whole rendered frame around each
            crop (``PortraitConfig.frame``), else ``None``; ``frame_boxes`` ``(N, 4)``: the face box in it.
        description: JSON-ready facts: counts, subjects, maps, seeds, settings, build time.

    Shape:
        - images: :math:`(N, 3, S, S)` uint8; alpha: :math:`(N, 1, S, S)` uint8
        - mirror_ball: :math:`(N, 3, 32, 32)`; nominal_boxes: :math:`(N, 4)`

    Convention:
        ``images`` are sRGB codes (docs/conventions.rst, "Images", times 255); ``mirror_ball`` is linear
        lighting in the units of the images (docs/conventions.rst, "Mirror ball" and "Units of lighting").

    Examples:
        >>> from kornia_ilum.geometry import mirror_ball_valid
        >>> tiny = EvalSet(torch.zeros(2, 3, 8, 8, dtype=torch.uint8), torch.ones(2, 3, 32, 32) * mirror_ball_valid(32),
        ...                label=["indoor", "outdoor"], skin_tone=[3, 7], subject_seed=[0, 1], source=["room", "sky"])
        >>> len(tiny), tiny.alpha is None, tiny.description
        (2, True, {})
    """

    images: torch.Tensor
    mirror_ball: torch.Tensor
    label: list[str]
    skin_tone: list[int]
    subject_seed: list[int]
    source: list[str]
    alpha: torch.Tensor | None = None
    nominal_boxes: torch.Tensor | None = None
    description: dict[str, Any] = dataclasses.field(default_factory=dict)
    frames: torch.Tensor | None = None
    frame_boxes: torch.Tensor | None = None

    def __len__(self) -> int:
        return len(self.images)


def build_eval_set(
    caches: Sequence[str | os.PathLike[str]] = (),
    hdri: Sequence[str | os.PathLike[str]] = (),
    *,
    samples: int = DEFAULT_SAMPLES,
    fields: Sequence[Any] = (),
    seed: int = EVAL_SEED,
    size: int = 256,
    fields_per_chunk: int = 4,
    lightings_per_field: int = 8,
    background: str = "environment",
    context: float | None = None,
    portraits: Mapping[str, Any] | None = None,
    progress: bool = False,
) -> EvalSet:
    r"""The held-out eval set: ``samples`` portraits of the eval subjects under eval environments.

    Deterministic: the same arguments give the same samples, bit for bit, in any run. Every sample comes with
    its subject's matte (``alpha``; :class:`PortraitConfig` ``matte=True``, which changes no other value).

    With ``context`` the same portraits (subjects, views, flips, lightings, backgrounds, camera-effect draws)
    are cropped wider, for :func:`~kornia_ilum_lab.evaluation.checks.crop_stability`: a square of ``context``
    times the nominal face crop (1.25 times the face box) around the same centre, without the crop jitter, at
    ``round(size * context)`` pixels, so that the nominal crop spans ``size`` of them. As every crop of the
    dataset, a context crop that leaves the render is shifted back inside it (and shrunk to the render if
    larger: the light-stage renders frame the face so that the nominal crop is about 0.7 of the side), so the
    nominal crop is not always the central square: ``nominal_boxes`` says where it is. The exposure meters the
    context crop (the camera's exposure does not depend on a face detector), so the gain, and with it the
    ground truth, differ a little from those of the usual set; the camera effects apply to the context crop.

    Args:
        caches: light-stage cache folders; their eval subjects are used (:func:`eval_fields`).
        hdri: folders of real maps; their eval maps join the procedural skies and rooms.
        samples: the number of portraits ``N``.
        fields: extra :class:`~kornia_ilum_lab.synth.lightstage.ReflectanceField` objects (those of split
            ``"eval"`` are used; for tests).
        seed: the seed of the environment sampler and of the portraits (:data:`EVAL_SEED`).
        size: the crops' side (the estimators take 256).
        fields_per_chunk, lightings_per_field: the dataset's chunks (:class:`PortraitConfig`); every chunk
            draws ``fields_per_chunk * lightings_per_field`` new environments (``env_pool = env_refresh``).
        background: ``"environment"`` (the matching background, as in training ``ours``) or ``"black"``
            (the same portraits, subjects, lightings and crops over black, the variant SIPR was trained on).
        context: ``None`` for the usual face crops, or a factor of at least 1: the context crops above.
        portraits: other :class:`~kornia_ilum_lab.synth.lightstage.portraits.PortraitConfig` settings of the
            portraits (for an ablation's input: ``{"subject": False}`` for the backgrounds alone, a wider
            ``crop_position`` and ``crop_extent`` for crops without a face detector); not those that this
            function sets itself (the split, environments, length, chunks, background, matte, sphere sizes).
        progress: show a progress bar.

    Returns:
        the :class:`EvalSet`, with ``alpha`` and ``description`` filled (and ``nominal_boxes`` with
        ``context``).

    Raises:
        ValueCheckError: no eval subject, a lighting size other than 32, ``context`` below 1.
        HDRIOError: a folder of ``hdri`` is missing or holds no eval map.

    Convention:
        As :class:`EvalSet`: sRGB crops and linear lighting in their units (docs/conventions.rst, "Images",
        "Mirror ball" and "Units of lighting").

    Examples:
        It needs a light-stage cache with eval subjects (``kornia-ilum synth subjects --split eval``):

        >>> build_eval_set([], samples=8)
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: no eval subject in the caches [] (or fields)
        >>> eval_set = build_eval_set(["lightstage/"], samples=8)  # doctest: +SKIP
    """
    check_positive_int(samples, "samples")
    if context is not None and not (isinstance(context, (int, float)) and math.isfinite(context)
                                    and context >= 1):
        raise ValueCheckError(f"context must be None or a finite number >= 1, got {context!r}")
    t0 = time.perf_counter()
    subjects = eval_fields(caches, fields)
    sources = eval_environment_sources(hdri)
    sampler = EnvironmentSampler(sources=sources, seed=seed)
    own = {"split", "environments", "length", "sphere_sizes", "fields_per_chunk", "lightings_per_field",
           "env_pool", "env_refresh", "shuffle", "background", "matte"}
    portraits = dict(portraits or {})
    unknown = sorted(set(portraits) - ({f.name for f in dataclasses.fields(PortraitConfig)} - own))
    if unknown:
        raise ValueCheckError(f"portraits settings {unknown} are not PortraitConfig's, or are set by the eval set")
    per_chunk = fields_per_chunk * lightings_per_field
    crop: dict[str, Any] = {"size": size}
    if context is not None:  # the same draws: a jitter of zero width still draws its numbers
        crop = {"size": round(size * context), "crop_scale": CROP_SCALE * context, "crop_position": 0.0,
                "crop_extent": 0.0}
    # sphere_sizes=(): the scores render their own spheres from the mirror ball (the samples' would go unread)
    config = PortraitConfig(split="eval", environments=sampler, length=samples, sphere_sizes=(),
                            fields_per_chunk=fields_per_chunk, lightings_per_field=lightings_per_field,
                            env_pool=per_chunk, env_refresh=per_chunk, shuffle=1, background=background,
                            matte=True, **{**portraits, **crop})
    dataset = PortraitDataset(subjects, config, seed=seed)
    render_size = {(f.subject_seed, int(f.meta.get("view_index", -1))): f.size for f in dataset.fields}
    what = "eval set" if context is None else "context set"
    items = dataset if not progress else bar(dataset, samples, what, "sample")
    images, balls, alphas, label, tone, subject, source, nominal = [], [], [], [], [], [], [], []
    frames, frame_boxes = [], []
    for s in items:
        if "frame" in s:
            frames.append(s["frame"])
            frame_boxes.append(s["frame_box"])
        images.append(s["image"])
        balls.append(s["mirror_ball"].float())
        alphas.append(s["alpha"])
        label.append(s["label"])
        tone.append(int(s["skin_tone"]))
        subject.append(int(s["subject_seed"]))
        source.append(s["source"])
        if context is not None:
            nominal.append(_nominal_box(s, render_size[s["subject_seed"], s["view_index"]], config.size))
    seconds = time.perf_counter() - t0
    maps = {}
    for src in sources:
        if isinstance(src, HDRFolderSource):
            maps[str(src.folder)] = {n: src.labels[n] for n in src.names}
    used = sorted({x.removeprefix("real:") for x in source if x.startswith("real:")})
    description = {
        "samples": len(images),
        "seed": seed,
        "size": config.size,
        "background": background,
        "context": context,
        "labels": {k: label.count(k) for k in ("indoor", "outdoor")},
        "subjects": sorted({f.subject_seed for f in subjects}),
        "fields": len(subjects),
        "caches": [str(c) for c in caches],
        "skin_tones": {str(k): tone.count(k) for k in sorted(set(tone))},
        "eval_maps": maps,
        "maps_used": {n: sum(x == f"real:{n}" for x in source) for n in used},
        "sources": {k: sum(_family(x) == k for x in source) for k in sorted({_family(x) for x in source})},
        "environment_sampler": {"seed": seed, "sources": [type(s).__name__ for s in sources],
                                "weights": [round(w, 6) for w in sampler.weights]},
        "portraits": {"fields_per_chunk": fields_per_chunk, "lightings_per_field": lightings_per_field,
                      "env_pool": per_chunk, "camera": "CameraEffects() (the training default)",
                      **{k: repr(v) for k, v in sorted(portraits.items())}},
        "build_seconds": round(seconds, 2),
        "torch_threads": torch.get_num_threads(),
    }
    if context is not None:
        description["crop"] = {"scale": config.crop_scale, "position": 0.0, "extent": 0.0,
                               "nominal_size": size}
    return EvalSet(torch.stack(images), torch.stack(balls), label, tone, subject, source,
                   alpha=torch.stack(alphas), nominal_boxes=torch.stack(nominal) if nominal else None,
                   description=description, frames=torch.stack(frames) if frames else None,
                   frame_boxes=torch.stack(frame_boxes) if frame_boxes else None)


def probe_eval_set(part: slice = CHECK) -> EvalSet:
    r"""The shipped probe's portraits (:mod:`~kornia_ilum.estimators.probe`) as an :class:`EvalSet`.

    Light-stage **training** portraits (train subjects, train environments): not the held-out split, so its
    scores are no evidence of accuracy; what it gives is the same tables, computed the same way, where no
    light-stage cache is at hand (``kornia-ilum bench`` without ``--cache``, and CI). By default its check part
    (:data:`~kornia_ilum.estimators.probe.CHECK`, 256 portraits, never used to calibrate).

    Args:
        part: which portraits of the probe (:data:`~kornia_ilum.estimators.probe.CALIBRATION` or
            :data:`~kornia_ilum.estimators.probe.CHECK`, or any slice of them).

    Returns:
        the :class:`EvalSet` of those portraits: uint8 crops (the probe's, rounded), the probe's lighting, the
        labels, skin tones, subjects and sources of its metadata; no matte, so no transfer check.

    Examples:
        >>> small = probe_eval_set(slice(64, 72))
        >>> len(small), small.description["source"]
        (8, 'probe')
    """
    probe = load_probe()
    per = probe.meta["per_sample"]
    index = range(len(probe))[part]
    pick = lambda key: [per[key][i] for i in index]  # noqa: E731
    images = (probe.crops[part] * 255.0).round().to(torch.uint8)
    description = {"source": "probe", "split": probe.meta.get("split"), "samples": len(index),
                   "part": [part.start, part.stop], "probe": probe_digest(),
                   "labels": {k: pick("label").count(k) for k in ("indoor", "outdoor")},
                   "skin_tones": {str(t): pick("skin_tone").count(t) for t in sorted(set(pick("skin_tone")))}}
    return EvalSet(images, probe.mirror_ball[part].clone(), pick("label"), pick("skin_tone"), pick("subject_seed"),
                   pick("source"), description=description)


def _nominal_box(sample: dict[str, Any], render_size: int, size: int) -> torch.Tensor:
    """Where the nominal face crop (no jitter, kept inside the render as the dataset's crops are) lies in the
    pixels of a sample's ``size x size`` crop; both boxes are in the (mirrored, where flipped) render's
    pixels."""
    box = sample["crop_box"].double()
    nominal = face_crop_boxes(sample["face_box"].double()[None], render_size)[0]
    origin = box[:2].repeat(2)
    return (nominal - origin) * (size / (box[2] - box[0]))


def _family(source: str) -> str:
    return "real" if source.startswith("real:") else source.split(":")[0]


def oracle_predictions(mirror_ball: torch.Tensor) -> dict[str, torch.Tensor]:
    r"""The two oracles from the ground truth.

    Args:
        mirror_ball: ground-truth linear lighting.

    Returns:
        a dict: ``"SH of GT"`` is ``sh_reconstruct(sh_project(gt))``, unclamped; ``"mean of GT"`` is the
        constant lighting with the solid-angle weighted mean of ``gt`` per channel, on the valid pixels.

    Shape:
        - mirror_ball: :math:`(B, 3, S, S)`
        - Output: each :math:`(B, 3, S, S)`

    Convention:
        docs/conventions.rst, "Mirror ball", "Units of lighting" and "Spherical harmonics"; the outputs are in the
        units of ``mirror_ball``.

    Examples:
        >>> gt = torch.rand(2, 3, 32, 32)
        >>> out = oracle_predictions(gt)
        >>> from kornia_ilum.metrics import relative_radiance
        >>> bool(relative_radiance(out["mean of GT"], gt).abs().max() < 1e-5)
        True
    """
    check_tensor(mirror_ball, "mirror_ball", ["B", "3", "S", "S"])
    s = mirror_ball.shape[-1]
    sh = sh_reconstruct(sh_project(mirror_ball), size=s, clamp_negative=False)
    omega = mirror_ball_solid_angles(s, device=mirror_ball.device, dtype=mirror_ball.dtype)
    valid = mirror_ball_valid(s, device=mirror_ball.device)
    gt = mirror_ball * valid
    mean = (gt * omega).sum((-2, -1), keepdim=True) / (4 * math.pi)
    return {"SH of GT": sh, "mean of GT": mean * valid.to(mirror_ball.dtype)}


def score(pred: torch.Tensor, target: torch.Tensor) -> dict[str, torch.Tensor]:
    r"""Per-sample scores: ``L_rec`` per sphere ``(B,)`` and ``"relative_radiance"`` ``(B, 3)``.

    Args:
        pred: the estimated lighting.
        target: the true lighting.

    Returns:
        ``{"diffuse", "matte_silver", "mirror"}`` -> ``L_rec`` per sample (32-pixel spheres, the metric form of
        :func:`~kornia_ilum.metrics.reconstruction_loss`), and ``"relative_radiance"`` per sample and channel
        (:func:`~kornia_ilum.metrics.relative_radiance`).

    Shape:
        - pred, target: :math:`(B, 3, 32, 32)`
        - Output: ``L_rec`` :math:`(B,)` each; ``relative_radiance`` :math:`(B, 3)`

    Convention:
        docs/conventions.rst, "The paper's error measure L_rec", "Reference spheres" and "Relative radiance";
        both lightings are mirror balls in the same units ("Mirror ball", "Units of lighting").

    Examples:
        >>> gt = torch.ones(2, 3, 32, 32)
        >>> s = score(gt, gt)
        >>> sorted(s), s["diffuse"].tolist()
        (['diffuse', 'matte_silver', 'mirror', 'relative_radiance'], [0.0, 0.0])
    """
    out = {b: reconstruction_loss(pred, target, brdf=b, size=32, reduction="none") for b in BRDF_NAMES}
    out["relative_radiance"] = relative_radiance(pred, target)
    return out


def predict(estimator: Callable[[torch.Tensor], Any], images: torch.Tensor, batch_size: int = 32) -> torch.Tensor:
    r"""``estimator`` on uint8 crops, in batches: float crops in ``[0, 1]`` in, ``(N, 3, 32, 32)`` float32 out.

    ``estimator`` returns a :class:`~kornia_ilum.estimators.LightingEstimate` (or a tensor of mirror balls); the
    crops are brought to its input size first (:func:`fit_crops`).

    Args:
        estimator: a lighting estimator, or any callable from crops to an estimate or a tensor of mirror balls.
        images: uint8 crops, such as :attr:`EvalSet.images`.
        batch_size: crops per forward pass.

    Returns:
        the estimated mirror balls, float32, without autograd graph (:func:`torch.inference_mode`).

    Shape:
        - images: :math:`(N, 3, S, S)` uint8
        - Output: :math:`(N, 3, 32, 32)`

    Convention:
        Crops are sRGB codes (docs/conventions.rst, "Images", divided by 255 here); the lighting is in their
        units (docs/conventions.rst, "Mirror ball" and "Units of lighting").

    Examples:
        >>> from kornia_ilum.estimators import create_estimator
        >>> crops = torch.randint(0, 256, (3, 3, 256, 256), dtype=torch.uint8)
        >>> tuple(predict(create_estimator("uniform"), crops, batch_size=2).shape)
        (3, 3, 32, 32)
    """
    out = []
    with torch.inference_mode():
        for i in range(0, len(images), batch_size):
            crops = fit_crops(estimator, images[i : i + batch_size].float() / 255.0)
            est = estimator(crops)
            out.append(getattr(est, "mirror_ball", est).float())
    return torch.cat(out)


def load_estimator(name: str, weights: str | os.PathLike[str] | None = None) -> LightingEstimator:
    r"""A registered estimator: ``create_estimator(name)``, or with ``weights`` the class of ``name`` built
    untrained and loaded from that ``.safetensors`` file (``strict=True``), in ``eval()`` mode.

    Either way the weights go through :func:`~kornia_ilum.estimators.read_weights`, the SHA-256-checked path of
    :meth:`~kornia_ilum.estimators.LightingEstimator.from_pretrained`; for a file of ``weights``, whose digest
    is not known in advance, :func:`load_checkpoint` also returns the digest.

    Args:
        name: a registered estimator name (:func:`~kornia_ilum.estimators.list_estimators`).
        weights: a ``.safetensors`` file of the class of ``name``; ``None`` for its shipped weights.

    Returns:
        the estimator, in ``eval()`` mode.

    Raises:
        ValueError: unknown name.
        MissingWeightsError: no shipped weights (``weights=None``) or the file is missing.
        ValueCheckError: the file is not ``.safetensors``.
        WeightsChecksumError: a shipped weight file fails its SHA-256 check.

    Examples:
        >>> net = load_estimator("uniform")
        >>> net.info.name, net.training
        ('uniform', False)
    """
    if weights is None:
        return create_estimator(name)
    return load_checkpoint(name, weights)[0]


def load_checkpoint(name: str, weights: str | os.PathLike[str]) -> tuple[LightingEstimator, str]:
    r"""The class of the registered estimator ``name``, built untrained and loaded from a ``.safetensors`` file.

    The file is read by :func:`~kornia_ilum.estimators.read_weights` (safetensors, never unpickled), which
    computes its SHA-256; the digest is returned so that the evaluation records which file it scored.

    Args:
        name: a registered estimator name; its class is built with its default arguments.
        weights: the weight file, such as a training run's ``<name>.safetensors``.

    Returns:
        ``(estimator, sha256)``: the estimator in ``eval()`` mode, and the file's SHA-256.

    Raises:
        ValueError: unknown name.
        MissingWeightsError: the file is missing.
        ValueCheckError: the file is not ``.safetensors``.

    Examples:
        >>> import tempfile, safetensors.torch
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     path = Path(tmp, "uniform.safetensors")
        ...     safetensors.torch.save_file({}, str(path))  # uniform has no parameters
        ...     net, digest = load_checkpoint("uniform", path)
        >>> type(net).__name__, net.training, len(digest)
        ('UniformEstimator', False, 64)
        >>> load_checkpoint("uniform", "weights.pt")
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: weights must be a .safetensors file, got weights.pt
    """
    path = Path(weights)
    if path.suffix != ".safetensors":
        raise ValueCheckError(f"weights must be a .safetensors file, got {path}")
    if not path.is_file():
        raise MissingWeightsError(f"weight file {path} not found")
    cls = estimator_registry().get(name)
    if cls is None:
        create_estimator(name, pretrained=False)  # raises the registry's ValueError for an unknown name
        cls = estimator_registry()[name]
    model = cls()
    state, digest = read_weights(path)
    model.load_state_dict(state, strict=True)
    return model.eval(), digest


def evaluate(
    eval_set: EvalSet,
    estimators: Sequence[str] | None = None,
    *,
    weights: Mapping[str, str | os.PathLike[str]] | Sequence[tuple[str, str | os.PathLike[str]]] | None = None,
    oracles: bool = True,
    batch_size: int = 32,
    checks: Callable[[LightingEstimator, torch.Tensor], dict[str, Any]] | None = None,
    tta: int | None = None,
    runtimes: Sequence[str] = (),
) -> dict[str, Any]:
    r"""Score the estimators and the oracles on ``eval_set`` (and run ``checks`` on the estimators).

    Args:
        eval_set: from :func:`build_eval_set`.
        estimators: registered names (``None``: all of :func:`~kornia_ilum.estimators.list_estimators`).
        weights: ``{name: checkpoint.safetensors}``, or ``(name, checkpoint)`` pairs to score several files of
            one class, each scored as ``"name@file"`` (the class of ``name``, :func:`load_checkpoint`).
        oracles: also score :data:`ORACLES`.
        batch_size: crops per forward pass.
        checks: called as ``checks(estimator, prediction)`` for every scored estimator (not the oracles, which
            see no image), with its lighting on the eval crops; what it returns is recorded as the method's
            ``"checks"`` (:func:`~kornia_ilum_lab.evaluation.checks.check_runner` makes one that runs
            :func:`~kornia_ilum_lab.evaluation.checks.run_checks`).
        tta: also score each estimator wrapped in
            :class:`~kornia_ilum.estimators.TestTimeAugmented` with ``jitters=tta`` (``2 tta`` passes per crop),
            as ``"name+ttaN"``, checks included.
        runtimes: also score each estimator computed by these runtimes
            (:func:`~kornia_ilum.estimators.with_runtime`: ``"bf16"``, ``"onnx"``, ``"onnx-int8"``), as
            ``"name+runtime"``, checks included; a runtime that cannot run here is skipped with the reason.

    Returns:
        ``{"methods": {name: {"scores": {key: tensor}, "seconds": float}}, "skipped": {name: reason}}``
        (:func:`score`'s per-sample tensors); a method scored from a file of ``weights`` also has
        ``"sha256"``, the file's digest, and with ``checks`` an estimator has ``"checks"``, what it returned.
        An estimator without weights (:class:`MissingWeightsError`) is skipped with the reason instead of
        failing the evaluation; other errors propagate.

    Raises:
        ValueCheckError: two methods would be reported under one name (weight files of the same name), or
            ``tta`` is not a positive int.

    Shape:
        - Output: each method's ``L_rec`` scores :math:`(N,)`, its ``relative_radiance`` :math:`(N, 3)`

    Convention:
        docs/conventions.rst, "The paper's error measure L_rec", "Reference spheres" and "Relative radiance"
        (:func:`score`).

    Examples:
        >>> results = evaluate(probe_eval_set(slice(64, 72)), ["uniform"])
        >>> sorted(results["methods"]), results["skipped"]
        (['SH of GT', 'mean of GT', 'uniform'], {})
        >>> tuple(results["methods"]["uniform"]["scores"]["diffuse"].shape)
        (8,)
    """
    if tta is not None:
        check_positive_int(tta, "tta")
    names = list(list_estimators() if estimators is None else estimators)
    jobs: list[tuple[str, str, Any]] = [(n, n, None) for n in names]
    pairs = list(weights.items() if isinstance(weights, Mapping) else weights or ())
    jobs += [(f"{n}@{Path(p).name}", n, p) for n, p in pairs]
    labels = [label for label, _, _ in jobs]
    repeated = sorted({label for label in labels if labels.count(label) > 1})
    if repeated:
        raise ValueCheckError(f"two methods would both be reported as {repeated}: give the weight files "
                              "different names")
    methods: dict[str, Any] = {}
    skipped: dict[str, str] = {}
    gt = eval_set.mirror_ball
    for label, name, path in jobs:
        try:
            model, digest = (load_estimator(name), None) if path is None else load_checkpoint(name, path)
        except MissingWeightsError as e:
            skipped[label] = f"MissingWeightsError: {e}"
            continue
        variants = [(label, model)]
        if tta is not None:
            variants.append((f"{label}+tta{tta}", TestTimeAugmented(model, jitters=tta)))
        for runtime in runtimes:
            reason = runtime_available(runtime)
            if reason is not None:
                skipped[f"{label}+{runtime}"] = reason
                continue
            variants.append((f"{label}+{runtime}", with_runtime(copy.deepcopy(model), runtime)))
        for variant, estimator in variants:
            t0 = time.perf_counter()
            pred = predict(estimator, eval_set.images, batch_size)
            methods[variant] = {"scores": score(pred, gt), "seconds": round(time.perf_counter() - t0, 2)}
            if digest is not None:
                methods[variant]["sha256"] = digest
            if checks is not None:
                methods[variant]["checks"] = checks(estimator, pred)
    if oracles:
        t0 = time.perf_counter()
        preds = oracle_predictions(gt)
        for label, pred in preds.items():
            methods[label] = {"scores": score(pred, gt), "seconds": round(time.perf_counter() - t0, 2)}
    return {"methods": methods, "skipped": skipped}
