"""Tests of kornia_ilum.core.check: the shared input checks, Kornia's switch and the trusted block."""

from __future__ import annotations

import threading

import pytest
import torch

from kornia_ilum.core import NonFiniteError, ShapeError, check_tensor, checks_active, trusted


def test_trusted_skips_checks_only_inside_the_block() -> None:
    nan = torch.tensor([float("nan")])
    with trusted():
        assert not checks_active()
        check_tensor(nan, "x")  # not scanned
    assert checks_active()
    with pytest.raises(NonFiniteError):
        check_tensor(nan, "x")


def test_trusted_is_undone_by_an_exception() -> None:
    with pytest.raises(RuntimeError), trusted():
        raise RuntimeError("boom")
    assert checks_active()


def test_trusted_is_local_to_its_thread() -> None:
    seen = []
    with trusted():
        thread = threading.Thread(target=lambda: seen.append(checks_active()))
        thread.start()
        thread.join()
    assert seen == [True]


def test_a_dimension_name_used_twice_means_one_size() -> None:
    """A non-square mirror ball is a ShapeError where it enters, not a broadcasting error deep inside an op."""
    from kornia_ilum.metrics import total_radiance  # lazy: a higher layer, used here as the example of the bug

    check_tensor(torch.zeros(2, 3, 8, 8), "mirror_ball", ["B", "3", "S", "S"])
    with pytest.raises(ShapeError, match=r"\(B, 3, S, S\), got \(2, 3, 8, 6\)"):
        check_tensor(torch.zeros(2, 3, 8, 6), "mirror_ball", ["B", "3", "S", "S"])
    with pytest.raises(ShapeError, match="mirror_ball must have shape"):
        total_radiance(torch.ones(1, 3, 32, 16))
