"""kornia_ilum.estimators.runtime: every estimator exported to ONNX and run by ONNX Runtime, at parity."""

from __future__ import annotations

import onnx
import pytest
import torch

from kornia_ilum.core.check import check_tensor
from kornia_ilum.core.errors import NonFiniteError, TypeCheckError, ValueCheckError
from kornia_ilum.estimators import (
    LREC_RTOL,
    PARITY_ATOL,
    Bf16Estimator,
    LightingEstimate,
    OnnxEstimator,
    create_estimator,
    export_onnx,
    native_bf16,
    onnx_model,
    parity,
    runtime_available,
    runtime_parity,
    with_runtime,
)
from kornia_ilum.estimators import runtime as runtime_module

NAMES = ("ours", "sh", "sipr", "uniform")


@pytest.fixture(scope="module")
def exported() -> dict[str, tuple[torch.nn.Module, bytes]]:
    """Each shipped estimator and its ONNX export (about 5 s each)."""
    torch.manual_seed(0)
    out = {}
    for name in NAMES:
        est = create_estimator(name)
        out[name] = (est, export_onnx(est))
    return out


def _crops(est: torch.nn.Module, batch: int, seed: int = 1) -> torch.Tensor:
    size = est.info.input_size
    return torch.rand(batch, 3, size, size, generator=torch.Generator().manual_seed(seed))


@pytest.mark.parametrize("name", NAMES)
def test_every_estimator_runs_under_onnx_runtime_at_parity_with_a_dynamic_batch(exported, name) -> None:
    est, model = exported[name]
    fast = OnnxEstimator(model, info=est.info, threads=1)
    for batch in (1, 5):  # exported at 2
        crops = _crops(est, batch)
        assert parity(est, fast, crops) <= PARITY_ATOL
        ref, got = est(crops), fast(crops)
        for field in ("mirror_ball", "log_mirror_ball", "sh"):
            a, b = getattr(ref, field), getattr(got, field)
            assert (a is None) == (b is None), field
            if a is not None:
                assert b.shape == a.shape and b.dtype == torch.float32
        assert torch.equal(got.valid, ref.valid)


@pytest.mark.parametrize("name", NAMES)
def test_the_file_names_its_outputs_after_the_estimate_and_carries_the_mask(exported, name) -> None:
    est, model = exported[name]
    proto = onnx.load_from_string(model)
    meta = {p.key: p.value for p in proto.metadata_props}
    outputs = [o.name for o in proto.graph.output]
    assert meta["kornia_ilum.estimator"] == name and meta["kornia_ilum.input_size"] == str(est.info.input_size)
    assert outputs == meta["kornia_ilum.outputs"].split(",") and outputs[:2] == ["mirror_ball", "valid"]
    assert ("sh" in outputs) == (create_estimator(name)(_crops(est, 1)).sh is not None)
    # the graph alone gives SPEC units: exp/softplus and the ball's mask are inside (0 outside the ball)
    got = OnnxEstimator(model)(_crops(est, 2))
    assert float(got.mirror_ball[..., ~got.valid].abs().amax()) == 0.0
    assert float(got.mirror_ball.amin()) >= 0.0


def test_export_writes_the_file_atomically_and_leaves_the_estimator_as_it_was(tmp_path) -> None:
    est = create_estimator("uniform").double()
    path = tmp_path / "uniform.onnx"
    data = export_onnx(est, path)
    assert path.read_bytes() == data and sorted(p.name for p in tmp_path.iterdir()) == ["uniform.onnx"]
    assert next(iter(est.buffers()), torch.zeros((), dtype=torch.float64)).dtype == torch.float64
    assert OnnxEstimator(path).info.name == "uniform"


def test_onnx_estimator_checks_its_input_and_rejects_foreign_models(exported) -> None:
    est, model = exported["uniform"]
    fast = OnnxEstimator(model)
    bad = _crops(est, 1)
    bad[0, 0, 0, 0] = float("nan")
    with pytest.raises(NonFiniteError):
        fast(bad)
    foreign = onnx.load_from_string(model)
    del foreign.metadata_props[:]
    with pytest.raises(ValueCheckError, match="not written by kornia_ilum"):
        OnnxEstimator(foreign.SerializeToString())


def test_runtimes_by_name(monkeypatch) -> None:
    est = create_estimator("uniform")
    assert with_runtime(est, "eager") is est
    assert isinstance(with_runtime(est, "auto"), OnnxEstimator)
    assert isinstance(create_estimator("uniform", runtime="onnx"), OnnxEstimator)
    with pytest.raises(ValueCheckError, match="runtime must be one of auto, eager, bf16, onnx, onnx-int8"):
        create_estimator("ours", runtime="tensorrt")
    with pytest.raises(TypeCheckError, match="LightingEstimator"):
        with_runtime(torch.nn.Identity(), "onnx")

    def missing():
        raise ImportError("no onnxruntime here")

    monkeypatch.setattr(runtime_module, "_onnxruntime", missing)
    assert with_runtime(est, "auto").runtime in ("bf16", "eager")  # auto never fails for want of ONNX Runtime
    with pytest.raises(ImportError):
        with_runtime(est, "onnx")


def test_auto_tries_only_the_order_given() -> None:
    est = create_estimator("uniform")
    assert with_runtime(est, "auto", order=("onnx",)).runtime == "onnx"
    assert with_runtime(est, "auto", order=()) is est
    with pytest.raises(ValueCheckError, match="order must hold runtimes of"):
        with_runtime(est, "auto", order=("eager",))


def test_auto_keeps_eager_when_every_runtime_fails_parity(monkeypatch) -> None:
    est = create_estimator("uniform")
    monkeypatch.setattr(runtime_module, "runtime_parity", lambda *a: (1.0, 0.0, False))
    assert with_runtime(est, "auto", cache=False) is est


def test_torch_export_takes_the_estimator_itself() -> None:
    est = create_estimator("ours", pretrained=False).eval()
    program = torch.export.export(est, (torch.rand(2, 3, 256, 256),),
                                  dynamic_shapes=({0: torch.export.Dim("batch", min=1, max=64)},))
    got = program.module()(torch.rand(3, 3, 256, 256))
    assert isinstance(got, LightingEstimate) and got.mirror_ball.shape == (3, 3, 32, 32)


def test_checks_pass_under_jit_trace_and_still_check_shapes() -> None:
    def f(x):
        check_tensor(x, "x", ["B", "3"])
        return x * 2

    traced = torch.jit.trace(f, torch.rand(2, 3))  # the sizes are 0-d tensors while tracing
    assert torch.equal(traced(torch.ones(4, 3)), torch.full((4, 3), 2.0))

    def g(x):
        check_tensor(x, "x", ["B", "4"])
        return x

    with pytest.raises(Exception, match=r"x must have shape \(B, 4\), got \(2, 3\)"):
        torch.jit.trace(g, torch.rand(2, 3))


# --------------------------------------------------------------------- reduced precision, the cache, auto
@pytest.mark.parametrize("name", NAMES)
def test_bf16_moves_l_rec_by_at_most_lrec_rtol_or_is_refused_where_it_would_be_emulated(name) -> None:
    est = create_estimator(name)
    if not native_bf16():
        with pytest.raises(ValueCheckError, match="no native bfloat16"):
            with_runtime(est, "bf16")
        return
    fast = with_runtime(create_estimator(name), "bf16")
    assert isinstance(fast, Bf16Estimator) and fast.runtime == "bf16"
    value, tol, passed = runtime_parity(est, fast, "bf16")
    assert tol == LREC_RTOL and passed, f"{name}: L_rec moved by {value:.4f} under bf16"
    assert fast(_crops(est, 2)).mirror_ball.dtype == torch.float32


@pytest.mark.parametrize("name", ("ours", "sh", "sipr"))
def test_int8_is_measured_on_the_probe_and_auto_takes_it_only_within_tolerance(name) -> None:
    est = create_estimator(name)
    fast = with_runtime(est, "onnx-int8")
    assert isinstance(fast, OnnxEstimator) and fast.runtime == "onnx-int8"
    value, tol, passed = runtime_parity(est, fast, "onnx-int8")
    # int8 changes the estimate; by how much depends on the CPU's int8 kernels (VNNI, AMX, or AVX2's saturating
    # u8 x s8 products), so only auto's use of the verdict is asserted, not its value
    assert value > 0.0 and tol == LREC_RTOL
    chosen = with_runtime(est, "auto", cache=False)
    assert chosen.runtime in ("onnx-int8", "onnx", "bf16", "eager")
    assert (chosen.runtime == "onnx-int8") == passed  # int8 is first in AUTO_ORDER: taken exactly when it passes
    # quantised: the encoder's weights are int8, so the file is smaller than the float32 export
    assert len(onnx_model(est, "onnx-int8")) < 0.9 * len(onnx_model(est, "onnx"))


def test_int8_needs_an_encoder_to_quantise() -> None:
    with pytest.raises(ValueCheckError, match="nothing for the int8 runtime to quantise"):
        with_runtime(create_estimator("uniform"), "onnx-int8")


def test_exports_are_cached_by_the_state_and_remade_when_damaged(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv("KORNIA_ILUM_CACHE", str(tmp_path))
    est = create_estimator("uniform")
    first = onnx_model(est, "onnx")
    files = list((tmp_path / "onnx").iterdir())
    assert len(files) == 1 and files[0].read_bytes() == first and files[0].name.startswith("uniform-onnx-")

    def fail(*a, **k):
        raise AssertionError("exported again")

    monkeypatch.setattr(runtime_module, "export_onnx", fail)
    assert onnx_model(est, "onnx") == first  # from the cache
    files[0].write_bytes(b"not an onnx model")
    monkeypatch.undo()
    monkeypatch.setenv("KORNIA_ILUM_CACHE", str(tmp_path))
    assert onnx_model(est, "onnx") == first and files[0].read_bytes() == first  # remade
    # another state (new weights), another file
    trained, untrained = create_estimator("sh"), create_estimator("sh", pretrained=False)
    names = {runtime_module._cache_path(e, "onnx", ".onnx").name for e in (trained, untrained)}
    assert len(names) == 2


def test_auto_caches_its_verdict(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv("KORNIA_ILUM_CACHE", str(tmp_path))
    est = create_estimator("uniform")
    first = with_runtime(est, "auto").runtime
    verdicts = sorted(p.name for p in (tmp_path / "parity").iterdir())
    assert verdicts and all(v.startswith("uniform-") for v in verdicts)
    monkeypatch.setattr(runtime_module, "runtime_parity", lambda *a: pytest.fail("checked again"))
    assert with_runtime(est, "auto").runtime == first


def test_onnx_runtimes_refuse_another_device_and_report_availability() -> None:
    assert runtime_available("onnx") is None
    assert runtime_available("onnx", "cuda") == "the ONNX runtimes run on the CPU"
    with pytest.raises(ValueCheckError, match="runtime must be one of"):
        runtime_available("tensorrt")
