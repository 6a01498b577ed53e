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
    """

    latlong: torch.Tensor
    mirror_ball: torch.Tensor
    label: Label
    source: str
    params: dict[str, Any] = field(default_factory=dict)


@runtime_checkable
class EnvironmentSource(Protocol):
    """Anything that draws environments: ``sample(generator)`` must depend only on the generator's state."""

    label: Label

    def sample(self, generator: torch.Generator) -> Environment:  # pragma: no cover - protocol
        ...
