"""The reflectance-field cache (kornia_ilum.synth.lightstage.cache): files, manifest, resume, shards."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace
from typing import ClassVar

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from kornia_ilum.core.errors import HDRIOError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum.synth.lightstage import cache
from kornia_ilum.synth.lightstage.cache import (
    build_cache,
    field_path,
    read_field,
    read_manifest,
    shard,
    write_field,
)
from kornia_ilum.synth.lightstage.olat import ReflectanceField, _icosphere
from kornia_ilum.synth.lightstage.scene import Camera


def synthetic_field(size: int = 16, s: int = 8, seed: int = 0) -> ReflectanceField:
    """A dense field like a render's: a disk of covered pixels, zero invalid lights, a soft edge."""
    gen = torch.Generator().manual_seed(seed)
    yy, xx = torch.meshgrid(torch.arange(size) + 0.5, torch.arange(size) + 0.5, indexing="ij")
    r = ((xx - size / 2) ** 2 + (yy - size / 2) ** 2).sqrt() / (size / 3)
    alpha = (1.5 - r).clamp(0, 1)[None]
    valid = mirror_ball_valid(s).flatten()
    field = torch.rand(3, size * size, s * s, generator=gen) * alpha.flatten()[None, :, None] * valid
    meta = {"lighting_size": s, "variant": "test", "render_seconds": 1.5}
    return ReflectanceField(field.to(torch.bfloat16), alpha, torch.tensor([2.0, 3.0, 12.0, 13.0]),
                            Camera(30.0, 0.5, 10.0, -5.0, size=size), seed, meta)


class TestWriteReadField:
    def test_roundtrip(self, tmp_path: Path) -> None:
        rf = synthetic_field()
        info = write_field(tmp_path / "a.safetensors", rf)
        back = read_field(tmp_path / "a.safetensors")
        assert torch.equal(back.field, rf.field) and back.field.dtype == torch.bfloat16
        torch.testing.assert_close(back.alpha, rf.alpha, atol=1e-3, rtol=0)  # stored as float16
        assert torch.equal(back.face_box, rf.face_box)
        assert back.camera == rf.camera and back.subject_seed == rf.subject_seed and back.meta == rf.meta
        assert info["bytes"] == (tmp_path / "a.safetensors").stat().st_size
        assert info["dtype"] == "bfloat16" and info["shape"][0] == 3

    def test_compact(self, tmp_path: Path) -> None:
        """Only covered pixels and valid lights are stored; the dense field is rebuilt exactly."""
        rf = synthetic_field()
        info = write_field(tmp_path / "a.safetensors", rf)
        compact = read_field(tmp_path / "a.safetensors", dense=False)
        covered = int((rf.alpha > 0).sum())
        assert compact.is_compact and info["shape"] == [3, covered, 52] == list(compact.field.shape)
        assert torch.equal(compact.light_index, torch.nonzero(mirror_ball_valid(8).flatten()).flatten())
        assert torch.equal(compact.to_dense().field, rf.field)
        assert info["bytes"] < 0.8 * rf.field.numel() * 2  # measured 0.58 of the dense bfloat16 here

    def test_mmap(self, tmp_path: Path) -> None:
        """A mapped field equals the read one, and writing it never touches the file (copy-on-write)."""
        rf = synthetic_field()
        path = tmp_path / "a.safetensors"
        write_field(path, rf)
        before = path.read_bytes()
        read = read_field(path, dense=False)
        mapped = read_field(path, dense=False, mmap=True)
        assert torch.equal(mapped.field, read.field) and mapped.field.dtype == torch.bfloat16
        assert torch.equal(mapped.pixel_index, read.pixel_index) and mapped.meta == read.meta
        mapped.field.zero_()
        assert path.read_bytes() == before

    def test_atomic(self, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
        """A failing write leaves neither the file nor a temporary one."""
        import safetensors.torch

        def broken(tensors: dict, path: str, metadata: dict) -> None:
            Path(path).write_bytes(b"partial")
            raise OSError("disk full")

        monkeypatch.setattr(safetensors.torch, "save_file", broken)
        with pytest.raises(OSError, match="disk full"):
            write_field(tmp_path / "a.safetensors", synthetic_field())
        assert list(tmp_path.iterdir()) == []

    def test_exception(self, tmp_path: Path) -> None:
        with pytest.raises(TypeCheckError, match="field must be a ReflectanceField"):
            write_field(tmp_path / "a.safetensors", torch.zeros(3))
        with pytest.raises(HDRIOError, match="missing.safetensors"):
            read_field(tmp_path / "missing.safetensors")
        (tmp_path / "junk.safetensors").write_bytes(b"not a safetensors file")
        with pytest.raises(HDRIOError, match="junk.safetensors"):
            read_field(tmp_path / "junk.safetensors")
        from safetensors.torch import save_file

        save_file({"x": torch.zeros(2)}, str(tmp_path / "other.safetensors"), metadata={"format": "other"})
        with pytest.raises(HDRIOError, match="is not a reflectance field"):
            read_field(tmp_path / "other.safetensors")


class TestShard:
    @given(st.integers(0, 40), st.integers(1, 7))
    def test_partition(self, n: int, workers: int) -> None:
        items = list(range(n))
        parts = [shard(items, i, workers) for i in range(workers)]
        assert sorted(x for part in parts for x in part) == items
        assert max(map(len, parts)) - min(map(len, parts)) <= 1

    def test_exception(self) -> None:
        with pytest.raises(ValueCheckError, match=r"worker_index must be an int in \[0, 2\)"):
            shard([1, 2], 2, 2)
        with pytest.raises(ValueCheckError, match="worker_count must be positive"):
            shard([1, 2], 0, 0)


VIEWS = (Camera(40.0, 4.0, 0.0, 0.0), Camera(40.0, 4.0, 30.0, 10.0))


@pytest.fixture()
def fake_subjects(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """make_subject replaced by spheres (the cache must not depend on the subject generator's speed); returns
    the list of seeds that render_olat was called for."""
    v, f = _icosphere(2)

    def make_subject(seed: int) -> SimpleNamespace:
        mat = SimpleNamespace(kind="diffuse", albedo=(0.5, 0.5, 0.5), roughness=0.5, specular=0.5)
        ball = SimpleNamespace(name="ball", vertices=v, faces=f, material=mat)
        return SimpleNamespace(seed=seed, split="train" if seed % 2 else "eval", skin_tone=1 + seed % 10,
                               parts=[ball], face_landmarks=v, params={})

    rendered: list[int] = []
    render = cache.render_olat

    def counting_render(subject, camera, **kw):
        rendered.append(subject.seed)
        return render(subject, camera, **kw)

    monkeypatch.setattr("kornia_ilum.synth.lightstage.subjects.make_subject", make_subject)
    monkeypatch.setattr(cache, "render_olat", counting_render)
    return rendered


class TestBuildCache:
    kw: ClassVar[dict] = {"size": 16, "spp": 4, "lighting_size": 4, "threads": 1, "progress": False}

    def test_sharded_and_resumed(self, tmp_path: Path, fake_subjects: list[int]) -> None:
        m0 = build_cache(tmp_path, [3, 4], VIEWS, worker_index=0, worker_count=2, **self.kw)
        assert len(m0["entries"]) == 2 and fake_subjects == [3, 4]
        manifest = build_cache(tmp_path, [3, 4], VIEWS, worker_index=1, worker_count=2, **self.kw)
        assert [(e["subject_seed"], e["view_index"]) for e in manifest["entries"]] == [(3, 0), (3, 1), (4, 0), (4, 1)]
        assert json.loads((tmp_path / "manifest.json").read_text()) == manifest
        for e in manifest["entries"]:
            path = tmp_path / e["path"]
            assert path.stat().st_size == e["bytes"] and e["path"] == field_path(e["subject_seed"], e["view_index"])
            assert e["camera"]["size"] == 16 and e["dtype"] == "bfloat16" and e["render_seconds"] > 0
            assert e["split"] == ("train" if e["subject_seed"] % 2 else "eval")
            rf = read_field(path)
            assert rf.subject_seed == e["subject_seed"] and rf.camera == Camera(**e["camera"])
        assert not list(tmp_path.rglob("*.tmp"))

        fake_subjects.clear()  # resume: everything is intact, nothing renders
        build_cache(tmp_path, [3, 4], VIEWS, worker_index=0, worker_count=1, **self.kw)
        assert fake_subjects == []

        victim = tmp_path / field_path(4, 1)
        victim.write_bytes(victim.read_bytes()[:-1] + b"x")  # corrupt one file: only it renders again
        build_cache(tmp_path, [3, 4], VIEWS, **self.kw)
        assert fake_subjects == [4]
        assert read_field(victim).subject_seed == 4

        fake_subjects.clear()  # other settings: rendered again
        build_cache(tmp_path, [3], VIEWS, **{**self.kw, "spp": 9})
        assert fake_subjects == [3, 3]
        entries = {(e["subject_seed"], e["view_index"]): e for e in read_manifest(tmp_path)["entries"]}
        assert entries[(3, 0)]["spp"] == 9 and entries[(4, 0)]["spp"] == 4

    def test_read_manifest(self, tmp_path: Path) -> None:
        assert read_manifest(tmp_path)["entries"] == []
        (tmp_path / "manifest.w000of002.json").write_text("{broken")
        with pytest.raises(HDRIOError, match="manifest.w000of002.json"):
            read_manifest(tmp_path)

    def test_exception(self, tmp_path: Path) -> None:
        with pytest.raises(TypeCheckError, match="views must be a non-empty sequence of Camera"):
            build_cache(tmp_path, [1], [(30.0, 1.0, 0.0, 0.0)], progress=False)
        with pytest.raises(ValueCheckError, match=r"worker_index must be an int in \[0, 2\)"):
            build_cache(tmp_path, [1], VIEWS, worker_index=5, worker_count=2, progress=False)

    def test_default_views(self) -> None:
        assert len(cache.DEFAULT_VIEWS) == 3 and cache.DEFAULT_VIEWS[0].yaw_deg == 0.0
        assert {v.yaw_deg for v in cache.DEFAULT_VIEWS} == {0.0, 25.0, -25.0}
        assert np.ptp([v.fov_deg for v in cache.DEFAULT_VIEWS]) > 0
