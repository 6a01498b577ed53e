"""Previews with textures, training portraits from a cache, and the detection benchmark's smoke run."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from kornia_ilum_lab.synth.lightstage.cache import SampledViews, Workers, build_cache, read_field, read_manifest
from kornia_ilum_lab.synth.lightstage.settings import Auto
from kornia_ilum_lab.synth.lightstage.preview import compose_portrait, preview_bsdf, render_preview, training_sheet
from kornia_ilum_lab.synth.lightstage.scene import sample_views
from kornia_ilum_lab.synth.lightstage.subjects import Material, MeshPart, make_subject
from tests.conftest import SHARED_DATA

PNG = b"\x89PNG\r\n\x1a\n"
ROOT = Path(__file__).resolve().parents[4]

pytestmark = pytest.mark.slow  # every test renders with Mitsuba (a preview, or the tiny cache's fields)


@pytest.fixture(scope="module")
def tiny_cache(tmp_path_factory) -> Path:
    """Two mannequins (seed 1 is an eval subject), two views each, 24 px, 4 x 4 lights."""
    out = tmp_path_factory.mktemp("cache")
    build_cache("mannequin", [0, 1], out_dir=out, renderer=Auto(spp=1, lighting_size=4),
                views=SampledViews(2, size=24), workers=Workers(processes=1), progress=False)
    return out


def test_textures_reach_the_render() -> None:
    """A quad whose albedo texture is red on the left and green on the right, and a cut-out opacity."""
    v = np.array([[-0.1, -0.1, 0.0], [0.1, -0.1, 0.0], [0.1, 0.1, 0.0], [-0.1, 0.1, 0.0]], np.float32)
    f = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    tex = np.zeros((4, 4, 3), np.float32)
    tex[:, :2, 0], tex[:, 2:, 1] = 0.8, 0.8
    opacity = np.ones((4, 4), np.float32)
    opacity[:2] = 0.0  # the top half (v > 0.5) is cut out
    mat = Material("diffuse", (0.4, 0.4, 0.0), albedo_texture=tex, opacity_texture=opacity)
    assert preview_bsdf(mat)["type"] == "mask"
    subject = type("S", (), {"parts": [MeshPart("quad", v, f, mat, uvs=uv)],
                             "face_landmarks": np.array([[-0.1, -0.1, 0.0], [0.1, 0.1, 0.0]], np.float32)})()
    img = render_preview(subject, size=32, spp=4, fov_deg=20.0, distance=0.5)
    mid = img[20:26]  # lower half: opaque
    left, right = mid[:, 8:14].mean((0, 1)), mid[:, 18:24].mean((0, 1))
    assert left[0] > 2 * left[1] and right[1] > 2 * right[0]
    top = img[6:12, 12:20].mean((0, 1))  # cut out: the studio's background shows through
    assert abs(top[0] - top[1]) < 0.5 * max(top[0], top[1], 1e-3) + 0.05


def test_preview_with_a_light_stage_camera() -> None:
    subject = make_subject(3)
    view = sample_views(3, 2, size=24, landmarks=subject.face_landmarks)[0]
    img = render_preview(subject, camera=view, spp=2)
    assert img.shape == (24, 24, 3) and float(img[6:18, 6:18].mean()) > 0.01


def test_compose_portrait(tiny_cache: Path) -> None:
    from kornia_ilum_lab.synth.environments import EnvironmentSampler

    entry = read_manifest(tiny_cache)["entries"][0]
    field = read_field(tiny_cache / entry["path"], dense=False)
    env = EnvironmentSampler(seed=1).sample(0)
    out = compose_portrait(field, env)
    assert out["image"].dtype == torch.uint8 and out["image"].shape == (3, 24, 24)
    assert out["lighting"].shape == (3, 32, 32) and out["gain"] > 0
    torch.testing.assert_close(out["lighting"], env.mirror_ball * out["gain"])
    # Metered over the face crop (the face box expanded 1.25 x), as the training crops are: exposing the
    # crop of the output again asks for no further gain (up to 8-bit rounding and clipped highlights).
    from kornia_ilum.color import srgb_to_linear
    from kornia_ilum.detection.crop import CROP_SCALE, crop_faces, square_crop_boxes
    from kornia_ilum_lab.synth.lightstage.portraits import auto_exposure

    linear = srgb_to_linear(out["image"].float()[None] / 255)
    crop = crop_faces(linear, square_crop_boxes(out["face_box"][None], CROP_SCALE), size=24)
    assert float(auto_exposure(crop)[0]) == pytest.approx(1.0, rel=0.1)
    assert float(auto_exposure(linear)[0]) != pytest.approx(1.0, rel=0.1)  # the whole frame would differ


def test_training_sheet(tiny_cache: Path) -> None:
    path = tiny_cache / "sheet.png"
    assert training_sheet(tiny_cache, path, count=3, split="train", size=48) == 3
    assert path.read_bytes()[:8] == PNG


def load_bench():
    spec = importlib.util.spec_from_file_location("bench_detection", ROOT / "benchmarks" / "bench_detection.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_detection"] = module
    spec.loader.exec_module(module)
    return module


def test_bench_detection_smoke(tiny_cache: Path, capsys, monkeypatch) -> None:
    """The benchmark runs on a tiny cache and prints its table (the numbers mean nothing at 24 px)."""
    bench = load_bench()
    monkeypatch.setenv("KORNIA_ILUM_SHARED_DATA", str(SHARED_DATA))
    assert bench.main(["--cache", str(tiny_cache), "--count", "3", "--upscale", "64", "--hdri",
                       str(SHARED_DATA / "hdri")]) == 0
    out = capsys.readouterr().out
    assert "fewer than 10" in out and "3 renders of 1 eval subjects" in out
    for label in ("0-10", "10-20", "20-30", "30-35", "all", "within +-30", "yunet", "opencv"):
        assert label in out
    box = torch.tensor([10.0, 10.0, 20.0, 20.0])
    assert bench.is_hit(torch.tensor([[11.0, 11.0, 21.0, 21.0, 0.9]]), box)
    assert bench.is_hit(torch.tensor([[0.0, 0.0, 30.0, 30.0, 0.9]]), box)  # low IoU, centre inside
    assert not bench.is_hit(torch.tensor([[25.0, 25.0, 40.0, 40.0, 0.9]]), box)
    assert not bench.is_hit(torch.zeros(0, 5), box)
    assert [bench.yaw_bin(y) for y in (-3, 12, -25, 35)] == [0, 1, 2, 3]
