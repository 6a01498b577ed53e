"""kornia_ilum.estimators.runtime: every estimator exported to ONNX and run by ONNX Runtime, at parity."""

from __future__ import annotations

import onnx
import pytest
import torch

from kornia_ilum.core.check import check_tensor
from kornia_ilum.core.errors import NonFiniteError, TypeCheckError, ValueCheckError
from kornia_ilum.estimators import (
    PARITY_ATOL,
    LightingEstimate,
    OnnxEstimator,
    create_estimator,
    export_onnx,
    parity,
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
    with pytest.raises(ValueCheckError, match="runtime must be one of auto, eager, onnx"):
        create_estimator("ours", runtime="tensorrt")
    with pytest.raises(TypeCheckError, match="LightingEstimator"):
        with_runtime(torch.nn.Identity(), "onnx")

    def missing():
        raise ImportError("no onnxruntime here")

    monkeypatch.setattr(runtime_module, "_onnxruntime", missing)
    assert with_runtime(est, "auto") is est  # auto never fails for want of ONNX Runtime
    with pytest.raises(ImportError):
        with_runtime(est, "onnx")


def test_auto_keeps_eager_when_the_export_fails_parity(monkeypatch) -> None:
    est = create_estimator("uniform")
    monkeypatch.setattr(runtime_module, "parity", lambda *a: 1.0)
    assert with_runtime(est, "auto") is est


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
