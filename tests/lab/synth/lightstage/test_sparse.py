"""kornia_ilum_lab.synth.lightstage.sparse: the sparse-relighting sidecars of a cache, written once, mapped back,
refused when stale, and the portrait dataset relit from them (``relight_eps``) close to the exact images."""

from __future__ import annotations

import os
import shutil

import pytest
import torch

from kornia_ilum.core.errors import HDRIOError, ValueCheckError
from kornia_ilum.render import prepare_sparse, relight_sparse
from kornia_ilum_lab.synth.lightstage import read_field, read_manifest, read_sparse, write_sparse_cache
from kornia_ilum_lab.synth.lightstage.sparse import sparse_path
from tests.lab.synth.lightstage.portraits.common import OFF, small

pytestmark = pytest.mark.slow  # the cache is rendered with Mitsuba


@pytest.fixture
def cache(tiny_cache, tmp_path):
    """A copy of the session's tiny cache (two mannequins, one 48 px view each), which the tests may change."""
    return shutil.copytree(tiny_cache, tmp_path / "cache")


def test_written_once_mapped_back_and_equal_to_preparing_the_field(cache) -> None:
    assert write_sparse_cache(cache, rank=8) == 2 and write_sparse_cache(cache) == 0  # up to date: kept
    entry = read_manifest(cache)["entries"][0]
    field = read_field(cache / entry["path"], dense=False)
    mapped = read_sparse(cache / entry["path"])
    assert mapped.field.is_meta and mapped.field.shape == field.field.shape
    fresh = prepare_sparse(field.field, rank=8)
    torch.manual_seed(0)
    lights = torch.rand(3, field.field.shape[-1], 3) ** 8 * 100  # a few bright lights
    torch.testing.assert_close(relight_sparse(mapped, lights, 0.01), relight_sparse(fresh, lights, 0.01))


def test_a_stale_or_missing_sidecar_is_refused(cache) -> None:
    entry = read_manifest(cache)["entries"][0]
    field_path = cache / entry["path"]
    with pytest.raises(HDRIOError, match="write_sparse_cache"):
        read_sparse(field_path)
    write_sparse_cache(cache)
    stat = field_path.stat()
    os.utime(field_path, ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9))  # the field was rewritten
    with pytest.raises(HDRIOError, match="does not match"):
        read_sparse(field_path)
    assert write_sparse_cache(cache) == 1 and sparse_path(field_path).is_file()


def test_the_dataset_relit_sparsely_stays_close_to_the_exact_images(cache) -> None:
    write_sparse_cache(cache)
    exact = list(small(cache, split=None, camera=OFF, length=8))
    sparse = list(small(cache, split=None, camera=OFF, length=8, relight_eps=0.01))
    for a, b in zip(exact, sparse, strict=True):
        # the same draws: only the relighting differs, and the exposure metered from it
        torch.testing.assert_close(a["mirror_ball"] / a["exposure"], b["mirror_ball"] / b["exposure"])
        assert abs(float(a["exposure"] / b["exposure"]) - 1) < 0.05
        difference = (a["image"].float() - b["image"].float()).abs().mean()
        assert float(difference) < 2.0, difference  # 8-bit codes, the mean over the crop
    with pytest.raises(ValueCheckError, match="relight_eps"):
        small([read_field(cache / read_manifest(cache)["entries"][0]["path"], dense=False)], split=None,
              relight_eps=0.01)
