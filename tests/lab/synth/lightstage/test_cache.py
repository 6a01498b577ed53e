"""The reflectance-field cache (kornia_ilum_lab.synth.lightstage.cache): files, manifest, resume, shards.

The build_cache tests render with Mitsuba (slow).
"""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace
from typing import ClassVar

import numpy as np
import pytest
import safetensors.torch
import torch
from hypothesis import given
from hypothesis import strategies as st
from safetensors import safe_open
from safetensors.torch import save_file

from kornia_ilum.core.errors import HDRIOError, IlumError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum_lab.synth.lightstage import cache
from kornia_ilum_lab.synth.lightstage.cache import (
    FixedViews,
    SampledViews,
    Workers,
    build_cache,
    field_path,
    read_field,
    read_manifest,
    shard,
    write_field,
)
from kornia_ilum_lab.synth.lightstage.field import ReflectanceField
from kornia_ilum_lab.synth.lightstage.scene import Camera
from kornia_ilum_lab.synth.lightstage.settings import Auto, OnePass, Reference
from kornia_ilum_lab.synth.lightstage.subjects.base import icosphere

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

class SphereSource:
    """Subjects that are spheres (picklable, for the worker processes): the cache must not depend on the subject
    generator's speed. ``face_landmarks`` are a 0.15 m tall box around the sphere's front."""

    name = "spheres"

    def sample(self, seed: int) -> SimpleNamespace:
        v, f = icosphere(2)
        v = (0.1 * v).astype(np.float32)
        mat = SimpleNamespace(kind="diffuse", albedo=(0.5, 0.5, 0.5), roughness=0.5, specular=0.5)
        ball = SimpleNamespace(name="ball", vertices=v, faces=f, material=mat, normals=None, uvs=None)
        lm = np.array([[-0.07, -0.075, 0.05], [0.07, 0.075, 0.05], [0.0, 0.0, 0.1]], np.float32)
        return SimpleNamespace(seed=seed, split="train" if seed % 2 else "eval", skin_tone=1 + seed % 10,
                               parts=[ball], face_landmarks=lm, params={"radius": 0.1, "kind": "ball", "v": [1]},
                               face_albedo=(0.5, 0.5, 0.5), source="spheres")

@pytest.fixture()
def rendered(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """render_olat counted (in this process): the list of subject seeds it was called for."""
    seen: list[int] = []
    render = cache.render_olat

    def counting_render(subject, camera, **kw):
        seen.append(subject.seed)
        return render(subject, camera, **kw)

    monkeypatch.setattr(cache, "render_olat", counting_render)
    return seen

@pytest.mark.slow
class TestBuildCache:
    kw: ClassVar[dict] = {"renderer": Auto(spp=1, lighting_size=4), "workers": Workers(processes=1),
                          "progress": False}

    def test_views_framed_wider(self) -> None:
        """A smaller face fraction frames every view from further away, and is part of the cache's settings."""
        wide = SampledViews(2, size=16, fraction=0.25)
        assert wide.label == "sample_views(n=2, fraction=0.25)" != SampledViews(2, size=16).label
        with pytest.raises(ValueCheckError, match="fraction"):
            SampledViews(2, fraction=1.0)

    def test_random_views_sharded_and_resumed(self, tmp_path: Path, rendered: list[int]) -> None:
        src = SphereSource()
        views = SampledViews(2, size=16)
        m0 = build_cache(src, [3, 4, 5], out_dir=tmp_path, renderer=self.kw["renderer"], views=views,
                         workers=Workers(processes=1, index=0, count=2), progress=False)
        assert len(m0["entries"]) == 4 and rendered == [3, 3, 5, 5]  # a subject's views in one go
        manifest = build_cache(src, [3, 4, 5], out_dir=tmp_path, renderer=self.kw["renderer"], views=views,
                               workers=Workers(processes=1, index=1, count=2), progress=False)
        assert [(e["subject_seed"], e["view_index"]) for e in manifest["entries"]] == [
            (3, 0), (3, 1), (4, 0), (4, 1), (5, 0), (5, 1)]
        on_disk = json.loads((tmp_path / "manifest.json").read_text())
        assert on_disk == {k: v for k, v in manifest.items() if k != "run"}
        assert on_disk["format"] == "kornia_ilum.olat-cache.v2"
        for e in manifest["entries"]:
            path = tmp_path / e["path"]
            assert path.stat().st_size == e["bytes"] and e["path"] == field_path(e["subject_seed"], e["view_index"])
            assert e["camera"]["size"] == 16 and e["dtype"] == "bfloat16" and e["render_seconds"] > 0
            assert e["split"] == ("train" if e["subject_seed"] % 2 else "eval")
            assert e["source"] == "spheres" and e["views"] == "sample_views(n=2)" and e["peak_rss_mb"] > 10
            assert e["face_albedo"] == [0.5, 0.5, 0.5] and e["params"] == {"kind": "ball", "radius": 0.1}
            assert e["skin_tone"] == 1 + e["subject_seed"] % 10
            rf = read_field(path)
            assert rf.subject_seed == e["subject_seed"] and rf.camera == Camera(**e["camera"])
            assert rf.meta["source"] == "spheres"
        cams = [Camera(**e["camera"]) for e in manifest["entries"] if e["subject_seed"] == 3]
        assert cams[0].yaw_deg * cams[1].yaw_deg < 0  # two views: one left, one right
        assert not list(tmp_path.rglob("*.tmp"))

        rendered.clear()  # resume: everything is intact, nothing renders
        again = build_cache(src, [3, 4, 5], out_dir=tmp_path, views=views, **self.kw)
        assert rendered == [] and again["run"]["rendered"] == 0

        victim = tmp_path / field_path(4, 1)
        victim.write_bytes(victim.read_bytes()[:-1] + b"x")  # corrupt one file: only it renders again
        build_cache(src, [3, 4, 5], out_dir=tmp_path, views=views, **self.kw)
        assert rendered == [4]
        assert read_field(victim).subject_seed == 4

        rendered.clear()  # other settings: rendered again
        build_cache(src, [3], out_dir=tmp_path, views=views,
                    **{**self.kw, "renderer": Auto(spp=4, lighting_size=4)})
        assert rendered == [3, 3]
        entries = {(e["subject_seed"], e["view_index"]): e for e in read_manifest(tmp_path)["entries"]}
        assert entries[(3, 0)]["spp_requested"] == 4 and entries[(4, 0)]["spp_requested"] == 1

    def test_two_worker_processes(self, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
        """workers=2 spawns two processes; their manifests merge; the summary and progress are printed."""
        manifest = build_cache(SphereSource(), [0, 1, 2], out_dir=tmp_path,
                               renderer=Auto(spp=1, lighting_size=4), views=SampledViews(2, size=16),
                               workers=Workers(processes=2), progress=True, summary=True)
        assert len(manifest["entries"]) == 6 and manifest["run"]["rendered"] == 6
        assert sorted(p.name for p in tmp_path.glob("manifest.w*")) == ["manifest.w000of002.json",
                                                                        "manifest.w001of002.json"]
        assert sorted(e["subject_seed"] for e in cache._read_manifest_file(tmp_path / "manifest.w001of002.json")) \
            == [1, 1]
        captured = capsys.readouterr()
        assert "subject-views: 6/6 (100 %)" in captured.err and "ETA" in captured.err
        assert "6 subject-views of 3 subjects" in captured.out and "MB on disk" in captured.out

    def test_worker_failure(self, tmp_path: Path) -> None:
        with pytest.raises(IlumError, match="cache worker process failed: AttributeError"):
            build_cache(BrokenSource(), [0, 1], out_dir=tmp_path, renderer=Auto(spp=1, lighting_size=4),
                        views=SampledViews(1, size=16), workers=Workers(processes=2), progress=False)

    def test_fixed_views(self, tmp_path: Path, rendered: list[int], monkeypatch) -> None:
        monkeypatch.setattr("kornia_ilum_lab.synth.lightstage.subjects.mannequin.make_subject",
                            SphereSource().sample)
        manifest = build_cache("mannequin", [3], out_dir=tmp_path, views=FixedViews(VIEWS, size=16),
                               **self.kw)
        assert [Camera(**e["camera"]) for e in manifest["entries"]] == [
            Camera(40.0, 4.0, 0.0, 0.0, size=16), Camera(40.0, 4.0, 30.0, 10.0, size=16)]
        assert manifest["entries"][0]["source"] == "mannequin" and manifest["entries"][0]["views"] == "fixed"
        rendered.clear()
        build_cache("mannequin", [3], out_dir=tmp_path, views=FixedViews(VIEWS, size=16), **self.kw)
        assert rendered == []  # the same settings: resumed

    def test_read_v1_field(self, tmp_path: Path) -> None:
        write_field(tmp_path / "a.safetensors", synthetic_field())
        with safe_open(str(tmp_path / "a.safetensors"), framework="pt") as fh:
            meta, tensors = fh.metadata(), {k: fh.get_tensor(k) for k in fh.keys()}  # noqa: SIM118
        save_file(tensors, str(tmp_path / "v1.safetensors"), metadata={**meta, "format": "kornia_ilum.olat.v1"})
        assert torch.equal(read_field(tmp_path / "v1.safetensors").field, synthetic_field().field)

    def test_read_manifest(self, tmp_path: Path) -> None:
        assert read_manifest(tmp_path)["entries"] == []
        (tmp_path / "manifest.w000of002.json").write_text("{broken")
        with pytest.raises(HDRIOError, match="manifest.w000of002.json"):
            read_manifest(tmp_path)

    def test_exception(self, tmp_path: Path) -> None:
        with pytest.raises(TypeCheckError, match="views must be a non-empty sequence of Camera"):
            build_cache("mannequin", [1], out_dir=tmp_path, views=FixedViews([(30.0, 1.0, 0.0, 0.0)]),
                        progress=False)
        with pytest.raises(ValueCheckError, match=r"index must be an int in \[0, 2\)"):
            build_cache("mannequin", [1], out_dir=tmp_path, workers=Workers(index=5, count=2), progress=False)
        with pytest.raises(TypeCheckError, match="source must be a SubjectSource"):
            build_cache(3, [1], out_dir=tmp_path, progress=False)
        with pytest.raises(ValueCheckError, match="processes must be positive"):
            build_cache("mannequin", [1], out_dir=tmp_path, workers=Workers(processes=0), progress=False)
        with pytest.raises(TypeCheckError, match="out_dir must be a folder path"):  # no cameras overload
            build_cache(tmp_path, [1], out_dir=list(VIEWS), progress=False)
        with pytest.raises(TypeCheckError, match="renderer must be OnePass, Reference or Auto"):
            build_cache("mannequin", [1], out_dir=tmp_path, renderer={"spp": 1}, progress=False)
        with pytest.raises(TypeCheckError, match="views must be FixedViews or SampledViews"):
            build_cache("mannequin", [1], out_dir=tmp_path, views=VIEWS, progress=False)
        with pytest.raises(TypeCheckError, match="workers must be Workers"):
            build_cache("mannequin", [1], out_dir=tmp_path, workers=1, progress=False)

    def test_renderer_settings_are_part_of_the_cache(self, tmp_path: Path, rendered: list[int]) -> None:
        """Explicit renderer settings are recorded and matched on resume; Auto with seed 0 records none."""
        views, workers = SampledViews(1, size=16), Workers(processes=1)
        onepass = OnePass(lighting_size=4, spp=2, subsurface=False)
        build_cache(SphereSource(), [1], out_dir=tmp_path, renderer=onepass, views=views, workers=workers,
                    progress=False)
        entry = read_manifest(tmp_path)["entries"][0]
        assert entry["renderer"] == onepass.to_dict() and entry["spp_requested"] == 2
        assert read_field(tmp_path / entry["path"]).meta["post"] == []
        rendered.clear()
        build_cache(SphereSource(), [1], out_dir=tmp_path, renderer=onepass, views=views, workers=workers,
                    progress=False)
        assert rendered == []
        build_cache(SphereSource(), [1], out_dir=tmp_path, renderer=OnePass(lighting_size=4, spp=2),
                    views=views,
                    workers=workers, progress=False)
        assert rendered == [1]  # subsurface on: another render
        build_cache(SphereSource(), [1], out_dir=tmp_path, renderer=Reference(lighting_size=4, spp=1),
                    views=views,
                    workers=workers, progress=False)
        assert "renderer" in read_manifest(tmp_path)["entries"][0] and rendered == [1, 1]
        build_cache(SphereSource(), [1], out_dir=tmp_path, renderer=Auto(lighting_size=4, spp=1), views=views,
                    workers=workers, progress=False)
        assert "renderer" not in read_manifest(tmp_path)["entries"][0] and rendered == [1, 1, 1]

    def test_default_views(self) -> None:
        assert len(cache.DEFAULT_VIEWS) == 3 and cache.DEFAULT_VIEWS[0].yaw_deg == 0.0
        assert {v.yaw_deg for v in cache.DEFAULT_VIEWS} == {0.0, 25.0, -25.0}
        assert np.ptp([v.fov_deg for v in cache.DEFAULT_VIEWS]) > 0

class TestViewsAndWorkers:
    def test_fixed_views(self) -> None:
        views = FixedViews(list(VIEWS), size=24)
        assert views.count == 2 and views.label == "fixed" and all(c.size == 24 for c in views.cameras)
        assert views.cameras[1] == Camera(40.0, 4.0, 30.0, 10.0, size=24) and isinstance(views.cameras, tuple)
        defaults = tuple(Camera(**{**c.to_dict(), "size": 192}) for c in cache.DEFAULT_VIEWS)
        assert FixedViews().cameras == defaults

    def test_sampled_views_and_workers(self) -> None:
        assert SampledViews().count == 4 and SampledViews(2).label == "sample_views(n=2)"
        workers = Workers()
        assert (workers.processes, workers.index, workers.count, workers.threads) == (2, 0, 1, 1)

    @pytest.mark.parametrize(
        ("make", "error", "match"),
        [
            (lambda: FixedViews(()), TypeCheckError, "views must be a non-empty sequence of Camera"),
            (lambda: FixedViews("front"), TypeCheckError, "views must be a non-empty sequence of Camera"),
            (lambda: FixedViews(size=0), ValueCheckError, "size must be positive"),
            (lambda: SampledViews(0), ValueCheckError, "views_per_subject must be positive"),
            (lambda: SampledViews(size=-1), ValueCheckError, "size must be positive"),
            (lambda: Workers(processes=0), ValueCheckError, "processes must be positive"),
            (lambda: Workers(count=0), ValueCheckError, "count must be positive"),
            (lambda: Workers(index=1), ValueCheckError, r"index must be an int in \[0, 1\)"),
            (lambda: Workers(threads=0), ValueCheckError, "threads must be positive"),
        ],
    )
    def test_exception(self, make, error: type, match: str) -> None:
        with pytest.raises(error, match=match):
            make()

class BrokenSource:
    name = "broken"

    def sample(self, seed: int):
        return None  # no face_landmarks: the worker fails
