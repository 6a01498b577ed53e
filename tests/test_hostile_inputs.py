"""Every estimator on hostile photographs (issue 24): black, white, saturated, one colour, noise, tiny and huge
images answer with finite, non-negative lighting; NaN and Inf pixels and faceless photos with a typed error;
half precision stays within the documented tolerance of float32; and a CPU estimate is bitwise repeatable."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from kornia_ilum import create_estimator, estimate_lighting
from kornia_ilum.core.errors import NoFaceError, NonFiniteError
from kornia_ilum.estimators import list_estimators
from kornia_ilum.estimators.probe import fit_crops, load_probe, probe_lrec
from kornia_ilum.estimators.runtime import LREC_RTOL

ESTIMATORS = sorted(list_estimators())


def _photo(kind: str) -> np.ndarray:
    rng = np.random.default_rng(0)
    h, w = (16, 16) if kind == "16x16" else (240, 320)
    photo = {
        "black": np.zeros((h, w, 3)),
        "white": np.ones((h, w, 3)),
        "saturated red": np.stack([np.ones((h, w)), np.zeros((h, w)), np.zeros((h, w))], -1),
        "one colour": np.broadcast_to([0.2, 0.5, 0.3], (h, w, 3)),
        "noise": rng.random((h, w, 3)),
        "16x16": rng.random((h, w, 3)),
    }[kind]
    return np.ascontiguousarray(photo, dtype=np.float32)


@pytest.mark.parametrize("estimator", ESTIMATORS)
@pytest.mark.parametrize("kind", ["black", "white", "saturated red", "one colour", "noise", "16x16"])
def test_hostile_photos_get_finite_non_negative_lighting(estimator, kind) -> None:
    est = estimate_lighting(_photo(kind), estimator=estimator, fallback="full_image")
    assert est.mirror_ball.shape == (1, 3, 32, 32)
    assert torch.isfinite(est.mirror_ball).all() and (est.mirror_ball >= 0).all()


def test_a_huge_photo_is_answered() -> None:
    est = estimate_lighting(np.zeros((6000, 8000, 3), np.uint8), fallback="full_image")
    assert torch.isfinite(est.mirror_ball).all()


@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
def test_nan_and_inf_pixels_are_refused(bad) -> None:
    photo = _photo("noise")
    photo[10, 20, 1] = bad
    with pytest.raises(NonFiniteError):
        estimate_lighting(photo, fallback="full_image")


def test_a_faceless_photo_without_fallback_is_refused() -> None:
    with pytest.raises(NoFaceError):
        estimate_lighting(_photo("noise"))


@pytest.mark.parametrize("estimator", ["ours", "sh"])
@pytest.mark.parametrize("dtype", [torch.bfloat16, torch.float16])
def test_half_precision_weights_stay_within_the_documented_tolerance(estimator, dtype) -> None:
    """Weights and crops cast to half precision move mean ``L_rec`` by at most ``LREC_RTOL`` (1 %; measured on
    the probe's 256 check portraits: ours 0.02 % in bfloat16 and 0.002 % in float16, sh 0.08 % and 0.002 %; sh's
    weights of issue 39 move diffuse ``L_rec`` by 0.6 % in bfloat16 on 64 of them, 0.8 % on the 8 here)."""
    reference = create_estimator(estimator)
    half = copy.deepcopy(reference).to(dtype)

    class Cast(torch.nn.Module):
        input_size = getattr(reference, "input_size", None)

        def forward(self, crops):
            return half(crops.to(dtype))

    probe = load_probe().part(slice(64, 72))  # eight check portraits: float16 convolutions are slow on CPU
    ref, got = probe_lrec(reference, probe), probe_lrec(Cast(), probe)
    assert all(abs(got[k] - ref[k]) <= LREC_RTOL * ref[k] for k in ref), (ref, got)


@pytest.mark.parametrize("estimator", ESTIMATORS)
def test_cpu_estimates_are_bitwise_repeatable(estimator) -> None:
    net = create_estimator(estimator)
    crops = fit_crops(net, load_probe().part(slice(64, 66)).crops)
    with torch.inference_mode():
        first, second = net(crops).mirror_ball, net(crops).mirror_ball
    assert torch.equal(first, second)
