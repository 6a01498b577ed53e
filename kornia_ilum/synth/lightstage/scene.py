r"""The light stage's camera: where it stands, how it frames a subject, and where subject points land.

The lighting stays in the camera frame of SPEC.md (+X right, +Y up, +Z toward the camera): the camera is a
pinhole at the origin looking along -Z, and the subject is turned and moved in front of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from kornia_ilum.core.check import check_positive_int
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.synth.background import camera_rotation

__all__ = ["PIVOT_RAISE", "Camera", "camera_transform", "project_points"]

#: The camera aims this fraction of the face-landmark box's height above the box's centre: OpenCV's Haar
#: detector centres its box 0.19 +- 0.04 landmark-box heights higher (measured on 16 detections in 36
#: light-stage renders; :data:`kornia_ilum.synth.lightstage.portraits.DETECTOR_BOX` uses the same number).
PIVOT_RAISE = 0.19


# ----------------------------------------------------------------------------------------------
# camera


@dataclass(frozen=True)
class Camera:
    r"""A perspective camera orbiting the subject; the lighting stays in this camera's frame.

    Args:
        fov_deg: horizontal field of view between the left and right image edges, in ``(0, 180)`` degrees.
        distance: from the camera to the pivot, in metres: the centre of the bounding box of the subject's
            face landmarks raised by :data:`PIVOT_RAISE` of the box's height, where face detectors centre
            their boxes (so the face crop of :mod:`kornia_ilum.synth.lightstage.portraits` sits mid-image).
        yaw_deg: orbit about the subject's +Y axis: positive moves the camera toward the subject's +X side (its
            own left, the image's right in the frontal view), so the face turns toward the image's left.
        pitch_deg: orbit elevation: positive raises the camera above the face, looking down at it.
        size: the square image side in pixels.
        roll_deg: rotation of the subject about the camera's optical axis through the pivot (a head tilt, or
            a camera roll when the environment is rolled with it): positive turns the subject
            counter-clockwise in the image.

    Convention:
        In the camera frame (SPEC.md), the camera is a pinhole at the origin looking along -Z, +X right, +Y up;
        the subject is turned by the inverse of the orbit and its pivot placed at ``(0, 0, -distance)``. So
        ``yaw_deg = 30`` is the same image as the frontal camera with the subject turned by -30 degrees about
        +Y, under the same camera-frame lighting. ``R = camera_rotation(yaw_deg, -pitch_deg)`` of
        :func:`kornia_ilum.synth.background.camera_rotation` maps camera axes to subject axes. The background
        behind the subject is :func:`~kornia_ilum.synth.background.render_background` with the same ``fov_deg``
        and no rotation (the environment is already in the camera frame).

    Examples:
        >>> Camera(fov_deg=30.0, distance=0.55, yaw_deg=0.0, pitch_deg=0.0)
        Camera(fov_deg=30.0, distance=0.55, yaw_deg=0.0, pitch_deg=0.0, size=256, roll_deg=0.0)
    """

    fov_deg: float
    distance: float
    yaw_deg: float
    pitch_deg: float
    size: int = 256
    roll_deg: float = 0.0

    def __post_init__(self) -> None:
        for name in ("fov_deg", "distance", "yaw_deg", "pitch_deg", "roll_deg"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeCheckError(f"Camera.{name} must be a number, got {type(value).__name__}")
            if not math.isfinite(value):
                raise ValueCheckError(f"Camera.{name} must be finite, got {value}")
        if not 0.0 < self.fov_deg < 180.0:
            raise ValueCheckError(f"Camera.fov_deg must be in (0, 180), got {self.fov_deg}")
        if self.distance <= 0.0:
            raise ValueCheckError(f"Camera.distance must be positive, got {self.distance}")
        check_positive_int(self.size, "Camera.size")

    def to_dict(self) -> dict[str, float | int]:
        """The fields as a JSON-ready dict (the inverse is ``Camera(**d)``)."""
        return {k: getattr(self, k) for k in ("fov_deg", "distance", "yaw_deg", "pitch_deg", "size", "roll_deg")}


def _pivot(subject: Any) -> np.ndarray:
    lm = np.asarray(subject.face_landmarks, dtype=np.float64)
    lo, hi = lm.min(axis=0), lm.max(axis=0)
    return 0.5 * (lo + hi) + np.array([0.0, PIVOT_RAISE * (hi[1] - lo[1]), 0.0])


def camera_transform(camera: Camera, pivot: np.ndarray | tuple[float, float, float]) -> np.ndarray:
    r"""The ``4 x 4`` rigid transform from subject coordinates to the camera frame of :class:`Camera`.

    Args:
        camera: the camera.
        pivot: the subject point that the camera orbits and looks at, ``(3,)`` metres.

    Returns:
        float64 ``(4, 4)`` matrix ``T`` with ``x_cam = T[:3, :3] @ x + T[:3, 3]``.

    Examples:
        >>> T = camera_transform(Camera(30.0, 2.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        >>> T[:3, 3].tolist()
        [0.0, 0.0, -2.0]
    """
    rot = camera_rotation(camera.yaw_deg, -camera.pitch_deg).numpy().T  # subject -> camera axes
    if camera.roll_deg:
        c, s = math.cos(math.radians(camera.roll_deg)), math.sin(math.radians(camera.roll_deg))
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ rot  # about the optical axis (+Z)
    t = np.eye(4)
    t[:3, :3] = rot
    t[:3, 3] = -rot @ np.asarray(pivot, dtype=np.float64) - np.array([0.0, 0.0, camera.distance])
    return t


def project_points(points: np.ndarray | torch.Tensor, camera: Camera, transform: np.ndarray) -> torch.Tensor:
    r"""Project subject points to continuous pixel coordinates of the camera's image.

    Args:
        points: ``(K, 3)`` points in subject coordinates (metres).
        camera: the camera (its ``fov_deg`` and ``size``).
        transform: the subject-to-camera transform of :func:`camera_transform`.

    Returns:
        float32 ``(K, 2)`` ``(x, y)`` with ``(0, 0)`` the top-left image corner and ``(size, size)`` the
        bottom-right one (the box convention of :mod:`kornia_ilum.detection`); pixel ``(i, j)`` spans
        ``[j, j + 1] x [i, i + 1]``.

    Raises:
        ValueCheckError: a point is not in front of the camera.

    Examples:
        >>> cam = Camera(90.0, 1.0, 0.0, 0.0, size=100)
        >>> project_points(np.array([[0.0, 0.0, 0.0], [0.5, 0.5, 0.0]]), cam, camera_transform(cam, (0, 0, 0)))
        tensor([[50., 50.],
                [75., 25.]])
    """
    p = np.asarray(points.detach().cpu() if isinstance(points, torch.Tensor) else points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) == 0:
        raise ShapeError(f"points must have shape (K, 3) with K > 0, got {tuple(p.shape)}")
    q = p @ transform[:3, :3].T + transform[:3, 3]
    depth = -q[:, 2]
    if not np.all(depth > 0):
        raise ValueCheckError("points must lie in front of the camera (z < 0 in the camera frame)")
    scale = 0.5 * camera.size / math.tan(math.radians(camera.fov_deg) / 2)
    x = 0.5 * camera.size + scale * q[:, 0] / depth
    y = 0.5 * camera.size - scale * q[:, 1] / depth
    return torch.from_numpy(np.stack([x, y], axis=-1)).float()
