"""The light stage's cameras (kornia_ilum_lab.synth.lightstage.scene): views, transforms, projection."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum_lab.synth.lightstage.olat import render_olat
from kornia_ilum_lab.synth.lightstage.scene import (
    FACE_FRACTION,
    PIVOT_RAISE,
    Camera,
    camera_transform,
    fov_from_focal,
    frame_distance,
    project_points,
    sample_views,
    subject_pivot,
)
from kornia_ilum_lab.synth.lightstage.settings import Auto
from kornia_ilum_lab.synth.lightstage.subjects import make_subject
from kornia_ilum_lab.synth.lightstage.subjects.base import icosphere
from tests.lab.synth.lightstage.spheres import sphere_subject


class TestSampleViews:
    def test_ranges(self) -> None:
        views = [v for seed in range(150) for v in sample_views(seed, 4, size=64)]
        yaw = np.array([v.yaw_deg for v in views])
        pitch = np.array([v.pitch_deg for v in views])
        roll = np.array([v.roll_deg for v in views])
        fov = np.array([v.fov_deg for v in views])
        assert np.abs(yaw).max() <= 35 and np.abs(pitch).max() <= 15 and np.abs(roll).max() <= 10
        assert yaw.min() < -33 and yaw.max() > 33 and pitch.min() < -14 and roll.max() > 9
        assert fov_from_focal(85.0) <= fov.min() < 26 and 70 < fov.max() <= fov_from_focal(24.0)
        # log-uniform in focal length: about half of the lenses are longer than sqrt(24 * 85) = 45 mm
        assert 0.4 < np.mean(fov < fov_from_focal(math.sqrt(24 * 85))) < 0.6
        assert abs(np.mean(np.abs(yaw) < 17.5) - 0.5) < 0.05  # uniform yaw
        assert all(v.size == 64 for v in views)

    def test_spread(self) -> None:
        """Each subject's views take one yaw stratum each: left, front and right are all covered."""
        for seed in range(30):
            yaws = sorted(v.yaw_deg for v in sample_views(seed, 4))
            assert [int((y + 35) // 17.5) for y in yaws] == [0, 1, 2, 3]
            three = sorted(v.yaw_deg for v in sample_views(seed, 3))
            assert three[0] < -35 / 3 and -35 / 3 <= three[1] <= 35 / 3 and three[2] > 35 / 3

    def test_deterministic(self) -> None:
        assert sample_views(11, 4, size=192) == sample_views(11, 4, size=192)
        assert sample_views(11, 4, size=192) != sample_views(12, 4, size=192)
        # the lens, pitch and roll of view i depend on (seed, i) only
        a, b = sample_views(5, 4), sample_views(5, 6)
        assert [(v.fov_deg, v.pitch_deg, v.roll_deg) for v in a] == [(v.fov_deg, v.pitch_deg, v.roll_deg)
                                                                     for v in b[:4]]

    def test_framing(self) -> None:
        """Project a subject's landmarks: the box is FACE_FRACTION of the image height and inside it."""
        for seed in (0, 3):
            subject = make_subject(seed)
            for view in sample_views(seed, 6, size=192, landmarks=subject.face_landmarks):
                transform = camera_transform(view, subject_pivot(subject))
                xy = project_points(subject.face_landmarks, view, transform).numpy()
                height = np.ptp(xy[:, 1]) / view.size
                assert abs(height - FACE_FRACTION) < 0.005
                assert xy.min() > 0.1 * view.size and xy.max() < 0.9 * view.size
            nominal = sample_views(seed, 4, size=192)  # framed for a typical face: close to it
            for view in nominal:
                transform = camera_transform(view, subject_pivot(subject))
                xy = project_points(subject.face_landmarks, view, transform).numpy()
                assert 0.4 < np.ptp(xy[:, 1]) / view.size < 0.6

    def test_exception(self) -> None:
        with pytest.raises(TypeCheckError, match="seed must be an int"):
            sample_views(1.5)
        with pytest.raises(ValueCheckError, match="n must be positive"):
            sample_views(1, 0)
        with pytest.raises(ValueCheckError, match="fraction must be in"):
            frame_distance(Camera(30.0, 1.0, 0.0, 0.0), np.zeros((3, 3)), 1.5)
        with pytest.raises(ShapeError, match="landmarks must have shape"):
            frame_distance(Camera(30.0, 1.0, 0.0, 0.0), np.zeros((3, 2)))
        with pytest.raises(ValueCheckError, match="focal_mm"):
            fov_from_focal(0.0)


def test_frame_distance_wide_lens_stands_closer() -> None:
    lm = make_subject(2).face_landmarks
    wide = frame_distance(Camera(70.0, 1.0, 0.0, 0.0), lm)
    tele = frame_distance(Camera(24.0, 1.0, 0.0, 0.0), lm)
    assert 0.2 < wide < 0.35 and 0.6 < tele < 0.8

class TestCamera:
    def test_smoke(self) -> None:
        cam = Camera(30.0, 0.5, 10.0, -5.0, size=64)
        assert Camera(**cam.to_dict()) == cam

    @pytest.mark.parametrize(
        ("kwargs", "error", "match"),
        [
            ({"fov_deg": 0.0}, ValueCheckError, "fov_deg must be in"),
            ({"fov_deg": 180.0}, ValueCheckError, "fov_deg must be in"),
            ({"distance": -1.0}, ValueCheckError, "distance must be positive"),
            ({"yaw_deg": float("nan")}, ValueCheckError, "yaw_deg must be finite"),
            ({"pitch_deg": "up"}, TypeCheckError, "pitch_deg must be a number"),
            ({"size": 0}, ValueCheckError, "Camera.size must be positive"),
            ({"size": 2.5}, TypeCheckError, "Camera.size must be an int"),
        ],
    )
    def test_exception(self, kwargs: dict, error: type, match: str) -> None:
        args = {"fov_deg": 30.0, "distance": 1.0, "yaw_deg": 0.0, "pitch_deg": 0.0, **kwargs}
        with pytest.raises(error, match=match):
            Camera(**args)

class TestCameraTransform:
    def test_frontal(self) -> None:
        t = camera_transform(Camera(30.0, 2.0, 0.0, 0.0), (0.1, 0.2, 0.3))
        np.testing.assert_allclose(t[:3, :3], np.eye(3), atol=1e-12)
        np.testing.assert_allclose(t[:3, :3] @ [0.1, 0.2, 0.3] + t[:3, 3], [0.0, 0.0, -2.0], atol=1e-12)

    @pytest.mark.parametrize(
        ("yaw", "pitch", "toward_camera"),
        [(90.0, 0.0, (1.0, 0.0, 0.0)), (-90.0, 0.0, (-1.0, 0.0, 0.0)), (0.0, 90.0, (0.0, 1.0, 0.0))],
    )
    def test_orbit(self, yaw: float, pitch: float, toward_camera: tuple) -> None:
        """The subject point on the camera's side comes nearest: yaw toward +X, pitch from above."""
        t = camera_transform(Camera(30.0, 2.0, yaw, pitch), (0.0, 0.0, 0.0))
        np.testing.assert_allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(t[:3, :3] @ toward_camera + t[:3, 3], [0.0, 0.0, -1.0], atol=1e-12)

    def test_yaw_turns_face_left(self) -> None:
        """Positive yaw: the subject's nose (+Z) turns toward the image's left (-X)."""
        t = camera_transform(Camera(30.0, 2.0, 30.0, 0.0), (0.0, 0.0, 0.0))
        assert (t[:3, :3] @ [0.0, 0.0, 1.0])[0] < -0.4

class TestProjectPoints:
    def test_smoke(self) -> None:
        cam = Camera(90.0, 1.0, 0.0, 0.0, size=100)
        xy = project_points(np.array([[0.0, 0.0, 0.0], [0.5, 0.5, 0.0], [-1.0, -1.0, 0.0]]), cam,
                            camera_transform(cam, (0.0, 0.0, 0.0)))
        torch.testing.assert_close(xy, torch.tensor([[50.0, 50.0], [75.0, 25.0], [0.0, 100.0]]))

    def test_exception(self) -> None:
        cam = Camera(60.0, 1.0, 0.0, 0.0)
        t = camera_transform(cam, (0.0, 0.0, 0.0))
        with pytest.raises(ValueCheckError, match="in front of the camera"):
            project_points(np.array([[0.0, 0.0, 2.0]]), cam, t)
        with pytest.raises(ShapeError, match=r"points must have shape \(K, 3\)"):
            project_points(np.zeros((4, 2)), cam, t)

    @pytest.mark.slow
    def test_matches_render(self, variant: str) -> None:
        """A small ball off the pivot, seen from an orbit, lands where project_points puts its centre."""
        pivot_marks = 0.2 * icosphere(1)[0]  # landmarks around the origin; not rendered
        centre = (0.3, 0.25, 0.1)
        subject = sphere_subject(radius=0.03, centre=centre, landmarks=pivot_marks, subdivisions=2)
        cam = Camera(40.0, 2.0, 30.0, 15.0, size=64)
        rf = render_olat(subject, cam, settings=Auto(lighting_size=2, spp=16), variant=variant, threads=1)
        alpha = rf.alpha[0]
        yy, xx = torch.meshgrid(torch.arange(64.0) + 0.5, torch.arange(64.0) + 0.5, indexing="ij")
        centroid = torch.stack([(alpha * xx).sum(), (alpha * yy).sum()]) / alpha.sum()
        pivot = (0.0, PIVOT_RAISE * 0.4, 0.0)  # the landmark box is 0.4 high, centred at the origin
        expected = project_points(np.array([centre]), cam, camera_transform(cam, pivot))[0]
        assert torch.dist(centroid, expected) < 0.3
        box = project_points(pivot_marks, cam, camera_transform(cam, pivot))
        torch.testing.assert_close(rf.face_box, torch.cat([box.min(0).values, box.max(0).values]))
        torch.testing.assert_close(torch.tensor(rf.meta["landmarks"]), box, atol=1e-3, rtol=0)
