"""Random camera views of the light stage (kornia_ilum.synth.lightstage.scene.sample_views)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.synth.lightstage.scene import (
    FACE_FRACTION,
    Camera,
    _pivot,
    camera_transform,
    fov_from_focal,
    frame_distance,
    project_points,
    sample_views,
)
from kornia_ilum.synth.lightstage.subjects import make_subject


class TestSampleViews:
    def test_ranges(self) -> None:
        views = [v for seed in range(150) for v in sample_views(seed, 4, 64)]
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
        assert sample_views(11, 4, 192) == sample_views(11, 4, 192)
        assert sample_views(11, 4, 192) != sample_views(12, 4, 192)
        # the lens, pitch and roll of view i depend on (seed, i) only
        a, b = sample_views(5, 4), sample_views(5, 6)
        assert [(v.fov_deg, v.pitch_deg, v.roll_deg) for v in a] == [(v.fov_deg, v.pitch_deg, v.roll_deg)
                                                                     for v in b[:4]]

    def test_framing(self) -> None:
        """Project a subject's landmarks: the box is FACE_FRACTION of the image height and inside it."""
        for seed in (0, 3):
            subject = make_subject(seed)
            for view in sample_views(seed, 6, 192, landmarks=subject.face_landmarks):
                xy = project_points(subject.face_landmarks, view, camera_transform(view, _pivot(subject))).numpy()
                height = np.ptp(xy[:, 1]) / view.size
                assert abs(height - FACE_FRACTION) < 0.005
                assert xy.min() > 0.1 * view.size and xy.max() < 0.9 * view.size
            nominal = sample_views(seed, 4, 192)  # framed for a typical face: close to it
            for view in nominal:
                xy = project_points(subject.face_landmarks, view, camera_transform(view, _pivot(subject))).numpy()
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
