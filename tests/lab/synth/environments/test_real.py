"""Tests of the real-map source: listing, labels, orientation (docs/conventions.rst lat-long), energy
conservation."""

from __future__ import annotations

import math

import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from kornia_ilum.core.errors import HDRIOError, NonFiniteError, ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import (
    direction_to_mirror_ball,
    latlong_directions,
    latlong_solid_angles,
    mirror_ball_pixel_index,
    mirror_ball_solid_angles,
)
from kornia_ilum.io import read_hdr, write_hdr
from kornia_ilum_lab.synth.environments import HDRFolderSource, guess_label, resize_latlong
from kornia_ilum_lab.synth.environments.real import DEFAULT_LABELS, ResizeLatLong
from tests.conftest import TOL, assert_close_dtype

F64 = torch.float64


def energy(x: torch.Tensor, omega: torch.Tensor) -> torch.Tensor:
    return (x.double() * omega.double()).sum((-2, -1))


class TestResizeLatLong:
    def test_smoke(self):
        out = resize_latlong(torch.rand(3, 8, 16), 4)
        assert out.shape == (3, 4, 8)
        assert (out >= 0).all()

    def test_cardinality(self):
        assert resize_latlong(torch.rand(2, 3, 12, 24), 5).shape == (2, 3, 5, 10)
        assert resize_latlong(torch.rand(1, 6, 12), 9).shape == (1, 9, 18)  # upsampling
        x = torch.rand(3, 4, 8)
        assert resize_latlong(x, 4) is x

    def test_exception(self):
        with pytest.raises(ShapeError, match="latlong must have shape"):
            resize_latlong(torch.rand(3, 4, 7), 2)
        with pytest.raises(ValueCheckError, match="latlong must be non-negative"):
            resize_latlong(-torch.ones(3, 4, 8), 2)
        with pytest.raises(NonFiniteError, match="latlong must be finite"):
            resize_latlong(torch.full((3, 4, 8), math.nan), 2)
        with pytest.raises(ValueCheckError, match="height must be positive"):
            resize_latlong(torch.rand(3, 4, 8), 0)

    @given(h_src=st.integers(1, 24), h_tgt=st.integers(1, 24), seed=st.integers(0, 100))
    def test_energy_conserved(self, h_src, h_tgt, seed):
        x = torch.rand(2, h_src, 2 * h_src, generator=torch.Generator().manual_seed(seed), dtype=F64)
        out = resize_latlong(x, h_tgt)
        e_out = energy(out, latlong_solid_angles(h_tgt, dtype=F64))
        e_in = energy(x, latlong_solid_angles(h_src, dtype=F64))
        torch.testing.assert_close(e_out, e_in)

    def test_constant_stays_constant(self):
        out = resize_latlong(torch.full((3, 37, 74), 2.5, dtype=F64), 11)
        torch.testing.assert_close(out, torch.full_like(out, 2.5))

    def test_sun_stays_in_its_pixel(self):
        x = torch.zeros(1, 64, 128, dtype=F64)
        x[0, 20, 70] = 1e5  # falls in target pixel (5, 17) at height 16
        out = resize_latlong(x, 16)
        assert out[0].flatten().nonzero().flatten().tolist() == [5 * 32 + 17]
        e_out = energy(out, latlong_solid_angles(16, dtype=F64))
        e_in = energy(x, latlong_solid_angles(64, dtype=F64))
        torch.testing.assert_close(e_out, e_in)

    def test_gradcheck(self):
        x = torch.rand(1, 6, 12, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(lambda t: resize_latlong(t, 4), (x,))

    def test_module_matches_functional(self):
        x = torch.rand(2, 3, 8, 16)
        torch.testing.assert_close(ResizeLatLong(5)(x), resize_latlong(x, 5))

    @pytest.mark.parametrize("dtype", [torch.float16, torch.bfloat16, torch.float32])
    def test_dtypes(self, dtype):
        x = torch.rand(3, 8, 16, dtype=F64)
        out = resize_latlong(x.to(dtype), 4)
        assert out.dtype == dtype
        assert_close_dtype(out, resize_latlong(x, 4), dtype, scale=2.0)

    @pytest.mark.slow  # torch.compile (Inductor): compiles, slow on a cold cache
    def test_compile(self):
        x = torch.rand(3, 8, 16)
        compiled = torch.compile(resize_latlong)
        torch.testing.assert_close(compiled(x, 4), resize_latlong(x, 4), **TOL[torch.float32])


def test_guess_label():
    assert guess_label("interior.exr") == guess_label("studio.exr") == "indoor"
    assert all(guess_label(n) == "outdoor" for n, lab in DEFAULT_LABELS.items() if lab == "outdoor")
    assert guess_label("Photo_Studio_01_4k.EXR") == "indoor"
    assert guess_label("unknown_place.hdr") == "outdoor"


@pytest.fixture
def tiny_folder(tmp_path):
    """Three tiny maps with different constant values, plus a file that is no map."""
    for k, name in enumerate(["a.exr", "b.hdr", "c_room.exr"]):
        write_hdr(tmp_path / name, torch.full((3, 8, 16), float(k + 1)))
    (tmp_path / "notes.txt").write_text("not a map")
    return tmp_path


class TestHDRFolderSource:
    def test_smoke(self, tiny_folder):
        source = HDRFolderSource(tiny_folder, height=4)
        assert source.names == ("a.exr", "b.hdr", "c_room.exr")
        assert len(source) == 3
        env = source.sample(torch.Generator().manual_seed(0))
        assert env.source.startswith("real:") and env.params["map"] in source.names

    def test_cardinality(self, tiny_folder):
        env = HDRFolderSource(tiny_folder, height=6).environment(1)
        assert env.latlong.shape == (3, 6, 12) and env.mirror_ball.shape == (3, 32, 32)
        assert env.params == {"map": "b.hdr", "index": 1}

    def test_exception(self, tmp_path, tiny_folder):
        with pytest.raises(HDRIOError, match="missing_dir does not exist"):
            HDRFolderSource(tmp_path / "missing_dir")
        empty = tmp_path / "empty"
        empty.mkdir()
        (empty / "readme.txt").write_text("-")
        with pytest.raises(HDRIOError, match=r"empty holds no lat-long map \(.hdr or .exr file\)"):
            HDRFolderSource(empty)
        with pytest.raises(ValueCheckError, match=r"label_of\('a.exr'\) must be 'indoor' or 'outdoor'"):
            HDRFolderSource(tiny_folder, label_of=lambda name: "cave")
        with pytest.raises(TypeCheckError, match="label_of must be None, a callable or a dict"):
            HDRFolderSource(tiny_folder, label_of=3)
        with pytest.raises(TypeCheckError, match="generator must be a torch.Generator"):
            HDRFolderSource(tiny_folder).sample(0)
        with pytest.raises(ValueCheckError, match=r"index must be an int in \[0, 3\)"):
            HDRFolderSource(tiny_folder).environment(3)
        square = tmp_path / "square"
        square.mkdir()
        write_hdr(square / "crop.exr", torch.ones(3, 8, 8))
        with pytest.raises(HDRIOError, match="crop.exr is not a lat-long map"):
            HDRFolderSource(square).environment(0)

    def test_labels(self, tiny_folder):
        labels = HDRFolderSource(tiny_folder).labels
        assert labels == {"a.exr": "outdoor", "b.hdr": "outdoor", "c_room.exr": "indoor"}
        by_dict = HDRFolderSource(tiny_folder, label_of={"a": "indoor", "b.hdr": "indoor"})
        assert by_dict.labels == {"a.exr": "indoor", "b.hdr": "indoor", "c_room.exr": "indoor"}
        assert by_dict.label == "indoor"
        assert HDRFolderSource(tiny_folder, label_of=lambda n: "outdoor").environment(2).label == "outdoor"

    def test_sample_uniform_and_reproducible(self, tiny_folder):
        source = HDRFolderSource(tiny_folder, height=4)
        names = [source.sample(torch.Generator().manual_seed(s)).params["map"] for s in range(60)]
        assert set(names) == set(source.names)
        assert all(n >= 10 for n in (names.count(m) for m in source.names))
        a = source.sample(torch.Generator().manual_seed(7))
        b = source.sample(torch.Generator().manual_seed(7))
        assert a.params == b.params and torch.equal(a.latlong, b.latlong)
        a.latlong += 1.0  # callers get copies, never the cache
        assert torch.equal(source.sample(torch.Generator().manual_seed(7)).latlong, b.latlong)

    def test_orientation_is_spec_latlong(self, tmp_path):
        """A bright pixel upper-left in the file is light from the left (-X) and above (+Y), per
        docs/conventions.rst."""
        image = torch.full((3, 16, 32), 0.01)
        image[:, 4, 8] = 100.0
        write_hdr(tmp_path / "marker.exr", image)
        env = HDRFolderSource(tmp_path, height=16).environment(0)
        torch.testing.assert_close(env.latlong, read_hdr(tmp_path / "marker.exr"))
        d = latlong_directions(16, dtype=F64)[4, 8]
        assert d[0] < -0.5 and d[1] > 0.5  # left, up: docs/conventions.rst's "left half is -X, top row is +Y"
        owner = int(mirror_ball_pixel_index(direction_to_mirror_ball(d), 32))
        assert int(env.mirror_ball.sum(0).flatten().argmax()) == owner

    def test_clamps_negative_values(self, tmp_path):
        import numpy as np
        import OpenImageIO as oiio

        image = np.ones((8, 16, 3), dtype=np.float32)
        image[2, 3, 0] = -0.004  # as lossy EXR stores (write_hdr refuses negative values, so write it raw)
        out = oiio.ImageOutput.create(str(tmp_path / "neg.exr"))
        out.open(str(tmp_path / "neg.exr"), oiio.ImageSpec(16, 8, 3, oiio.FLOAT))
        out.write_image(image)
        out.close()
        env = HDRFolderSource(tmp_path, height=8).environment(0)
        assert env.latlong.min() == 0.0 and env.mirror_ball.min() >= 0.0


@pytest.mark.parametrize("name", ["pedestrian_overpass_1k.hdr", "interior.exr", "city.exr"])
def test_shared_maps_conserve_energy(shared_data, name):
    """Lat-long at the working height and the 32 x 32 ball keep sum(L * Omega) of the file
    (docs/conventions.rst)."""
    source = HDRFolderSource(shared_data / "hdri")
    env = source.environment(source.names.index(name))
    assert env.label == ("indoor" if name == "interior.exr" else "outdoor")
    full = read_hdr(shared_data / "hdri" / name)
    e_file = energy(full, latlong_solid_angles(full.shape[-2]))
    e_latlong = energy(env.latlong, latlong_solid_angles(128, dtype=F64))
    e_ball = energy(env.mirror_ball, mirror_ball_solid_angles(32, dtype=F64))
    assert ((e_latlong - e_file).abs() / e_file).max() < 1e-5
    assert ((e_ball - e_latlong).abs() / e_latlong).max() < 1e-3
    mean = e_ball / (4 * math.pi)
    assert (env.mirror_ball.amax((1, 2)) / mean).min() > 100  # the sun (or the sunlit window) stays a peak


def test_shared_folder_labels(shared_data):
    source = HDRFolderSource(shared_data / "hdri")
    assert len(source) == 10
    assert sorted(n for n, lab in source.labels.items() if lab == "indoor") == ["interior.exr", "studio.exr"]
    assert source.label == "outdoor"
