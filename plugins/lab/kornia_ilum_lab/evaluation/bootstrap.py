r"""Intervals over subjects: the bootstrap that the per-tone figures of ``kornia-ilum evaluate`` carry.

The eval portraits of one subject are not independent draws: the same face under many lightings shares its
albedo, its shape and its accessories, and an estimator that misreads one face misreads most of its
portraits. So the unit of resampling is the subject (a cluster bootstrap; Davison and Hinkley 1997, Sec. 3.8):
each resample draws the group's subjects with replacement and takes all their portraits, and the interval is
the 2.5 and 97.5 percentiles of the statistic over the resamples. With four subjects in a tone the interval is
wide, and it should be: it says how much the tone's figure depends on which four faces were rendered.

- :func:`subject_resamples`: the statistic over the resamples of one group (``(R,)``), so that callers can
  combine groups resample by resample (the spread across tones, :func:`ratio_interval`);
- :func:`subject_interval`: the statistic's interval for one group;
- :func:`ratio_interval`: the largest over the smallest of per-group statistics, with its interval.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import torch

from kornia_ilum.core.check import check_positive_int
from kornia_ilum.core.errors import ShapeError

__all__ = ["RESAMPLES", "median", "ratio_interval", "subject_interval", "subject_resamples"]

#: Resamples per interval.
RESAMPLES = 1000

Statistic = Callable[[torch.Tensor], torch.Tensor]


def median(x: torch.Tensor) -> torch.Tensor:
    """The median of the finite values (the mean of the two middle ones for an even count); NaN for none."""
    x = x[torch.isfinite(x)]
    return torch.quantile(x, 0.5) if x.numel() else x.new_tensor(float("nan"))


def subject_resamples(values: torch.Tensor, subjects: Sequence[int] | torch.Tensor, *,
                      statistic: Statistic = median, resamples: int = RESAMPLES,
                      seed: int = 0) -> torch.Tensor:
    r"""``statistic`` of the portraits of ``resamples`` draws of the subjects with replacement.

    Args:
        values: ``(N,)`` one value per portrait.
        subjects: ``(N,)`` the subject of each portrait.
        statistic: ``(M,) -> ()``; the median of the finite values by default.
        resamples: the number of resamples ``R``.
        seed: the resamples' seed (the same seed, the same resamples of the same subjects).

    Returns:
        ``(R,)`` float64.

    Raises:
        ShapeError: ``values`` and ``subjects`` differ in length, or are empty.

    Examples:
        >>> values = torch.tensor([1.0, 1.0, 3.0, 3.0])
        >>> out = subject_resamples(values, [0, 0, 1, 1], resamples=200)
        >>> sorted(set(out.tolist()))  # both subjects, one of them twice, or the other
        [1.0, 2.0, 3.0]
    """
    check_positive_int(resamples, "resamples")
    values = values.double().flatten()
    subjects = torch.as_tensor(subjects).flatten()
    if len(values) != len(subjects) or len(values) == 0:
        raise ShapeError(f"values and subjects must be non-empty and of one length, got {len(values)} and "
                         f"{len(subjects)}")
    ids, which = torch.unique(subjects, return_inverse=True)
    members = [values[which == i] for i in range(len(ids))]
    generator = torch.Generator().manual_seed(seed)
    draws = torch.randint(len(ids), (resamples, len(ids)), generator=generator)
    return torch.stack([statistic(torch.cat([members[i] for i in draw.tolist()])) for draw in draws]).double()


def _percentiles(x: torch.Tensor, level: float) -> list[float]:
    x = x[torch.isfinite(x)]
    if x.numel() == 0:
        return [float("nan"), float("nan")]
    tail = (1.0 - level) / 2.0
    return torch.quantile(x, torch.tensor([tail, 1.0 - tail], dtype=x.dtype)).tolist()


def subject_interval(values: torch.Tensor, subjects: Sequence[int] | torch.Tensor, *,
                     statistic: Statistic = median, level: float = 0.95, resamples: int = RESAMPLES,
                     seed: int = 0) -> list[float]:
    r"""The ``level`` percentile interval of ``statistic`` over subject resamples (:func:`subject_resamples`).

    Args:
        values, subjects, statistic, resamples, seed: as :func:`subject_resamples`.
        level: the interval's coverage.

    Returns:
        ``[low, high]``; both equal the statistic where the group has one subject (no spread to draw).

    Examples:
        >>> values = torch.tensor([0.9, 1.0, 1.1, 1.9, 2.0, 2.1])
        >>> low, high = subject_interval(values, [0, 0, 0, 1, 1, 1])
        >>> 0.9 <= low < 1.5 < high <= 2.1
        True
    """
    return _percentiles(subject_resamples(values, subjects, statistic=statistic, resamples=resamples,
                                          seed=seed), level)


def ratio_interval(groups: dict[str, tuple[torch.Tensor, Sequence[int] | torch.Tensor]],
                   statistic: Statistic = median, *, level: float = 0.95, resamples: int = RESAMPLES,
                   seed: int = 0) -> dict[str, float | list[float]]:
    r"""The largest over the smallest of the groups' statistics (the spread across skin tones), with its interval.

    Each group is resampled over its own subjects (:func:`subject_resamples`, one seed per group), and the ratio
    is taken resample by resample.

    Args:
        groups: ``{name: (values, subjects)}``, at least one.
        statistic, level, resamples, seed: as :func:`subject_interval`.

    Returns:
        ``{"ratio": max / min of the statistics, "interval": [low, high], "max": name, "min": name}``.

    Examples:
        >>> groups = {"1": (torch.tensor([1.0, 1.0]), [0, 1]), "2": (torch.tensor([2.0, 2.0]), [2, 3])}
        >>> out = ratio_interval(groups)
        >>> out["ratio"], out["interval"], out["max"], out["min"]
        (2.0, [2.0, 2.0], '2', '1')
    """
    names = list(groups)
    point = torch.stack([statistic(v.double().flatten()) for v, _ in groups.values()])
    draws = torch.stack([subject_resamples(v, s, statistic=statistic, resamples=resamples, seed=seed + k)
                         for k, (v, s) in enumerate(groups.values())])
    ratio = draws.amax(0) / draws.amin(0)
    return {"ratio": float(point.max() / point.min()), "interval": _percentiles(ratio, level),
            "max": names[int(point.argmax())], "min": names[int(point.argmin())]}
