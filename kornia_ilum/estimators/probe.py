r"""The probe: light-stage training portraits with their true lighting, shipped to calibrate and check runtimes.

A reduced-precision runtime (:mod:`~kornia_ilum.estimators.runtime`: ``"onnx-int8"``, ``"bf16"``) changes the
estimate a little; whether it changes it too much is a question of ``L_rec`` against the truth, which needs
portraits whose lighting is known. The probe is such a set, small enough to ship: :data:`PROBE_SAMPLES`
portraits of the light stage's **train** subjects under **train** environments (never the eval split), written
by ``kornia-ilum export --probe`` (:func:`kornia_ilum_lab.train.data.write_training_probe`). Its first part calibrates
the int8 quantisation (:data:`CALIBRATION`), the rest checks the runtime against eager float32 (:data:`CHECK`,
:func:`probe_lrec_change`), so a runtime is never checked on the crops it was calibrated on.

Files (``weights/`` beside this module): ``probe.jpg``, the crops as one mosaic (rows of 8 tiles of
``256 x 256``, JPEG quality 95, as a camera would store them), and ``probe.safetensors``, the mirror balls
``(N, 3, 32, 32)`` in bfloat16 (both estimators of a check are scored against the same rounded truth) and the
metadata (how it was made).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
from pathlib import Path
from typing import Any

import torch
from torch import Tensor

from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.core.files import atomic_write
from kornia_ilum.detection import crop_faces
from kornia_ilum.io import read_ldr, write_ldr
from kornia_ilum.metrics import reconstruction_loss

__all__ = ["CALIBRATION", "CHECK", "PROBE_SAMPLES", "Probe", "fit_crops", "load_probe", "probe_digest",
           "probe_lrec", "probe_lrec_change", "write_probe"]

#: Portraits in the shipped probe.
PROBE_SAMPLES = 320
#: The probe's calibration part (int8 ranges: 64 portraits) and its check part (:func:`probe_lrec_change`: 256,
#: so that a change of mean ``L_rec`` of 1 % stands out of the sampling noise: on 32 portraits the int8 runtime
#: of ``ours`` measured -2.4 %, on the 1024 of the eval split +0.8 %).
CALIBRATION, CHECK = slice(0, 64), slice(64, PROBE_SAMPLES)
_TILE, _COLUMNS = 256, 8
_BRDFS = ("diffuse", "matte_silver", "mirror")


@dataclasses.dataclass(frozen=True)
class Probe:
    r"""Portraits with their true lighting.

    Attributes:
        crops: ``(N, 3, 256, 256)`` float32 sRGB face crops in ``[0, 1]``.
        mirror_ball: ``(N, 3, 32, 32)`` float32 linear lighting in the crops' units.
        meta: how the probe was made (caches, seed, command).

    Convention:
        Crops are sRGB (docs/conventions.rst, "Images"); the lighting is a mirror ball in the units of the crops
        (docs/conventions.rst, "Mirror ball" and "Units of lighting").

    Examples:
        >>> probe = Probe(torch.rand(4, 3, 256, 256), torch.rand(4, 3, 32, 32), {"seed": 0})
        >>> len(probe), len(probe.part(slice(0, 2))), probe.part(slice(0, 2)).meta
        (4, 2, {'seed': 0})
    """

    crops: Tensor
    mirror_ball: Tensor
    meta: dict[str, Any]

    def __len__(self) -> int:
        return self.crops.shape[0]

    def part(self, which: slice) -> Probe:
        """The portraits of ``which`` (:data:`CALIBRATION` or :data:`CHECK`)."""
        return Probe(self.crops[which], self.mirror_ball[which], self.meta)


def _default_dir() -> Path:
    return Path(__file__).resolve().parent / "weights"


def write_probe(folder: str | os.PathLike[str], crops: Tensor, mirror_ball: Tensor, meta: dict[str, Any]) -> None:
    r"""Write a probe (``probe.jpg`` and ``probe.safetensors``) into ``folder``, each file atomically.

    Args:
        folder: an existing folder.
        crops: ``(N, 3, 256, 256)`` sRGB crops in ``[0, 1]``, ``N`` a multiple of 8.
        mirror_ball: ``(N, 3, 32, 32)`` their lighting.
        meta: JSON-ready facts, stored in the safetensors header.

    Returns:
        None; ``folder`` holds ``probe.jpg`` and ``probe.safetensors``, replacing any there.

    Raises:
        ShapeError: wrong shapes.

    Shape:
        - crops: :math:`(N, 3, 256, 256)`, ``N`` a multiple of 8
        - mirror_ball: :math:`(N, 3, 32, 32)`

    Convention:
        Crops are sRGB (docs/conventions.rst, "Images"), stored as JPEG quality 95; the mirror balls are linear
        (docs/conventions.rst, "Mirror ball" and "Units of lighting"), stored as bfloat16.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     write_probe(folder, torch.rand(8, 3, 256, 256), torch.rand(8, 3, 32, 32), {"seed": 0})
        ...     sorted(p.name for p in Path(folder).iterdir())
        ['probe.jpg', 'probe.safetensors']
    """
    import safetensors.torch  # lazy: as read_weights

    n = crops.shape[0]
    if crops.shape[1:] != (3, _TILE, _TILE) or n % _COLUMNS or mirror_ball.shape != (n, 3, 32, 32):
        raise ShapeError(f"a probe is (N, 3, {_TILE}, {_TILE}) crops with N a multiple of {_COLUMNS} and (N, 3, "
                         f"32, 32) mirror balls, got {tuple(crops.shape)} and {tuple(mirror_ball.shape)}")
    rows = n // _COLUMNS
    mosaic = crops.reshape(rows, _COLUMNS, 3, _TILE, _TILE).permute(2, 0, 3, 1, 4).reshape(3, rows * _TILE, -1)
    folder = Path(folder)
    write_ldr(folder / "probe.jpg", mosaic.clamp(0, 1), quality=95)
    tensors = {"mirror_ball": mirror_ball.to(torch.bfloat16).contiguous()}
    atomic_write(folder / "probe.safetensors",
                 lambda tmp: safetensors.torch.save_file(tensors, str(tmp), metadata={"meta": json.dumps(meta)}))


@functools.lru_cache(maxsize=2)
def _load(folder: str) -> Probe:
    import safetensors  # lazy: as read_weights

    path = Path(folder)
    with safetensors.safe_open(str(path / "probe.safetensors"), framework="pt") as f:
        mirror_ball = f.get_tensor("mirror_ball").float()
        meta = json.loads((f.metadata() or {}).get("meta", "{}"))
    mosaic = read_ldr(path / "probe.jpg")
    n = mirror_ball.shape[0]
    rows = n // _COLUMNS
    if mosaic.shape != (3, rows * _TILE, _COLUMNS * _TILE):
        raise ValueCheckError(f"probe.jpg in {path} is {tuple(mosaic.shape)}, not the mosaic of {n} crops")
    crops = mosaic.reshape(3, rows, _TILE, _COLUMNS, _TILE).permute(1, 3, 0, 2, 4).reshape(n, 3, _TILE, _TILE)
    return Probe(crops.contiguous(), mirror_ball, meta)


def load_probe(folder: str | os.PathLike[str] | None = None) -> Probe:
    r"""The probe of ``folder`` (default: the shipped one), read once per process.

    Args:
        folder: a folder written by :func:`write_probe`; ``None`` for the probe shipped in ``weights/``.

    Returns:
        the :class:`Probe`, cached and shared between callers: do not modify its tensors.

    Raises:
        HDRIOError: ``probe.jpg`` is missing or unreadable; ``OSError`` for ``probe.safetensors``.

    Examples:
        >>> probe = load_probe()
        >>> len(probe), tuple(probe.part(CHECK).crops.shape)
        (320, (256, 3, 256, 256))
    """
    return _load(str(Path(os.fspath(folder)) if folder is not None else _default_dir()))


@functools.lru_cache(maxsize=2)
def probe_digest(folder: str | os.PathLike[str] | None = None) -> str:
    """The first 12 hex digits of the SHA-256 of the probe's two files: part of the name of every cache file that
    depends on the probe (int8 models, parity verdicts), so a new probe never meets an old verdict.

    Args:
        folder: a folder written by :func:`write_probe`; ``None`` for the probe shipped in ``weights/``.

    Returns:
        12 lowercase hex digits, computed once per process and folder.

    Examples:
        >>> len(probe_digest()), probe_digest() == probe_digest().lower()
        (12, True)
    """
    path = Path(os.fspath(folder)) if folder is not None else _default_dir()
    h = hashlib.sha256()
    for name in ("probe.jpg", "probe.safetensors"):
        h.update((path / name).read_bytes())
    return h.hexdigest()[:12]


def fit_crops(estimator: Any, crops: Tensor) -> Tensor:
    r"""``crops`` at the side that ``estimator`` takes (``estimator.info.input_size``): as they are when they
    have it (or the estimator has no ``info``), else resized by :func:`~kornia_ilum.detection.crop_faces` with
    each whole crop as its box (bilinear, antialiased) and clamped to ``[0, 1]``.

    The eval set's and the probe's crops are 256 px, the paper's size; an estimator that takes another size
    (``sipr``: 128) is scored on the same crops resized to it, as :func:`~kornia_ilum.estimate_lighting` cuts
    its crops at that size.

    Args:
        estimator: a lighting estimator, or anything with ``info.input_size``.
        crops: sRGB face crops in ``[0, 1]``.

    Returns:
        ``crops`` itself when no resize is needed, else a new tensor of the estimator's side.

    Shape:
        - crops: :math:`(N, 3, H, W)`
        - Output: :math:`(N, 3, S, S)`, ``S = estimator.info.input_size`` (the input's shape without ``info``)

    Convention:
        sRGB-encoded values in ``[0, 1]`` (docs/conventions.rst, "Images").

    Examples:
        >>> class Small:
        ...     info = type("Info", (), {"input_size": 128})
        >>> tuple(fit_crops(Small(), torch.rand(2, 3, 256, 256)).shape)
        (2, 3, 128, 128)
    """
    info = getattr(estimator, "info", None)
    size = getattr(info, "input_size", None)
    if size is None or crops.shape[-1] == crops.shape[-2] == size:
        return crops
    n, _, h, w = crops.shape
    whole = torch.tensor([[0.0, 0.0, w, h]], device=crops.device).expand(n, 4)  # each whole crop: a resize
    resized = crop_faces(crops, whole, size=size, index=torch.arange(n, device=crops.device),
                         check_values=False)
    return resized.clamp_(0.0, 1.0)


def probe_lrec(estimator: Any, probe: Probe, batch_size: int = 16) -> dict[str, float]:
    r"""Mean ``L_rec`` per sphere of ``estimator`` against the probe's true lighting.

    Args:
        estimator: a lighting estimator (``crops -> LightingEstimate``); its crops are fitted by :func:`fit_crops`.
        probe: the portraits and their true lighting, e.g. ``load_probe().part(CHECK)``.
        batch_size: crops per forward pass.

    Returns:
        ``{"diffuse", "matte_silver", "mirror"}`` -> mean ``L_rec`` over the probe's portraits.

    Convention:
        docs/conventions.rst, "The paper's error measure L_rec" and "Reference spheres".

    Examples:
        >>> from kornia_ilum.estimators import create_estimator
        >>> sorted(probe_lrec(create_estimator("uniform"), load_probe().part(slice(0, 8))))
        ['diffuse', 'matte_silver', 'mirror']
    """
    preds = []
    with torch.inference_mode():
        for i in range(0, len(probe), batch_size):
            preds.append(estimator(fit_crops(estimator, probe.crops[i : i + batch_size])).mirror_ball.float())
    pred = torch.cat(preds)
    return {b: float(reconstruction_loss(pred, probe.mirror_ball, brdf=b, size=32)) for b in _BRDFS}


def probe_lrec_change(reference: Any, candidate: Any, probe: Probe | None = None) -> float:
    r"""The largest relative change of mean ``L_rec`` (diffuse, matte silver, mirror) from ``reference`` to
    ``candidate`` on the check part of the probe: ``max_k |L_k(candidate) - L_k(reference)| / L_k(reference)``.

    The parity of a reduced-precision runtime (int8, bfloat16) against eager float32: it must stay within
    :data:`~kornia_ilum.estimators.runtime.LREC_RTOL`.

    Args:
        reference: the estimator to compare with, usually eager float32.
        candidate: the estimator to check, e.g. the same weights under another runtime.
        probe: the probe whose :data:`CHECK` part is used; ``None`` for the shipped one.

    Returns:
        the largest relative change over the three spheres; 0 when both score the same.

    Convention:
        docs/conventions.rst, "The paper's error measure L_rec" and "Reference spheres".

    Examples:
        >>> from kornia_ilum.estimators import create_estimator
        >>> net = create_estimator("uniform")
        >>> probe_lrec_change(net, net)
        0.0
    """
    check = (probe or load_probe()).part(CHECK)
    ref, cand = probe_lrec(reference, check), probe_lrec(candidate, check)
    return max(abs(cand[b] - ref[b]) / max(ref[b], 1e-12) for b in _BRDFS)
