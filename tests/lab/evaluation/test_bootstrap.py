"""kornia_ilum_lab.evaluation.bootstrap: intervals over subjects."""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.core.errors import ShapeError
from kornia_ilum_lab.evaluation import ratio_interval, subject_interval, subject_resamples


def test_resamples_draw_whole_subjects() -> None:
    # two subjects whose portraits all read 1 and 3: every resample's mean is 1, 2 or 3, never in between
    values = torch.tensor([1.0] * 5 + [3.0] * 5)
    subjects = [0] * 5 + [1] * 5
    out = subject_resamples(values, subjects, statistic=torch.mean, resamples=300, seed=1)
    assert set(out.tolist()) == {1.0, 2.0, 3.0}
    assert torch.equal(out, subject_resamples(values, subjects, statistic=torch.mean, resamples=300, seed=1))


def test_one_subject_has_no_spread_and_many_portraits_do_not_narrow_it() -> None:
    assert subject_interval(torch.tensor([2.0, 4.0, 6.0]), [7, 7, 7], statistic=torch.mean) == [4.0, 4.0]
    # the interval comes from the subjects: 100 portraits per subject do not make it 10 times narrower
    gen = torch.Generator().manual_seed(0)
    level = torch.randn(4, generator=gen)
    few = subject_interval(level, [0, 1, 2, 3], statistic=torch.mean)
    many = subject_interval(
        level.repeat_interleave(100), torch.arange(4).repeat_interleave(100), statistic=torch.mean
    )
    assert many[1] - many[0] > 0.5 * (few[1] - few[0])


def test_ratio_across_groups() -> None:
    groups = {"a": (torch.tensor([1.0, 1.2]), [0, 1]), "b": (torch.tensor([2.0, 2.4]), [2, 3])}
    out = ratio_interval(groups, torch.mean)
    assert out["max"] == "b" and out["min"] == "a" and abs(out["ratio"] - 2.0) < 1e-12
    assert out["interval"][0] <= out["ratio"] <= out["interval"][1]


def test_bad_input() -> None:
    with pytest.raises(ShapeError):
        subject_resamples(torch.ones(3), [0, 1])
    with pytest.raises(ShapeError):
        subject_resamples(torch.ones(0), [])
