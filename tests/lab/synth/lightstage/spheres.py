"""Hand-built sphere subjects for the light-stage tests: they do not depend on the subject generator.

Renders with them are tiny (32 x 32 pixels, an 8 x 8 mirror ball = 52 lights, 16 spp), so the tests run in
seconds.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from kornia_ilum_lab.synth.lightstage.scene import PIVOT_RAISE, Camera
from kornia_ilum_lab.synth.lightstage.subjects.base import icosphere

S = 8  # lighting size of the tests: 52 valid lights
ALBEDO = 0.7
CAM = Camera(fov_deg=40.0, distance=4.0, yaw_deg=0.0, pitch_deg=0.0, size=32)


def material(kind: str = "diffuse", albedo: float = ALBEDO, **kw: float) -> SimpleNamespace:
    return SimpleNamespace(kind=kind, albedo=(albedo, albedo, albedo), roughness=kw.get("roughness", 0.3),
                           specular=kw.get("specular", 0.5))


def sphere_subject(radius: float = 1.0, centre=(0.0, 0.0, 0.0), mat: SimpleNamespace | None = None,
                   landmarks: np.ndarray | None = None, subdivisions: int = 4, extra=()) -> SimpleNamespace:
    """A hand-built Subject: a sphere mesh (plus ``extra`` parts) with the subjects module's attributes."""
    v, f = icosphere(subdivisions)
    v = v * radius + np.asarray(centre, dtype=np.float32)
    ball = SimpleNamespace(name="ball", vertices=v, faces=f, material=mat or material())
    if landmarks is None:  # the sphere's vertices, lowered so that the camera's pivot is the sphere's centre
        landmarks = v - np.array([0.0, PIVOT_RAISE * 2 * radius, 0.0], dtype=np.float32)
    return SimpleNamespace(seed=11, split="eval", skin_tone=4, parts=[ball, *extra], face_landmarks=landmarks,
                           params={})
