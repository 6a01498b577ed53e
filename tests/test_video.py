"""kornia_ilum.video: frames from files, the face detected every N frames, repeated crops reused, log-space
smoothing with its time constant, a cut followed at once; and kornia-ilum video."""

from __future__ import annotations

import math
import subprocess
import sys

import cv2
import numpy as np
import pytest
import skimage.data
import torch

from kornia_ilum.core.errors import HDRIOError, NoFaceError, ValueCheckError
from kornia_ilum.io import read_hdr
from kornia_ilum.estimators import AUTO_ORDER
from kornia_ilum.video import TRACKER_AUTO_ORDER, LightingTracker, estimate_video, read_frames

FACE = skimage.data.astronaut()


def _darker(k: float) -> np.ndarray:
    return np.clip(np.round(FACE.astype(np.float64) * k), 0, 255).astype(np.uint8)


def test_detects_every_n_frames_and_reuses_repeated_crops() -> None:
    tracker = LightingTracker(estimator="uniform", detect_every=3)
    frames = [tracker(FACE) for _ in range(7)]
    assert [f.detected for f in frames] == [True, False, False, True, False, False, True]
    assert [f.estimated for f in frames] == [True] + [False] * 6
    assert [f.index for f in frames] == list(range(7))
    first = frames[0].lighting.mirror_ball
    assert all(torch.equal(f.lighting.mirror_ball, first) for f in frames)  # a still scene stays still


def test_auto_takes_a_float_runtime_never_int8() -> None:
    assert "onnx-int8" in AUTO_ORDER and "onnx-int8" not in TRACKER_AUTO_ORDER
    assert set(TRACKER_AUTO_ORDER) <= set(AUTO_ORDER)
    tracker = LightingTracker(estimator="uniform", runtime="auto")
    assert tracker.estimator.runtime == "onnx"  # ONNX Runtime is a test dependency, and passes its parity check
    assert LightingTracker(estimator="uniform").detect_every == 5


def test_smoothing_in_log_space_with_its_time_constant() -> None:
    tracker = LightingTracker(estimator="uniform", time_constant=2.0, reuse_below=0.0, cut_above=1.0)
    bright = tracker(FACE).lighting.mirror_ball
    plain = LightingTracker(estimator="uniform", time_constant=0.0, reuse_below=0.0, cut_above=1.0)
    plain(FACE)
    dark = plain(_darker(0.8)).lighting.mirror_ball  # the same box, no smoothing
    step = tracker(_darker(0.8)).lighting.mirror_ball  # one frame after the change
    a = math.exp(-1.0 / 2.0)
    centre = (0, 0, 16, 16)
    expected = math.exp(a * math.log(bright[centre]) + (1 - a) * math.log(dark[centre]))
    assert step[centre].item() == pytest.approx(expected, rel=1e-5)


class _Spread(torch.nn.Module):
    """The uniform estimator with a given spread per call (a stand-in for a learned spread)."""

    def __init__(self, spreads: list[float]) -> None:
        super().__init__()
        from kornia_ilum.estimators import create_estimator

        self.inner, self.spreads = create_estimator("uniform"), list(spreads)
        self.info = self.inner.info

    def forward(self, crops: torch.Tensor, check_values: bool = True):
        import dataclasses

        out = self.inner(crops, check_values=check_values)
        return dataclasses.replace(out, log_energy_spread=torch.tensor([self.spreads.pop(0)]))


def test_a_frame_counts_as_its_inverse_variance() -> None:
    def step(spreads: list[float]) -> float:
        tracker = LightingTracker(estimator="uniform", time_constant=2.0, reuse_below=0.0, cut_above=1.0)
        tracker.estimator = _Spread(spreads)
        first = tracker(FACE).lighting
        out = tracker(_darker(0.8)).lighting
        return math.log(out.mirror_ball[0, 0, 16, 16] / first.mirror_ball[0, 0, 16, 16]), out.log_energy_spread

    a = math.exp(-1.0 / 2.0)
    same, spread_same = step([0.3, 0.3])
    unsure, _ = step([0.3, 0.6])  # twice the spread: a quarter of a frame's weight
    sure, _ = step([0.3, 0.15])
    full = same / (1 - a)  # the whole change in log
    assert unsure == pytest.approx(full * (1 - a**0.25), rel=1e-4)
    assert sure == pytest.approx(full * (1 - a**4), rel=1e-4)
    assert spread_same.item() == pytest.approx(0.3, rel=1e-6)


def test_a_scene_branch_sets_the_strength_before_the_smoothing() -> None:
    """``scene=``: the first frame is ``estimate_lighting``'s with the same branch, and says the scene's share."""
    from kornia_ilum.api import estimate_lighting
    from kornia_ilum.estimators import SceneStrength

    torch.manual_seed(0)
    scene = SceneStrength()
    first = LightingTracker(estimator="ours", scene=scene)(FACE).lighting
    photo = estimate_lighting(FACE, estimator="ours", scene=scene)
    torch.testing.assert_close(first.mirror_ball, photo.mirror_ball, rtol=1e-4, atol=1e-5)
    torch.testing.assert_close(first.scene_share, photo.scene_share)
    assert LightingTracker(estimator="ours")(FACE).lighting.scene_share is None


def test_a_cut_restarts_the_smoothing_and_detects_again() -> None:
    tracker = LightingTracker(estimator="uniform", time_constant=10.0, detect_every=100)
    tracker(FACE)
    cut = tracker(_darker(0.3))
    alone = LightingTracker(estimator="uniform")(_darker(0.3))
    assert cut.cut and cut.detected and cut.estimated
    torch.testing.assert_close(cut.lighting.mirror_ball, alone.lighting.mirror_ball)


def _two_people() -> np.ndarray:
    """A 480 x 1280 strip: the astronaut (a face of about 90 pixels) on the left, the cameraman (65) on the right."""
    strip = np.zeros((480, 1280, 3), np.uint8)
    strip[:, 40:520] = cv2.resize(FACE, (480, 480), interpolation=cv2.INTER_AREA)
    camera = cv2.resize(skimage.data.camera(), (480, 480), interpolation=cv2.INTER_AREA)
    strip[:, 760:1240] = camera[..., None]
    return strip


def test_another_face_is_a_cut_not_a_jump() -> None:
    """A pan over two people: when the tracked face leaves the frame and the detector takes the other one, the
    new face's lighting starts afresh (a cut), however little the crop's thumbnail changed; the smoothing
    does not carry the first face's light into it."""
    strip = _two_people()
    frames = [np.ascontiguousarray(strip[:, x : x + 640]) for x in range(0, 641, 40)]
    tracker = LightingTracker(estimator="uniform", time_constant=8.0, detect_every=1, cut_above=1.0)
    out = [tracker(f) for f in frames]
    centres = [float(f.lighting.boxes[0, [0, 2]].mean()) + 40 * i for i, f in enumerate(out)]  # in the strip
    switch = next(i for i, c in enumerate(centres) if c > 640)
    assert all(c < 640 for c in centres[:switch]) and all(c > 640 for c in centres[switch:])
    assert [f.cut for f in out] == [i == switch for i in range(len(out))]
    fresh = LightingTracker(estimator="uniform")(frames[switch])
    torch.testing.assert_close(out[switch].lighting.mirror_ball, fresh.lighting.mirror_ball)


def test_faceless_frames() -> None:
    noise = np.random.default_rng(0).integers(0, 255, (120, 160, 3), dtype=np.uint8)
    with pytest.raises(NoFaceError, match="frame 0"):
        LightingTracker(estimator="uniform")(noise)
    assert torch.isfinite(LightingTracker(estimator="uniform", fallback="full_image")(noise).lighting.mirror_ball).all()
    with pytest.raises(ValueCheckError, match="time_constant"):
        LightingTracker(estimator="uniform", time_constant=-1.0)


def test_reads_videos_and_image_sequences(tmp_path) -> None:
    small = cv2.resize(FACE, (128, 128))
    for i in range(3):
        cv2.imwrite(str(tmp_path / f"{i:02d}.png"), cv2.cvtColor(small, cv2.COLOR_RGB2BGR))
    assert len(list(read_frames(tmp_path))) == 3 and len(list(read_frames(str(tmp_path / "*.png")))) == 3
    video = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10, (128, 128))
    for _ in range(4):
        writer.write(cv2.cvtColor(small, cv2.COLOR_RGB2BGR))
    writer.release()
    frames = list(read_frames(video))
    assert len(frames) == 4 and frames[0].shape == (128, 128, 3) and frames[0].dtype == np.uint8
    with pytest.raises(HDRIOError, match="no such video"):
        list(read_frames(tmp_path / "missing.mp4"))
    with pytest.raises(HDRIOError, match="no image"):
        list(read_frames(tmp_path / "*.jpg"))
    assert len(list(estimate_video(video, estimator="uniform", fallback="full_image"))) == 4


def test_read_frames_refuses_what_it_cannot_read(tmp_path) -> None:
    (tmp_path / "f0.jpg").write_bytes(b"\xff\xd8 not a jpeg")
    with pytest.raises(HDRIOError, match="f0.jpg: missing, corrupt or not an image"):
        next(read_frames(tmp_path))
    empty = tmp_path / "empty.avi"
    cv2.VideoWriter(str(empty), cv2.VideoWriter_fourcc(*"MJPG"), 10, (16, 16)).release()
    with pytest.raises(HDRIOError, match="no frame in .*empty.avi"):
        next(read_frames(empty))
    with pytest.raises(HDRIOError, match="no such video file or folder"):
        next(read_frames(tmp_path / "missing"))


def test_the_video_command_writes_one_exr_per_frame(tmp_path) -> None:
    for i in range(3):
        cv2.imwrite(str(tmp_path / f"f{i}.png"), cv2.cvtColor(FACE, cv2.COLOR_RGB2BGR))
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, "-m", "kornia_ilum", "video", str(tmp_path), "-o", str(out),
                          "--estimator", "uniform"], capture_output=True, text=True, check=False)
    assert run.returncode == 0, run.stderr
    assert "3 frames" in run.stdout and "estimated on 1" in run.stdout
    assert sorted(p.name for p in out.iterdir()) == ["frame_00000.exr", "frame_00001.exr", "frame_00002.exr"]
    assert read_hdr(out / "frame_00002.exr").shape[-1] == 32
    bad = subprocess.run([sys.executable, "-m", "kornia_ilum", "video", str(tmp_path / "nope.mp4"), "-o",
                          str(out)], capture_output=True, text=True, check=False)
    assert bad.returncode == 1 and "no such video" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
    faceless = tmp_path / "faceless"
    faceless.mkdir()
    cv2.imwrite(str(faceless / "f0.png"), np.full((64, 96, 3), 90, np.uint8))
    none = subprocess.run([sys.executable, "-m", "kornia_ilum", "video", str(faceless), "-o", str(out),
                           "--estimator", "uniform"], capture_output=True, text=True, check=False)
    assert none.returncode == 1 and "--fallback full_image" in none.stderr


def test_the_video_command_takes_a_scene_branch(tmp_path) -> None:
    """``--scene FILE``: the frames' strength fused with the whole frame's; a file that holds no branch fails
    before anything is written."""
    import safetensors.torch

    from kornia_ilum.cli import main
    from kornia_ilum.estimators import SceneStrength

    frames = tmp_path / "frames"
    frames.mkdir()
    for i in range(2):
        cv2.imwrite(str(frames / f"f{i}.png"), cv2.cvtColor(FACE, cv2.COLOR_RGB2BGR))
    torch.manual_seed(0)
    weights = tmp_path / "scene.safetensors"
    safetensors.torch.save_file(SceneStrength().state_dict(), str(weights))
    assert main(["video", str(frames), "-o", str(tmp_path / "out"), "--runtime", "eager",
                 "--scene", str(weights)]) == 0
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["frame_00000.exr", "frame_00001.exr"]
    safetensors.torch.save_file({"w": torch.ones(2)}, str(tmp_path / "bad.safetensors"))
    assert main(["video", str(frames), "-o", str(tmp_path / "bad"), "--scene", str(tmp_path / "bad.safetensors")]) == 1
    assert not (tmp_path / "bad").exists()
