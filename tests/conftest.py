"""Shared fixtures: device and dtype parametrisation in Kornia's style, and per-dtype tolerances."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import torch
from hypothesis import HealthCheck, settings

settings.register_profile(
    "ci", max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True
)
settings.register_profile("dev", max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

# One torch thread per xdist worker (the workers already use the cores); up to 2 in a plain run.
torch.set_num_threads(1 if "PYTEST_XDIST_WORKER" in os.environ else max(1, min(2, os.cpu_count() or 1)))

#: Absolute/relative tolerances against a float64 reference, per dtype (Kornia's convention).
TOL = {
    torch.float16: dict(atol=1e-2, rtol=1e-2),
    torch.bfloat16: dict(atol=3e-2, rtol=3e-2),
    torch.float32: dict(atol=1e-5, rtol=1e-4),
    torch.float64: dict(atol=1e-10, rtol=1e-8),
}

def _find_shared_data() -> Path:
    """``$KORNIA_ILUM_SHARED_DATA``, else ``../shared/data`` beside the checkout, else the workplace's copy."""
    if "KORNIA_ILUM_SHARED_DATA" in os.environ:
        return Path(os.environ["KORNIA_ILUM_SHARED_DATA"])
    candidates = [Path(__file__).resolve().parents[2] / "shared" / "data", Path("/work/shared/data")]
    return next((c for c in candidates if (c / "hdri").is_dir()), candidates[0])


SHARED_DATA = _find_shared_data()


@pytest.fixture(params=["cpu"] + (["cuda"] if torch.cuda.is_available() else []))
def device(request) -> torch.device:
    return torch.device(request.param)


@pytest.fixture(params=[torch.float32, torch.float64], ids=["float32", "float64"])
def dtype(request) -> torch.dtype:
    return request.param


@pytest.fixture
def shared_data() -> Path:
    """The read-only shared data folder; tests that need it skip with the reason when it is absent."""
    if not (SHARED_DATA / "hdri").is_dir():
        pytest.skip(f"shared data not found at {SHARED_DATA} (set KORNIA_ILUM_SHARED_DATA)")
    return SHARED_DATA


def assert_close_dtype(actual: torch.Tensor, expected: torch.Tensor, dtype: torch.dtype, scale: float = 1.0) -> None:
    """Compare a low-precision result with a float64 reference using the tolerance of ``dtype``."""
    tol = TOL[dtype]
    torch.testing.assert_close(
        actual.to(torch.float64), expected.to(torch.float64), atol=tol["atol"] * scale, rtol=tol["rtol"] * scale
    )


def hdr_lighting(
    b: int = 2, s: int = 32, seed: int = 0, dtype=torch.float32, coloured: bool = False
) -> torch.Tensor:
    """HDR-like mirror-ball lighting: a dim floor plus one bright light per item (white, or of a random colour
    with ``coloured``), zero off the ball."""
    from kornia_ilum.geometry import mirror_ball_valid

    g = torch.Generator().manual_seed(seed)
    x = 0.3 * torch.rand(b, 3, s, s, generator=g, dtype=torch.float64)
    for i in range(b):
        r, c = torch.randint(s // 4, 3 * s // 4, (2,), generator=g).tolist()
        x[i, :, r, c] += 30.0 * (torch.rand(3, generator=g, dtype=torch.float64) if coloured else 1.0)
    return (x * mirror_ball_valid(s)).to(dtype)


@pytest.fixture
def untrained_name():
    """A registered estimator that needs weights and ships none (``"untrained"``, an ``OursEstimator``
    subclass): the MissingWeightsError paths, now that ``ours`` ships its weights."""
    import dataclasses

    from kornia_ilum.estimators import OursEstimator, registry

    class Untrained(OursEstimator):
        info = dataclasses.replace(OursEstimator.info, name="untrained", weights=(), install_hint="")

    registry.register_estimator("untrained", Untrained)
    yield "untrained"
    registry._reset()


@pytest.fixture(scope="session")
def tiny_cache(tmp_path_factory):
    """A tiny light-stage cache for the training tests: two train mannequins, one 48 px view each."""
    from kornia_ilum_lab.synth.lightstage import Auto, SampledViews, Workers, build_cache

    out = tmp_path_factory.mktemp("train_cache")
    build_cache("mannequin", [0, 2], out_dir=out, renderer=Auto(spp=4), views=SampledViews(1, size=48),
                workers=Workers(processes=1), progress=False)
    return out


@pytest.fixture(autouse=True, scope="session")
def _export_cache(tmp_path_factory):
    """The runtimes' export cache (``KORNIA_ILUM_CACHE``) in the session's temporary folder, never ``~/.cache``."""
    old = os.environ.get("KORNIA_ILUM_CACHE")
    os.environ["KORNIA_ILUM_CACHE"] = str(tmp_path_factory.mktemp("export_cache"))
    yield
    if old is None:
        os.environ.pop("KORNIA_ILUM_CACHE", None)
    else:
        os.environ["KORNIA_ILUM_CACHE"] = old
