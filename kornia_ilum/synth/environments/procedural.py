r"""Helpers shared by the procedural sources (:mod:`~kornia_ilum.synth.environments.sky`, ``indoor``).

:class:`Draw` turns a :class:`torch.Generator` into the scalar draws the scene samplers make (uniform,
log-uniform, integer, weighted choice, coin flip), one draw of the generator each, so that a scene depends
only on the generator's state. :func:`latlong_pixels` is the lat-long grid the scenes are rendered on, flat
and cached per height.

Convention:
    The lat-long grid of docs/conventions.rst ("Lat-long"), in its camera frame ("Frames"); float32 on the
    CPU. Every draw is float64 (or an int) from the generator passed in: no other source of randomness.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache
from typing import Any

import torch

from kornia_ilum.geometry import latlong_directions, latlong_solid_angles

__all__ = ["Draw", "latlong_pixels"]


@lru_cache(maxsize=8)
def latlong_pixels(height: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Cached float32 pixel directions ``(H W, 3)`` and exact solid angles ``(H W,)`` of the lat-long grid.

    The tensors are shared between calls: do not modify them in place.

    Examples:
        >>> d, om = latlong_pixels(4)
        >>> tuple(d.shape), tuple(om.shape), round(float(om.sum()) / math.pi, 4)
        ((32, 3), (32,), 4.0)
    """
    d = latlong_directions(height, dtype=torch.float32).reshape(-1, 3)
    om = latlong_solid_angles(height, dtype=torch.float32).reshape(-1)
    return d, om


class Draw:
    """Scalar draws from a torch generator (the only source of randomness).

    Args:
        generator: the generator every draw reads from.

    Examples:
        >>> draw = Draw(torch.Generator().manual_seed(0))
        >>> 2.0 <= draw.uniform(2.0, 3.0) < 3.0, draw.integer(1, 1), draw.choice(["a"])
        (True, 1, 'a')
    """

    def __init__(self, generator: torch.Generator) -> None:
        self.g = generator

    def uniform(self, lo: float, hi: float) -> float:
        """Uniform in ``[lo, hi)`` (one float64 draw)."""
        return lo + (hi - lo) * float(torch.rand((), generator=self.g, dtype=torch.float64))

    def log_uniform(self, lo: float, hi: float) -> float:
        """Log-uniform in ``[lo, hi)``, ``lo > 0`` (one float64 draw)."""
        return math.exp(self.uniform(math.log(lo), math.log(hi)))

    def integer(self, lo: int, hi: int) -> int:
        """Uniform in ``[lo, hi]`` inclusive."""
        return int(torch.randint(lo, hi + 1, (), generator=self.g))

    def choice(self, options: Sequence[Any], weights: Sequence[float] | None = None) -> Any:
        """One of ``options``, with probability proportional to ``weights`` (equal when ``None``)."""
        w = (
            torch.ones(len(options), dtype=torch.float64)
            if weights is None
            else torch.tensor(weights, dtype=torch.float64)
        )
        return options[int(torch.multinomial(w, 1, generator=self.g))]

    def bernoulli(self, p: float) -> bool:
        """``True`` with probability ``p`` (one uniform draw)."""
        return self.uniform(0.0, 1.0) < p
