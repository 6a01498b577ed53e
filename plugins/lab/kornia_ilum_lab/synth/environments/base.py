"""The lighting environment record and the protocol every environment source follows.

Convention:
    Everything is in the camera frame of docs/conventions.rst (+X right, +Y up, +Z toward the camera; a
    direction is where light arrives *from*), linear HDR radiance, never negative. ``latlong`` is an
    ``H x 2H`` equirectangular map (docs/conventions.rst, "Lat-long"), ``mirror_ball`` the 32 x 32 equal-area
    mirror ball obtained from it by energy-conserving resampling
    (:func:`kornia_ilum.geometry.latlong_to_mirror_ball`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal, Protocol, runtime_checkable

import torch

__all__ = ["Environment", "EnvironmentSource", "Label"]

Label = Literal["indoor", "outdoor"]


@dataclass
class Environment:
    """One lighting environment.

    Attributes:
        latlong: ``(3, H, 2H)`` linear HDR lat-long map in the camera frame (for backgrounds and SH).
        mirror_ball: ``(3, 32, 32)`` linear HDR mirror ball, 0 outside the ball (the estimators' target).
        label: ``"indoor"`` or ``"outdoor"``.
        source: where it came from, e.g. ``"real:city.exr"``, ``"sky:clear"``, ``"indoor:room"``.
        params: the sampled parameters (JSON-serialisable), enough to reproduce and to describe it.

    Examples:
        >>> env = Environment(torch.ones(3, 8, 16), torch.ones(3, 32, 32), "outdoor", "constant")
        >>> env.label, tuple(env.latlong.shape), env.params
        ('outdoor', (3, 8, 16), {})
    """

    latlong: torch.Tensor
    mirror_ball: torch.Tensor
    label: Label
    source: str
    params: dict[str, Any] = field(default_factory=dict)


@runtime_checkable
class EnvironmentSource(Protocol):
    """Anything that draws environments: ``sample(generator)`` must depend only on the generator's state.

    Attributes:
        label: ``"indoor"`` or ``"outdoor"``, the label of the environments it draws.

    Examples:
        >>> class Uniform:  # a constant white environment, whatever the generator
        ...     label = "indoor"
        ...     def sample(self, generator):
        ...         return Environment(torch.ones(3, 8, 16), torch.ones(3, 32, 32), "indoor", "uniform")
        >>> isinstance(Uniform(), EnvironmentSource)  # a structural protocol: no base class needed
        True
        >>> Uniform().sample(torch.Generator().manual_seed(0)).source
        'uniform'
    """

    label: Label

    def sample(self, generator: torch.Generator) -> Environment:  # pragma: no cover - protocol
        ...
