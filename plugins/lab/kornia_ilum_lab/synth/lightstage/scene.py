r"""The light stage's camera: where it stands, how it frames a subject, and where subject points land.

The lighting stays in the camera frame of docs/conventions.rst ("Frames": +X right, +Y up, +Z toward the
camera): the camera is a pinhole at the origin looking along -Z, and the subject is turned and moved in front
of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from kornia_ilum.core.check import check_positive_int
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.core.seeding import hashed_seed
from kornia_ilum_lab.synth.background import camera_rotation

__all__ = [
    "FACE_FRACTION",
    "FOCAL_RANGE_MM",
    "PIVOT_RAISE",
    "ROLL_RANGE_DEG",
    "PITCH_RANGE_DEG",
    "YAW_RANGE_DEG",
    "Camera",
    "camera_transform",
    "fov_from_focal",
    "frame_distance",
    "project_points",
    "sample_views",
    "subject_pivot",
]

#: The camera aims this fraction of the face-landmark box's height above the box's centre: OpenCV's Haar
#: detector centres its box 0.19 +- 0.04 landmark-box heights higher (measured on 16 detections in 36
#: light-stage renders; :data:`kornia_ilum_lab.synth.lightstage.portraits.DETECTOR_BOX` uses the same number).
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
            their boxes (so the face crop of :mod:`kornia_ilum_lab.synth.lightstage.portraits` sits mid-image).
        yaw_deg: orbit about the subject's +Y axis: positive moves the camera toward the subject's +X side (its
            own left, the image's right in the frontal view), so the face turns toward the image's left.
        pitch_deg: orbit elevation: positive raises the camera above the face, looking down at it.
        size: the square image side in pixels.
        roll_deg: rotation of the subject about the camera's optical axis through the pivot (a head tilt, or
            a camera roll when the environment is rolled with it): positive turns the subject
            counter-clockwise in the image.

    Convention:
        In the camera frame (docs/conventions.rst), the camera is a pinhole at the origin looking along -Z, +X
        right, +Y up; the subject is turned by the inverse of the orbit and its pivot placed at ``(0, 0,
        -distance)``. So ``yaw_deg = 30`` is the same image as the frontal camera with the subject turned by
        -30 degrees about +Y, under the same camera-frame lighting. ``R = camera_rotation(yaw_deg,
        -pitch_deg)`` of :func:`kornia_ilum_lab.synth.background.camera_rotation` maps camera axes to subject
        axes. The background behind the subject is :func:`~kornia_ilum_lab.synth.background.render_background`
        with the same ``fov_deg`` and no rotation (the environment is already in the camera frame).

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


def subject_pivot(subject: Any) -> np.ndarray:
    """The point a :class:`Camera` aims at: the pivot of the subject's ``face_landmarks`` (float64 ``(3,)``).

    The landmark box's centre raised by :data:`PIVOT_RAISE` of its height; both renderers and the previews
    turn the subject about it (:func:`camera_transform`).

    Args:
        subject: a subject, or anything with ``face_landmarks`` ``(K, 3)`` in metres.

    Returns:
        the pivot ``(3,)``, float64, in the subject's coordinates (metres).

    Convention:
        The subject's frame (docs/conventions.rst, "Frames": +Y up), so the pivot is raised along +Y.

    Examples:
        >>> from types import SimpleNamespace
        >>> box = SimpleNamespace(face_landmarks=[[-0.1, -0.1, 0.0], [0.1, 0.1, 0.05]])  # 0.2 m high
        >>> [round(v, 3) for v in subject_pivot(box).tolist()]  # raised by 0.19 x 0.2 m
        [0.0, 0.038, 0.025]
    """
    return _landmark_pivot(np.asarray(subject.face_landmarks, dtype=np.float64))


def _landmark_pivot(lm: np.ndarray) -> np.ndarray:
    """The pivot of :class:`Camera`: the landmark box's centre raised by :data:`PIVOT_RAISE` of its height."""
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

    Shape:
        - points: :math:`(K, 3)`
        - transform: :math:`(4, 4)`
        - Output: :math:`(K, 2)`

    Convention:
        Camera frame of docs/conventions.rst ("Frames"): a pinhole at the origin looking along -Z, +X to the
        right of the image, +Y up (so image ``y`` grows downwards).

    Examples:
        >>> cam = Camera(90.0, 1.0, 0.0, 0.0, size=100)
        >>> xy = project_points(np.array([[0.0, 0.0, 0.0], [0.5, 0.5, 0.0]]), cam, camera_transform(cam, (0, 0, 0)))
        >>> xy.round(decimals=3)
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


# ----------------------------------------------------------------------------------------------
# random views

#: Half-ranges of the sampled views' orbit, in degrees: yaw within +-35, pitch within +-15, roll within +-10.
YAW_RANGE_DEG = 35.0
PITCH_RANGE_DEG = 15.0
ROLL_RANGE_DEG = 10.0

#: Full-frame-equivalent focal lengths of the sampled lenses, mm: a phone's wide camera (24 mm, 73.7 degrees of
#: horizontal field of view) to a portrait lens (85 mm, 23.9 degrees); drawn log-uniformly.
FOCAL_RANGE_MM = (24.0, 85.0)

#: The height of the projected face-landmark box (brow tops to chin, ear to ear), as a fraction of the image
#: height, that :func:`sample_views` frames every view to: 0.5, so the face box expanded 1.25 x (the crop of
#: :mod:`~kornia_ilum_lab.synth.lightstage.portraits`, about 1.13 x 1.25 = 0.71 of the image) fits with room for
#: its jitter, whatever the lens, as :data:`~kornia_ilum_lab.synth.lightstage.cache.DEFAULT_VIEWS` did (0.5 to 0.6).
FACE_FRACTION = 0.5

_NOMINAL_LANDMARKS = None  # landmarks of a typical face, for views sampled without a subject (lazy)


def fov_from_focal(focal_mm: float) -> float:
    r"""The horizontal field of view, degrees, of a full-frame-equivalent focal length (a 36 mm wide frame).

    ``fov = 2 atan(18 / focal_mm)``.

    Args:
        focal_mm: the focal length in millimetres, positive.

    Returns:
        the horizontal field of view in degrees, in ``(0, 180)``.

    Raises:
        ValueCheckError: ``focal_mm`` is not a positive number.

    Examples:
        >>> round(fov_from_focal(24.0), 1), round(fov_from_focal(85.0), 1)
        (73.7, 23.9)
    """
    if isinstance(focal_mm, bool) or not isinstance(focal_mm, (int, float)) or not focal_mm > 0:
        raise ValueCheckError(f"focal_mm must be a positive number, got {focal_mm!r}")
    return math.degrees(2.0 * math.atan(18.0 / focal_mm))


def _box_height(camera: Camera, landmarks: np.ndarray, pivot: np.ndarray) -> float:
    xy = project_points(landmarks, camera, camera_transform(camera, pivot)).numpy()
    return float(xy[:, 1].max() - xy[:, 1].min())


def frame_distance(camera: Camera, landmarks: np.ndarray, fraction: float = FACE_FRACTION) -> float:
    r"""The camera distance at which the projected face-landmark box is ``fraction`` of the image height.

    Found by bisection on the projection itself (:func:`project_points` about the pivot of
    :func:`camera_transform`), so perspective, the lens, pitch and roll are all accounted for: a wide lens
    stands closer and sees the nose larger, exactly as a phone held close does.

    Args:
        camera: the camera; its ``distance`` is ignored.
        landmarks: ``(K, 3)`` face landmarks in subject coordinates (metres).
        fraction: the target height of the landmark box over the image height, in ``(0, 1)``.

    Returns:
        the distance in metres (1 mm precision).

    Examples:
        >>> lm = np.array([[-0.07, -0.08, 0.0], [0.07, 0.08, 0.0]])  # a flat 16 cm tall "face"
        >>> d = frame_distance(Camera(90.0, 1.0, 0.0, 0.0, size=100), lm, 0.5)
        >>> round(d, 2)  # tan(45) = 1: 0.16 m spans half of 2 d
        0.16
    """
    if not 0.0 < float(fraction) < 1.0:
        raise ValueCheckError(f"fraction must be in (0, 1), got {fraction}")
    lm = np.asarray(landmarks, dtype=np.float64)
    if lm.ndim != 2 or lm.shape[1] != 3 or len(lm) < 2:
        raise ShapeError(f"landmarks must have shape (K, 3) with K >= 2, got {tuple(lm.shape)}")
    pivot = _landmark_pivot(lm)
    reach = float(np.linalg.norm(lm - pivot, axis=1).max())  # nothing may come closer than this
    target = fraction * camera.size
    near, far = 1.05 * reach + 1e-3, 100.0
    for _ in range(40):  # the box shrinks monotonically with the distance
        mid = math.sqrt(near * far)
        if _box_height(Camera(camera.fov_deg, mid, camera.yaw_deg, camera.pitch_deg, camera.size, camera.roll_deg),
                       lm, pivot) > target:
            near = mid
        else:
            far = mid
        if far - near < 5e-4:
            break
    return round(0.5 * (near + far), 3)


def _nominal_landmarks() -> np.ndarray:
    """The landmarks of a typical face (14.5 cm from brow tops to chin, 15 cm ear to ear): a fixed layout."""
    global _NOMINAL_LANDMARKS
    if _NOMINAL_LANDMARKS is None:
        # a coarse face: brows, eyes, nose, mouth, chin, jaw, cheeks and ears (subject frame, eyes near y = 0)
        _NOMINAL_LANDMARKS = np.array([
            [-0.035, 0.035, 0.075], [0.035, 0.035, 0.075], [0.0, 0.02, 0.085],
            [-0.045, 0.0, 0.06], [-0.015, 0.0, 0.07], [0.015, 0.0, 0.07], [0.045, 0.0, 0.06],
            [0.0, -0.045, 0.1], [0.0, -0.055, 0.085], [-0.025, -0.075, 0.07], [0.025, -0.075, 0.07],
            [0.0, -0.068, 0.082], [0.0, -0.085, 0.078], [0.0, -0.11, 0.06],
            [-0.055, -0.085, 0.01], [0.055, -0.085, 0.01], [-0.06, -0.035, 0.045], [0.06, -0.035, 0.045],
            [-0.075, -0.01, -0.02], [0.075, -0.01, -0.02],
        ])  # fmt: skip
    return _NOMINAL_LANDMARKS


def sample_views(
    seed: int,
    n: int = 4,
    *,
    size: int = 192,
    landmarks: np.ndarray | None = None,
    fraction: float = FACE_FRACTION,
) -> tuple[Camera, ...]:
    r"""``n`` random camera views of the subject of ``seed``: phone-wide to portrait lenses, spread in yaw.

    View ``i`` draws from its own generator, seeded by ``hashed_seed(f"kornia_ilum.lightstage.view:{seed}:{i}")``
    (:func:`~kornia_ilum.core.seeding.hashed_seed`), so a view depends only on ``(seed, i, n)``:

    - yaw, stratified: the ``n`` views take the ``n`` equal strata of ``[-35, 35]`` degrees in an order
      shuffled per subject (``hashed_seed(f"kornia_ilum.lightstage.views:{seed}")``), each uniform within its
      stratum, so every subject is seen from its left, the front and its right, and the yaw is uniform overall;
    - pitch uniform in ``[-15, 15]``, roll uniform in ``[-10, 10]`` degrees;
    - focal length log-uniform in :data:`FOCAL_RANGE_MM` (24 to 85 mm full-frame equivalent; 73.7 to 23.9
      degrees, :func:`fov_from_focal`);
    - distance from :func:`frame_distance`: the projected face-landmark box is ``fraction`` (:data:`FACE_FRACTION`,
      0.5) of the image height, for the subject's own ``landmarks`` when given (the cache passes them), else
      for a typical 14.5 cm face (then the box is 0.5 of the image only for faces of that size).

    Args:
        seed: the subject's seed.
        n: views per subject.
        size: the image side in pixels.
        landmarks: ``(K, 3)`` face landmarks of the subject (:attr:`~.subjects.Subject.face_landmarks`).
        fraction: the face-landmark box height over the image height.

    Returns:
        ``n`` :class:`Camera`.

    Examples:
        >>> views = sample_views(7, 4, size=192)
        >>> len(views), all(abs(v.yaw_deg) <= 35 for v in views), views == sample_views(7, 4, size=192)
        (4, True, True)
        >>> sorted(int((v.yaw_deg + 35) // 17.5) for v in views)  # one view per yaw stratum
        [0, 1, 2, 3]
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise TypeCheckError(f"seed must be an int, got {type(seed).__name__}")
    check_positive_int(n, "n")
    check_positive_int(size, "size")
    lm = _nominal_landmarks() if landmarks is None else np.asarray(landmarks, dtype=np.float64)
    order = np.random.default_rng(hashed_seed(f"kornia_ilum.lightstage.views:{int(seed)}")).permutation(n)
    views = []
    lo_f, hi_f = (math.log(f) for f in FOCAL_RANGE_MM)
    for i in range(n):
        rng = np.random.default_rng(hashed_seed(f"kornia_ilum.lightstage.view:{int(seed)}:{i}"))
        u_yaw, u_pitch, u_roll, u_focal = rng.random(4)
        yaw = -YAW_RANGE_DEG + 2.0 * YAW_RANGE_DEG * (order[i] + u_yaw) / n
        pitch = PITCH_RANGE_DEG * (2.0 * u_pitch - 1.0)
        roll = ROLL_RANGE_DEG * (2.0 * u_roll - 1.0)
        fov = fov_from_focal(math.exp(lo_f + (hi_f - lo_f) * u_focal))
        cam = Camera(round(float(fov), 3), 1.0, round(float(yaw), 3), round(float(pitch), 3), size,
                     round(float(roll), 3))
        views.append(Camera(cam.fov_deg, frame_distance(cam, lm, fraction), cam.yaw_deg, cam.pitch_deg, size,
                            cam.roll_deg))
    return tuple(views)
