r"""Runtimes: the same estimator's estimate, computed by eager PyTorch, in bfloat16, or by ONNX Runtime (float32
or int8).

An estimator is exported as it is, not through a copy of its graph: :func:`export_onnx` hands the estimator
itself to :func:`torch.onnx.export` (the ``torch.export`` path; :class:`~kornia_ilum.estimators.LightingEstimate`
is a pytree node), so the file holds everything between the sRGB crop and the lighting in the units of
docs/conventions.rst: the exposure normalisation, the network, ``exp`` / ``softplus`` and the mirror ball's mask.
Its outputs are named after the estimate's fields (``mirror_ball``, ``valid``, and ``log_mirror_ball`` or ``sh``
where the estimator has them), its batch is dynamic, and its metadata names the estimator and its input size.

:class:`OnnxEstimator` runs such a file with ONNX Runtime behind the estimator contract (``forward(crops) ->
LightingEstimate``, the same input checks), so it goes wherever an estimator goes. :func:`with_runtime` turns a
created estimator into the runtime asked for (``create_estimator(name, runtime=...)``), one of :data:`RUNTIMES`:

- ``"eager"``: the estimator itself, PyTorch in its own dtype (float32);
- ``"bf16"``: :class:`Bf16Estimator`, channels-last and bfloat16 autocast, only where the device computes
  bfloat16 natively (:func:`native_bf16`: a CPU with AVX-512 BF16 or AMX, or CUDA; elsewhere a bfloat16
  matmul is emulated, orders of magnitude slower than float32);
- ``"onnx"``: ONNX Runtime in float32, within :data:`PARITY_ATOL` of eager (:func:`parity`);
- ``"onnx-int8"``: ONNX Runtime with static int8 quantisation (:func:`quantize_int8`: per-channel int8 weights,
  uint8 activations of the convolutions and the fully connected layers, the first convolution kept in float32),
  calibrated on the light-stage training portraits of the shipped probe (:mod:`~kornia_ilum.estimators.probe`),
  within :data:`LREC_RTOL` of eager's ``L_rec`` (:func:`~kornia_ilum.estimators.probe.probe_lrec_change`);
- ``"auto"``: the first of :data:`AUTO_ORDER` that is available here and passes its parity check, else eager.

The exported and quantised models are cached by the digest of the estimator's state, its name and the
versions that made them (:func:`onnx_model`), in :func:`cache_dir`, so the export (seconds to tens of seconds)
is paid once per machine and weights. ``kornia-ilum bench`` measures what each runtime gives on the machine at hand.

ONNX Runtime (``pip install kornia_ilum[onnx]``) is imported only when an ONNX runtime is asked for.
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import json
import logging
import os
import tempfile
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import torch
from torch import Tensor

from kornia_ilum.core.check import check_positive_int, checks_active
from kornia_ilum.core.errors import TypeCheckError, ValueCheckError
from kornia_ilum.core.files import atomic_write
from kornia_ilum.estimators.base import (
    EstimatorInfo,
    LightingEstimate,
    LightingEstimator,
    check_crop_range,
    check_crops,
)
from kornia_ilum.estimators.scene import SceneStrength, scene_input

__all__ = [
    "AUTO_ORDER",
    "ESTIMATE_FIELDS",
    "LREC_RTOL",
    "PARITY_ATOL",
    "RUNTIMES",
    "Bf16Estimator",
    "OnnxEstimator",
    "cache_dir",
    "export_onnx",
    "export_scene_onnx",
    "native_bf16",
    "onnx_model",
    "parity",
    "probe_parity",
    "quantize_int8",
    "runtime_available",
    "runtime_parity",
    "with_runtime",
]

#: The runtimes :func:`with_runtime` knows, ``"auto"`` first.
RUNTIMES: tuple[str, ...] = ("auto", "eager", "bf16", "onnx", "onnx-int8")
#: What ``"auto"`` tries, in order: the fastest first, as ``kornia-ilum bench`` measured them on the project's
#: CPUs (``ours`` at batch 1: int8, then ONNX float32, then bfloat16, then eager; docs/bench.rst).
AUTO_ORDER: tuple[str, ...] = ("onnx-int8", "onnx", "bf16")
#: The fields of :class:`~kornia_ilum.estimators.LightingEstimate` an exported estimator may output, in order.
ESTIMATE_FIELDS: tuple[str, ...] = ("mirror_ball", "valid", "log_mirror_ball", "sh", "log_energy_spread")
#: The largest difference of ``log(1 + L)`` from eager float32 that a float32 runtime may have.
PARITY_ATOL = 1e-4
#: The largest relative change of mean ``L_rec`` (any sphere) from eager float32 that a reduced-precision
#: runtime (``"bf16"``, ``"onnx-int8"``) may have on the probe's check part.
LREC_RTOL = 0.01

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


def _exported(model: torch.nn.Module, probe: Tensor, name: str, outputs: list[str], opset: int) -> Any:
    """The ONNX ``ModelProto`` of ``model`` on one input ``name`` with a dynamic batch (``probe`` shows its
    shape), by :func:`torch.onnx.export` with ``dynamo=True``, its chatter silenced."""
    batch = torch.export.Dim("batch", min=1, max=1 << 16)
    with torch.no_grad(), _quiet_exporter():
        return torch.onnx.export(model, (probe,), input_names=[name], output_names=outputs,
                                 dynamic_shapes=({0: batch},), opset_version=opset, dynamo=True,
                                 verbose=False).model_proto


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
    proto = _exported(model, probe, "crops", fields, opset)
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


def export_scene_onnx(branch: SceneStrength, path: str | os.PathLike[str] | None = None, *,
                      opset: int = _OPSET) -> bytes:
    r"""Export a scene branch to ONNX: :func:`~kornia_ilum.estimators.scene.scene_input`'s frames in,
    ``log_energy`` and ``spread`` out, with a dynamic batch; checked by ONNX Runtime against PyTorch.

    Args:
        branch: a :class:`~kornia_ilum.estimators.SceneStrength` (exported as a float32 CPU copy in eval mode).
        path: also write the model here (atomically), once it passed; ``None`` keeps it in memory only.
        opset: the ONNX opset.

    Returns:
        the serialized model: input ``frames`` :math:`(B, 5, 128, 128)`; outputs ``log_energy`` :math:`(B, 3)`
        and ``spread`` :math:`(B,)`.

    Raises:
        ValueCheckError: ONNX Runtime's outputs differ from PyTorch's by more than :data:`PARITY_ATOL` on a probe
            batch (nothing is written).
        ImportError: the exporter's packages are not installed.
    """
    ort = _onnxruntime()
    model = copy.deepcopy(branch).to("cpu", torch.float32).eval()
    probe = scene_input(torch.rand(3, 3, 96, 128, generator=torch.Generator().manual_seed(0)),
                        torch.tensor([[40.0, 20, 80, 70], [10, 10, 50, 60], [0, 0, 128, 96]]), torch.arange(3))
    data = _exported(model, probe, "frames", ["log_energy", "spread"], opset).SerializeToString()
    with torch.no_grad():
        want = model(probe)
    got = ort.InferenceSession(data, providers=["CPUExecutionProvider"]).run(None, {"frames": probe.numpy()})
    gap = max(float((torch.from_numpy(g) - w).abs().max()) for g, w in zip(got, want, strict=True))
    if not gap <= PARITY_ATOL:
        raise ValueCheckError(f"the scene branch's ONNX export differs from PyTorch by {gap:.3g} (at most "
                              f"{PARITY_ATOL:g}); nothing was written")
    if path is not None:
        atomic_write(Path(os.fspath(path)), lambda tmp: tmp.write_bytes(data))
    return data


class OnnxEstimator(LightingEstimator):
    r"""An exported estimator (:func:`export_onnx`) run by ONNX Runtime, behind the estimator contract.

    ``forward`` checks the crops as every estimator does, runs the session on the CPU in float32 and returns a
    :class:`~kornia_ilum.estimators.LightingEstimate` on the crops' device, in float32. The value scan of the
    crops runs in NumPy, on one thread: a parallel PyTorch reduction just before the session left PyTorch's
    OpenMP threads spinning against ONNX Runtime's and doubled the time of a batch of one (docs/bench.rst).

    Args:
        model: the ONNX model: its bytes, or a path to a ``.onnx`` file written by :func:`export_onnx` (or
            :func:`quantize_int8`).
        info: the estimator's metadata (by default one made from the model's own: its name and input size).
        threads: ONNX Runtime's intra-op threads (``None``: its default, one per physical core).
        runtime: the name the runtime goes by (``"onnx"`` or ``"onnx-int8"``), for ``repr`` and ``bench``.

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
                 threads: int | None = None, runtime: str = "onnx") -> None:
        super().__init__()
        ort = _onnxruntime()
        if threads is not None:
            check_positive_int(threads, "threads")
        data = model if isinstance(model, bytes) else Path(os.fspath(model)).read_bytes()
        options = ort.SessionOptions()
        if threads is not None:
            options.intra_op_num_threads = threads
        # no spinning between runs: ONNX Runtime's idle threads would spin against PyTorch's and OpenCV's in a
        # pipeline (kornia-ilum bench: Haar's detection took a third longer beside a spinning session)
        options.add_session_config_entry("session.intra_op.allow_spinning", "0")
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
        self.runtime = runtime

    def forward(self, crops: Tensor, *, check_values: bool = True) -> LightingEstimate:
        check_crops(crops, self.info.input_size, values=False)
        feed = crops.detach().to("cpu", torch.float32).contiguous().numpy()
        if check_values and checks_active():
            check_crop_range(float(feed.min()), float(feed.max()))  # NumPy: one thread (class docstring)
        return self._run(feed, crops.device)

    def predict(self, crops: Tensor) -> LightingEstimate:
        return self._run(crops.detach().to("cpu", torch.float32).contiguous().numpy(), crops.device)

    def _run(self, feed: Any, device: torch.device) -> LightingEstimate:
        outputs = self.session.run(list(self.fields), {"crops": feed})
        return LightingEstimate(**{name: torch.from_numpy(out).to(device) for name, out in zip(self.fields, outputs)})

    def extra_repr(self) -> str:
        return f"estimator={self.info.name!r}, runtime={self.runtime!r}, outputs={self.fields}"


def native_bf16(device: str | torch.device = "cpu") -> bool:
    r"""Whether ``device`` computes bfloat16 natively: CUDA, or a CPU with AVX-512 BF16 or AMX (oneDNN's check).

    Elsewhere (an AVX2-only CPU such as AMD Zen 3) bfloat16 is emulated, orders of magnitude slower than float32.

    Args:
        device: the device to ask about; any device other than CUDA or the CPU has no native bfloat16 here.

    Returns:
        ``True`` where the ``"bf16"`` runtime may run (:func:`runtime_available`).

    Examples:
        >>> isinstance(native_bf16(), bool)
        True
    """
    device = torch.device(device)
    if device.type == "cuda":
        return True
    return device.type == "cpu" and bool(torch.ops.mkldnn._is_mkldnn_bf16_supported())


class Bf16Estimator(LightingEstimator):
    r"""An estimator run channels-last under bfloat16 autocast; the estimate comes back in float32.

    The networks' convolutions and matrix products run in bfloat16 (autocast's list), the rest as the estimator
    has it (``ours`` keeps its exposure normalisation and output in float32). Its parity with eager float32 is
    ``L_rec``'s (:data:`LREC_RTOL`), not the float32 runtimes' :data:`PARITY_ATOL`.

    Args:
        estimator: the estimator (converted to channels-last in place).

    Examples:
        >>> from kornia_ilum.estimators import create_estimator
        >>> fast = Bf16Estimator(create_estimator("ours", pretrained=False))
        >>> fast(torch.rand(1, 3, 256, 256)).mirror_ball.dtype
        torch.float32
    """

    info = EstimatorInfo("bf16", "an estimator under bfloat16 autocast", "none: a runtime", needs_weights=False)

    def __init__(self, estimator: LightingEstimator) -> None:
        super().__init__()
        self.estimator = _check_estimator(estimator).to(memory_format=torch.channels_last)
        self.info = estimator.info  # type: ignore[misc]  # per instance: the wrapped estimator's
        self.runtime = "bf16"

    def predict(self, crops: Tensor) -> LightingEstimate:
        crops = crops.contiguous(memory_format=torch.channels_last)
        with torch.autocast(crops.device.type, dtype=torch.bfloat16):
            est = self.estimator.predict(crops)
        fields = {f: getattr(est, f) for f in ESTIMATE_FIELDS if getattr(est, f) is not None}
        return LightingEstimate(**{f: (v.float().contiguous() if v.is_floating_point() else v)
                                   for f, v in fields.items()})


def quantize_int8(model: bytes, calibration: Tensor) -> bytes:
    r"""Static int8 quantisation of an exported estimator, calibrated on ``calibration``'s crops.

    ONNX Runtime's :func:`~onnxruntime.quantization.quantize_static` in QDQ form: per-channel symmetric int8
    weights and uint8 activations (min-max ranges over ``calibration``) for the **encoder**: the convolutions
    after the first one and before the first fully connected layer (``Gemm``). The first convolution stays
    float32 (three input channels: in int8 it cost three times its float32 time), and so do the fully connected
    layers and everything after them (the decoder, whose rounding lands on the log radiance itself), the
    exposure normalisation, resampling matrices and ``exp``. The layers were chosen on ``ours`` and the 1024
    portraits of the eval split (``kornia-ilum evaluate --runtime onnx-int8``), with an earlier calibration set
    of 32 crops: every convolution and ``Gemm`` but the first in int8 moved diffuse ``L_rec`` by +1.27 %, the
    encoder alone by +0.79 %, for a tenth more time per crop. With the shipped probe's calibration part the
    encoder-only model moves it by more (docs/bench.rst): ``auto`` takes int8 only where the probe's check
    part says it stays within :data:`LREC_RTOL`.

    Args:
        model: from :func:`export_onnx`.
        calibration: ``(N, 3, S, S)`` sRGB crops at the model's input size, from the training distribution
            (the probe's :data:`~kornia_ilum.estimators.probe.CALIBRATION` part), never the eval split.

    Returns:
        the quantised model, with the exported model's metadata.

    Raises:
        ValueCheckError: the model has no convolution before a fully connected layer (nothing to quantise).
        ImportError: ONNX Runtime or ONNX is not installed.

    Shape:
        - calibration: :math:`(N, 3, S, S)`, ``S`` the model's ``input_size``; read in batches of 8

    Convention:
        Crops are sRGB-encoded in ``[0, 1]`` (docs/conventions.rst, "Images").

    Examples:
        >>> from kornia_ilum.estimators import create_estimator
        >>> from kornia_ilum.estimators.probe import CALIBRATION, load_probe
        >>> model = export_onnx(create_estimator("ours"))  # doctest: +SKIP
        >>> int8 = OnnxEstimator(quantize_int8(model, load_probe().part(CALIBRATION).crops),
        ...                      runtime="onnx-int8")  # doctest: +SKIP
    """
    _onnxruntime()
    import onnx  # lazy, as all of ONNX: only for this runtime
    from onnxruntime import quantization as q  # lazy: the same
    from onnxruntime.quantization.shape_inference import quant_pre_process  # lazy: the same

    batches = [{"crops": calibration[i : i + 8].float().contiguous().numpy()} for i in range(0, len(calibration), 8)]

    class _Reader(q.CalibrationDataReader):
        def __init__(self) -> None:
            self.items = iter(batches)

        def get_next(self) -> dict | None:
            return next(self.items, None)

    proto = onnx.load_from_string(model)
    encoder = []
    for node in proto.graph.node:  # topological order
        if node.op_type in ("Gemm", "MatMul"):
            break
        if node.op_type == "Conv":
            encoder.append(node.name)
    if len(encoder) < 2:
        raise ValueCheckError("the model has no convolution between its first one and its first fully connected "
                              "layer: nothing for the int8 runtime to quantise")
    with tempfile.TemporaryDirectory(prefix="kornia_ilum_int8_") as tmp, _quiet_exporter():
        src, pre, out = (Path(tmp) / f for f in ("model.onnx", "pre.onnx", "int8.onnx"))
        src.write_bytes(model)
        quant_pre_process(str(src), str(pre), skip_symbolic_shape=True)
        q.quantize_static(str(pre), str(out), _Reader(), quant_format=q.QuantFormat.QDQ, per_channel=True,
                          activation_type=q.QuantType.QUInt8, weight_type=q.QuantType.QInt8,
                          op_types_to_quantize=["Conv"], nodes_to_quantize=encoder[1:])
        quantized = onnx.load(str(out))
    del quantized.metadata_props[:]
    quantized.metadata_props.extend(proto.metadata_props)
    return quantized.SerializeToString()


def cache_dir() -> Path:
    r"""Where exported models are cached: ``$KORNIA_ILUM_CACHE``, else ``$XDG_CACHE_HOME/kornia_ilum``, else
    ``~/.cache/kornia_ilum``. Nothing is written there until a model is exported.

    Returns:
        the folder, read from the environment on each call; it may not exist yet.

    Examples:
        >>> cache_dir().name in ("kornia_ilum",) or "KORNIA_ILUM_CACHE" in os.environ
        True
    """
    if os.environ.get("KORNIA_ILUM_CACHE"):
        return Path(os.environ["KORNIA_ILUM_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "kornia_ilum"


def _state_digest(estimator: LightingEstimator) -> str:
    """SHA-256 of the estimator's class, input size and state (names, dtypes, shapes, values)."""
    h = hashlib.sha256(f"{type(estimator).__module__}.{type(estimator).__qualname__}:"
                       f"{estimator.info.input_size}".encode())
    for name, value in sorted(estimator.state_dict().items()):
        t = value.detach().to("cpu").contiguous()
        h.update(f"{name}:{t.dtype}:{tuple(t.shape)}".encode())
        h.update(t.reshape(-1).view(torch.uint8).numpy().tobytes())
    return h.hexdigest()


def onnx_model(estimator: LightingEstimator, runtime: str = "onnx", *, cache: bool = True) -> bytes:
    r"""The exported model of ``estimator`` for an ONNX runtime (``"onnx"`` or ``"onnx-int8"``), from the cache.

    The cache file is named after the estimator, the runtime, the digest of the estimator's state (so new
    weights never meet an old export) and the versions of PyTorch, ONNX Runtime and the opset; it is written
    atomically. A cache file that ONNX cannot parse is made again. Where the cache folder cannot be written
    the model is made in memory (with a warning).

    Args:
        estimator: the estimator.
        runtime: ``"onnx"`` (:func:`export_onnx`) or ``"onnx-int8"`` (then :func:`quantize_int8` on the probe's
            calibration part).
        cache: read and write :func:`cache_dir`; ``False`` always exports.

    Returns:
        the serialized ONNX model, as :func:`export_onnx` (or :func:`quantize_int8`) returns it.

    Raises:
        ValueCheckError: another runtime.
        ImportError: ONNX Runtime or the exporter's packages are not installed.

    Examples:
        >>> from kornia_ilum.estimators import create_estimator
        >>> onnx_model(create_estimator("uniform"), "bf16")
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: runtime must be 'onnx' or 'onnx-int8', got 'bf16'
        >>> model = onnx_model(create_estimator("ours"), "onnx-int8")  # doctest: +SKIP
    """
    _check_estimator(estimator)
    if runtime not in ("onnx", "onnx-int8"):
        raise ValueCheckError(f"runtime must be 'onnx' or 'onnx-int8', got {runtime!r}")
    _onnxruntime()
    path = _cache_path(estimator, runtime, ".onnx")
    if cache and path.is_file():
        data = path.read_bytes()
        if _parses(data):
            return data
    data = export_onnx(estimator)
    if runtime == "onnx-int8":
        from kornia_ilum.estimators.probe import CALIBRATION, fit_crops, load_probe  # lazy: reads the probe

        data = quantize_int8(data, fit_crops(estimator, load_probe().part(CALIBRATION).crops))
    if cache:
        _cache_write(path, data)
    return data


def _cache_path(estimator: LightingEstimator, runtime: str, suffix: str) -> Path:
    """The cache file of ``estimator`` under ``runtime``: named after everything that decides its content."""
    versions = f"torch{torch.__version__}-opset{_OPSET}"
    if runtime.startswith("onnx"):
        versions += f"-ort{_onnxruntime().__version__}"
    if suffix == ".json":  # a parity check's result also depends on the CPU's kernels
        versions += f"-{torch.backends.cpu.get_cpu_capability()}"
    if suffix == ".json" or runtime == "onnx-int8":  # calibrated or checked on the probe
        from kornia_ilum.estimators.probe import probe_digest  # lazy: reads the probe

        versions += f"-probe{probe_digest()}"
    name = f"{estimator.info.name}-{runtime}-{_state_digest(estimator)[:16]}-{versions}".replace("+", "_")
    return cache_dir() / ("onnx" if suffix == ".onnx" else "parity") / f"{name}{suffix}"


def _cache_write(path: Path, data: bytes) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, lambda tmp: tmp.write_bytes(data))
    except OSError as e:
        warnings.warn(f"could not write the cache file {path} ({e}); set KORNIA_ILUM_CACHE to a writable folder",
                      RuntimeWarning, stacklevel=3)


def _parses(data: bytes) -> bool:
    import onnx  # lazy: as ONNX Runtime

    try:
        onnx.load_from_string(data)
    except Exception:  # a truncated or foreign file: made again
        return False
    return True


def parity(reference: LightingEstimator, candidate: LightingEstimator, crops: Tensor) -> float:
    r"""The largest difference of ``log(1 + L)`` between two estimators on the same crops (0 where equal).

    Compares in log space, as the estimates are read and scored, so a bright light and the dark do not weigh
    by their radiance.

    Args:
        reference: the estimator to compare with, usually eager float32.
        candidate: the estimator to check, e.g. the same weights under another runtime.
        crops: the face crops both estimate from, at their input size.

    Returns:
        ``max |log(1 + L_reference) - log(1 + L_candidate)|`` over the mirror balls' pixels and channels
        (negative radiance clamped to 0), compared with :data:`PARITY_ATOL` by the float32 runtimes.

    Shape:
        - crops: :math:`(B, 3, S, S)`, ``S`` the estimators' ``info.input_size``

    Convention:
        Crops are sRGB in ``[0, 1]`` (docs/conventions.rst, "Images"); ``L`` is the mirror ball's linear radiance
        (docs/conventions.rst, "Mirror ball" and "Units of lighting"), ``log`` the natural log.

    Examples:
        >>> from kornia_ilum.estimators import create_estimator
        >>> net = create_estimator("ours", pretrained=False).eval()
        >>> parity(net, net, torch.rand(1, 3, 256, 256))
        0.0
    """
    with torch.no_grad():
        a, b = reference(crops).mirror_ball.float(), candidate(crops).mirror_ball.float()
    return float((torch.log1p(a.clamp(min=0)) - torch.log1p(b.clamp(min=0))).abs().amax())


def probe_parity(reference: LightingEstimator, candidate: LightingEstimator) -> float:
    r""":func:`parity` on the probe batch every float32 runtime is checked on: 4 seeded random crops of the
    reference's input size (``with_runtime("auto")`` and ``kornia-ilum export`` use it).

    Args:
        reference: the estimator to compare with, usually eager float32; its ``info.input_size`` sets the crops'.
        candidate: the estimator to check.

    Returns:
        :func:`parity` of the two on the seeded crops, the same crops on every call.

    Examples:
        >>> from kornia_ilum.estimators import create_estimator
        >>> net = create_estimator("uniform")
        >>> probe_parity(net, net)
        0.0
    """
    size = reference.info.input_size
    return parity(reference, candidate, torch.rand(4, 3, size, size, generator=torch.Generator().manual_seed(0)))


def runtime_parity(reference: LightingEstimator, candidate: LightingEstimator, runtime: str) -> tuple[float, float, bool]:
    r"""The parity check of ``runtime``: ``(value, tolerance, passed)``.

    Float32 runtimes (``"eager"``, ``"onnx"``): :func:`probe_parity` within :data:`PARITY_ATOL`. Reduced
    precision (``"bf16"``, ``"onnx-int8"``): :func:`~kornia_ilum.estimators.probe.probe_lrec_change` within
    :data:`LREC_RTOL`.

    Args:
        reference: the estimator under eager float32.
        candidate: the same estimator under ``runtime``.
        runtime: which check applies; any name but ``"bf16"`` and ``"onnx-int8"`` gets the float32 one.

    Returns:
        ``(value, tolerance, passed)``: the measured difference, the tolerance it is held to and
        ``value <= tolerance``.

    Examples:
        >>> from kornia_ilum.estimators import create_estimator
        >>> net = create_estimator("uniform")
        >>> value, tolerance, passed = runtime_parity(net, net, "onnx")
        >>> value, tolerance == PARITY_ATOL, passed
        (0.0, True, True)
    """
    if runtime in ("bf16", "onnx-int8"):
        from kornia_ilum.estimators.probe import probe_lrec_change  # lazy: reads the probe

        value, tol = probe_lrec_change(reference, candidate), LREC_RTOL
    else:
        value, tol = probe_parity(reference, candidate), PARITY_ATOL
    return value, tol, value <= tol


def _passes(reference: LightingEstimator, candidate: LightingEstimator, runtime: str, cache: bool) -> bool:
    """:func:`runtime_parity`'s verdict, cached beside the exports (the int8 and bfloat16 checks take seconds)."""
    path = _cache_path(reference, runtime, ".json")
    if cache and path.is_file():
        try:
            return bool(json.loads(path.read_text())["passed"])
        except (ValueError, KeyError, OSError):
            pass  # a damaged verdict: checked again
    value, tol, passed = runtime_parity(reference, candidate, runtime)
    if cache:
        _cache_write(path, json.dumps({"runtime": runtime, "value": value, "tolerance": tol,
                                       "passed": passed}).encode())
    return passed


def runtime_available(runtime: str, device: str | torch.device = "cpu") -> str | None:
    r"""``None`` where ``runtime`` can run on ``device``, else the reason it cannot.

    Args:
        runtime: one of :data:`RUNTIMES`.
        device: where the estimator runs.

    Returns:
        ``None`` where it can run; else one line saying why not (no native bfloat16, not the CPU, ONNX Runtime
        not installed, with its install hint).

    Raises:
        ValueCheckError: ``runtime`` is not one of :data:`RUNTIMES`.

    Examples:
        >>> runtime_available("eager") is None
        True
        >>> runtime_available("onnx", "meta")
        'the ONNX runtimes run on the CPU'
    """
    if runtime not in RUNTIMES:
        raise ValueCheckError(f"runtime must be one of {', '.join(RUNTIMES)}, got {runtime!r}")
    if runtime == "bf16" and not native_bf16(device):
        return f"{torch.device(device)} has no native bfloat16 (it would be emulated, slower than float32)"
    if runtime.startswith("onnx"):
        if torch.device(device).type != "cpu":
            return "the ONNX runtimes run on the CPU"
        try:
            _onnxruntime()
        except ImportError as e:
            return str(e)
    return None


def with_runtime(estimator: LightingEstimator, runtime: str = "eager", *, threads: int | None = None,
                 cache: bool = True, order: Sequence[str] = AUTO_ORDER) -> LightingEstimator:
    r"""The estimator computed by another runtime (one of :data:`RUNTIMES`; the module docstring).

    ``"auto"`` takes the first of ``order`` (:data:`AUTO_ORDER`) that :func:`runtime_available` allows here and
    that passes :func:`runtime_parity`, else the estimator itself; the runtime chosen is the result's ``runtime``
    attribute. A runtime asked for by name is not checked here (``kornia-ilum export`` and the tests check it).

    Args:
        estimator: a created estimator (on the CPU for the ONNX runtimes).
        runtime: the runtime.
        threads: ONNX Runtime's intra-op threads.
        cache: use the export cache (:func:`onnx_model`).
        order: the runtimes ``"auto"`` tries, in order (any of :data:`RUNTIMES` but ``"auto"`` and ``"eager"``).

    Returns:
        ``estimator`` itself for ``"eager"`` (and for ``"auto"`` where nothing else passes), else a new
        :class:`Bf16Estimator` or :class:`OnnxEstimator` around it.

    Raises:
        ValueCheckError: an unknown runtime (the message lists :data:`RUNTIMES`), one that cannot run here
            (the message says why), or an ``order`` beyond :data:`AUTO_ORDER`.
        ImportError: an ONNX runtime without ONNX Runtime.

    Examples:
        >>> from kornia_ilum.estimators import create_estimator
        >>> net = create_estimator("uniform")
        >>> with_runtime(net, "eager") is net
        True
        >>> with_runtime(net, "auto", order=()) is net  # nothing to try: eager
        True
    """
    _check_estimator(estimator)
    if runtime not in RUNTIMES:
        raise ValueCheckError(f"runtime must be one of {', '.join(RUNTIMES)}, got {runtime!r}")
    device = next((p.device for p in estimator.parameters()), torch.device("cpu"))
    if runtime == "auto":
        if not set(order) <= set(AUTO_ORDER):
            raise ValueCheckError(f"order must hold runtimes of {', '.join(AUTO_ORDER)}, got {tuple(order)}")
        for candidate in order:
            if runtime_available(candidate, device) is not None:
                continue
            try:
                fast = with_runtime(copy.deepcopy(estimator) if candidate == "bf16" else estimator, candidate,
                                    threads=threads, cache=cache)
            except ValueCheckError:  # no form for this runtime (int8 of a model without an encoder)
                continue
            if _passes(estimator, fast, candidate, cache):
                return fast
        return estimator
    if runtime == "eager":
        return estimator
    if runtime == "bf16":
        reason = runtime_available("bf16", device)
        if reason is not None:
            raise ValueCheckError(f"runtime 'bf16' cannot run here: {reason}")
        return Bf16Estimator(estimator)
    _onnxruntime()  # the install hint first
    if device.type != "cpu":
        raise ValueCheckError(f"runtime {runtime!r} runs on the CPU; the estimator is on {device}")
    return OnnxEstimator(onnx_model(estimator, runtime, cache=cache), info=estimator.info, threads=threads,
                         runtime=runtime)
