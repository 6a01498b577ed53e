r"""Runtimes: the same estimator's estimate, computed by eager PyTorch or by ONNX Runtime.

An estimator is exported as it is, not through a copy of its graph: :func:`export_onnx` hands the estimator
itself to :func:`torch.onnx.export` (the ``torch.export`` path; :class:`~kornia_ilum.estimators.LightingEstimate`
is a pytree node), so the file holds everything between the sRGB crop and the lighting in the units of
docs/conventions.rst: the exposure normalisation, the network, ``exp`` / ``softplus`` and the mirror ball's mask.
Its outputs are named after the estimate's fields (``mirror_ball``, ``valid``, and ``log_mirror_ball`` or ``sh``
where the estimator has them), its batch is dynamic, and its metadata names the estimator and its input size.

:class:`OnnxEstimator` runs such a file with ONNX Runtime behind the estimator contract (``forward(crops) ->
LightingEstimate``, the same input checks), so it goes wherever an estimator goes. :func:`with_runtime` turns a
created estimator into the runtime asked for (``create_estimator(name, runtime=...)``); ``"auto"`` takes ONNX
Runtime where it is installed and the exported estimator passes :func:`parity` on a probe batch, else eager.

ONNX Runtime (``pip install kornia_ilum[onnx]``) is imported only when a runtime other than eager is asked for.
"""

from __future__ import annotations

import contextlib
import copy
import logging
import os
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import torch
from torch import Tensor

from kornia_ilum.core.check import check_positive_int
from kornia_ilum.core.errors import TypeCheckError, ValueCheckError
from kornia_ilum.core.files import atomic_write
from kornia_ilum.estimators.base import EstimatorInfo, LightingEstimate, LightingEstimator

__all__ = [
    "ESTIMATE_FIELDS",
    "PARITY_ATOL",
    "RUNTIMES",
    "OnnxEstimator",
    "export_onnx",
    "parity",
    "probe_parity",
    "with_runtime",
]

#: The runtimes :func:`with_runtime` knows, ``"auto"`` first.
RUNTIMES: tuple[str, ...] = ("auto", "eager", "onnx")
#: The fields of :class:`~kornia_ilum.estimators.LightingEstimate` an exported estimator may output, in order.
ESTIMATE_FIELDS: tuple[str, ...] = ("mirror_ball", "valid", "log_mirror_ball", "sh")
#: The largest difference of ``log(1 + L)`` from eager float32 that a float32 runtime may have.
PARITY_ATOL = 1e-4

_OPSET = 18


def _onnxruntime() -> Any:
    try:
        import onnxruntime  # lazy: only a non-eager runtime needs it
    except ImportError as e:
        raise ImportError(
            "the onnx runtime needs ONNX Runtime and the ONNX exporter: pip install 'kornia_ilum[onnx]' "
            "(onnx, onnxruntime, onnxscript)"
        ) from e
    return onnxruntime


def _check_estimator(estimator: object) -> LightingEstimator:
    if not isinstance(estimator, LightingEstimator):
        raise TypeCheckError(f"estimator must be a LightingEstimator instance, got {type(estimator).__name__}")
    return estimator


@contextlib.contextmanager
def _quiet_exporter() -> Iterator[None]:
    """The exporter's chatter (skipped torchvision ops, deduplication notes, torch's own deprecations) off."""
    loggers = [logging.getLogger(n) for n in ("torch.onnx", "torch.export", "onnx_ir", "onnxscript")]
    levels = [lg.level for lg in loggers]
    try:
        for lg in loggers:
            lg.setLevel(logging.ERROR)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)
            warnings.simplefilter("ignore", DeprecationWarning)
            yield
    finally:
        for lg, level in zip(loggers, levels):
            lg.setLevel(level)


def export_onnx(
    estimator: LightingEstimator, path: str | os.PathLike[str] | None = None, *, opset: int = _OPSET
) -> bytes:
    r"""Export an estimator to ONNX: sRGB crops in, the estimate's fields out, with a dynamic batch.

    The estimator is exported in ``eval()`` mode on the CPU in float32 (a copy: the one given is not changed)
    by :func:`torch.onnx.export` with ``dynamo=True``.

    Args:
        estimator: any :class:`~kornia_ilum.estimators.LightingEstimator`.
        path: also write the model here (atomically); ``None`` keeps it in memory only.
        opset: the ONNX opset.

    Returns:
        the serialized ONNX model. Input ``crops`` :math:`(B, 3, S, S)`; outputs the estimate's fields that
        the estimator fills, in the order of :data:`ESTIMATE_FIELDS`; metadata ``estimator`` (the registry
        name), ``input_size`` and ``outputs`` (comma-separated).

    Raises:
        TypeCheckError: ``estimator`` is not a LightingEstimator.
        ValueCheckError: the estimator's graph fixes the batch size (it reads it as a Python ``int``).
        ImportError: the exporter's packages are not installed.

    Examples:
        >>> from kornia_ilum.estimators import create_estimator
        >>> model = export_onnx(create_estimator("uniform"))  # doctest: +SKIP
    """
    _check_estimator(estimator)
    check_positive_int(opset, "opset")
    _onnxruntime()  # the same install hint as running it
    model = copy.deepcopy(estimator).to("cpu", torch.float32).eval()
    size = model.info.input_size
    probe = torch.rand(2, 3, size, size, generator=torch.Generator().manual_seed(0))
    with torch.no_grad():
        fields = [f for f in ESTIMATE_FIELDS if getattr(model(probe), f) is not None]
    batch = torch.export.Dim("batch", min=1, max=1 << 16)
    with torch.no_grad(), _quiet_exporter():
        program = torch.onnx.export(model, (probe,), input_names=["crops"], output_names=fields,
                                    dynamic_shapes=({0: batch},), opset_version=opset, dynamo=True,
                                    verbose=False)
    proto = program.model_proto
    first = proto.graph.input[0].type.tensor_type.shape.dim[0]
    if not first.dim_param:  # the exporter fell back to the probe's batch: something in predict fixes it
        raise ValueCheckError(f"estimator '{model.info.name}' exports with a fixed batch of {first.dim_value}: "
                              "its predict turns the batch size into a Python int (len(x), int(x.shape[0])); "
                              "use x.shape[0]")
    meta = {"estimator": model.info.name, "input_size": str(size), "outputs": ",".join(fields)}
    for key, value in meta.items():
        entry = proto.metadata_props.add()
        entry.key, entry.value = f"kornia_ilum.{key}", value
    data = proto.SerializeToString()
    if path is not None:
        atomic_write(Path(os.fspath(path)), lambda tmp: tmp.write_bytes(data))
    return data


class OnnxEstimator(LightingEstimator):
    r"""An exported estimator (:func:`export_onnx`) run by ONNX Runtime, behind the estimator contract.

    ``forward`` checks the crops as every estimator does, runs the session on the CPU in float32 and returns a
    :class:`~kornia_ilum.estimators.LightingEstimate` on the crops' device, in float32.

    Args:
        model: the ONNX model: its bytes, or a path to a ``.onnx`` file written by :func:`export_onnx`.
        info: the estimator's metadata (by default one made from the model's own: its name and input size).
        threads: ONNX Runtime's intra-op threads (``None``: its default, one per physical core).

    Raises:
        ValueCheckError: the model was not written by :func:`export_onnx` (no ``kornia_ilum`` metadata).
        ImportError: ONNX Runtime is not installed.

    Examples:
        >>> from kornia_ilum.estimators import create_estimator
        >>> onnx = OnnxEstimator(export_onnx(create_estimator("ours", pretrained=False)))  # doctest: +SKIP
    """

    info = EstimatorInfo("onnx", "an exported estimator run by ONNX Runtime", "none: a runtime",
                         needs_weights=False)

    def __init__(self, model: bytes | str | os.PathLike[str], info: EstimatorInfo | None = None,
                 threads: int | None = None) -> None:
        super().__init__()
        ort = _onnxruntime()
        if threads is not None:
            check_positive_int(threads, "threads")
        data = model if isinstance(model, bytes) else Path(os.fspath(model)).read_bytes()
        options = ort.SessionOptions()
        if threads is not None:
            options.intra_op_num_threads = threads
        self.session = ort.InferenceSession(data, options, providers=["CPUExecutionProvider"])
        meta = self.session.get_modelmeta().custom_metadata_map
        if "kornia_ilum.outputs" not in meta:
            raise ValueCheckError("the ONNX model was not written by kornia_ilum's export_onnx: it has no "
                                  "kornia_ilum.* metadata naming its outputs")
        self.fields = tuple(meta["kornia_ilum.outputs"].split(","))
        self.info = info or EstimatorInfo(  # type: ignore[misc]  # per instance: the exported estimator's
            name=meta["kornia_ilum.estimator"], description="an exported estimator run by ONNX Runtime",
            paper="see the estimator's own", input_size=int(meta["kornia_ilum.input_size"]),
            needs_weights=False)
        self.runtime = "onnx"

    def predict(self, crops: Tensor) -> LightingEstimate:
        feed = crops.detach().to("cpu", torch.float32).contiguous().numpy()
        outputs = self.session.run(list(self.fields), {"crops": feed})
        found = {name: torch.from_numpy(out).to(crops.device) for name, out in zip(self.fields, outputs)}
        return LightingEstimate(**found)

    def extra_repr(self) -> str:
        return f"estimator={self.info.name!r}, outputs={self.fields}"


def parity(reference: LightingEstimator, candidate: LightingEstimator, crops: Tensor) -> float:
    r"""The largest difference of ``log(1 + L)`` between two estimators on the same crops (0 where equal).

    Compares in log space, as the estimates are read and scored, so a bright light and the dark do not weigh
    by their radiance.

    Examples:
        >>> from kornia_ilum.estimators import create_estimator
        >>> net = create_estimator("ours", pretrained=False).eval()
        >>> parity(net, net, torch.rand(1, 3, 256, 256))
        0.0
    """
    with torch.no_grad():
        a, b = reference(crops).mirror_ball.float(), candidate(crops).mirror_ball.float()
    return float((torch.log1p(a.clamp(min=0)) - torch.log1p(b.clamp(min=0))).abs().amax())


def with_runtime(estimator: LightingEstimator, runtime: str = "eager", *, threads: int | None = None) -> LightingEstimator:
    r"""The estimator computed by another runtime: ``"eager"`` (itself), ``"onnx"``, or ``"auto"``.

    ``"auto"`` exports to ONNX where ONNX Runtime is installed and keeps it only if it passes :func:`parity`
    within :data:`PARITY_ATOL` on a seeded probe batch; otherwise, and where ONNX Runtime is missing, the
    estimator itself.

    Raises:
        ValueCheckError: an unknown runtime (the message lists :data:`RUNTIMES`).
        ImportError: ``"onnx"`` without ONNX Runtime.

    Examples:
        >>> from kornia_ilum.estimators import create_estimator
        >>> net = create_estimator("uniform")
        >>> with_runtime(net, "eager") is net
        True
    """
    _check_estimator(estimator)
    if runtime not in RUNTIMES:
        raise ValueCheckError(f"runtime must be one of {', '.join(RUNTIMES)}, got {runtime!r}")
    if runtime == "eager":
        return estimator
    if runtime == "auto":
        try:
            _onnxruntime()
        except ImportError:
            return estimator
    fast = OnnxEstimator(export_onnx(estimator), info=estimator.info, threads=threads)
    if runtime == "auto" and probe_parity(estimator, fast) > PARITY_ATOL:
        return estimator
    return fast


def probe_parity(reference: LightingEstimator, candidate: LightingEstimator) -> float:
    r""":func:`parity` on the probe batch every runtime is checked on: 4 seeded random crops of the
    reference's input size (``with_runtime("auto")`` and ``kornia-ilum export`` use it)."""
    size = reference.info.input_size
    return parity(reference, candidate, torch.rand(4, 3, size, size, generator=torch.Generator().manual_seed(0)))
