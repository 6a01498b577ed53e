"""Fixtures of the portrait tests: a rendered sphere and a tiny cache (Mitsuba renders: the tests that use
them are slow)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kornia_ilum_lab.synth.lightstage import (
    DEFAULT_VIEWS,
    LANDMARK_NAMES,
    Auto,
    FixedViews,
    OnePass,
    Workers,
    build_cache,
    render_olat,
    select_mitsuba_variant,
)
from kornia_ilum_lab.synth.lightstage.scene import PIVOT_RAISE, Camera
from tests.lab.synth.lightstage.portraits.common import SIZE, S
from tests.lab.synth.lightstage.spheres import sphere_subject


@pytest.fixture(scope="package")
def package_variant() -> str:
    return select_mitsuba_variant()

@pytest.fixture(scope="package")
def sphere_field(package_variant: str):
    """A white Lambertian sphere (albedo 0.7) filling most of a 48 x 48 frontal view, with 20 landmarks (denoised:
    render_olat no longer denoises by default, and the 16-spp noise would exceed test_uniform_environment's bound)."""
    angles = 2 * math.pi * np.arange(len(LANDMARK_NAMES)) / len(LANDMARK_NAMES)
    rho = 0.8
    ring = np.stack([rho * np.cos(angles), rho * np.sin(angles), np.zeros_like(angles)], -1)
    inner_height = np.ptp(ring[:, 1])
    landmarks = (ring - [0.0, PIVOT_RAISE * inner_height, 0.0]).astype(np.float32)
    camera = Camera(fov_deg=40.0, distance=4.0, yaw_deg=0.0, pitch_deg=0.0, size=SIZE)
    subject = sphere_subject(landmarks=landmarks)
    settings = OnePass(lighting_size=S, spp=16, denoise=True)
    return render_olat(subject, camera, settings=settings, variant=package_variant, threads=1)

@pytest.fixture(scope="package")
def cache(tmp_path_factory, package_variant: str):
    """Two light-stage subjects, seed 0 (train) and seed 1 (eval), one small view each."""
    out = tmp_path_factory.mktemp("lightstage")
    build_cache("mannequin", [0, 1], out_dir=out, renderer=Auto(spp=4, lighting_size=S),
                views=FixedViews(DEFAULT_VIEWS[:1], size=SIZE), workers=Workers(processes=1),
                variant=package_variant, progress=False)
    return out
