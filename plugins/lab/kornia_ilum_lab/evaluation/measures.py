r"""What the evaluation's checks measure of a lighting estimate: its energy and dominant direction, and the
quantiles they are summarised by.

An estimator here is any callable that takes ``(B, 3, H, W)`` float sRGB crops in ``[0, 1]`` and returns a
:class:`~kornia_ilum.estimators.LightingEstimate` (or a tensor) whose ``mirror_ball`` ``(B, 3, 32, 32)`` is
linear lighting in the units of the photo (docs/conventions.rst, "Units of lighting"). The energy is
:func:`~kornia_ilum.metrics.lighting_energy` (the integral over the sphere of the mean over R, G, B); the
direction is :func:`dominant_direction` (the energy-weighted mean direction, the lighting's l = 1 "dipole").
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import torch

from kornia_ilum.core.check import check_tensor
from kornia_ilum.geometry import mirror_ball_directions, mirror_ball_solid_angles
from kornia_ilum.metrics import lighting_energy
from kornia_ilum_lab.evaluation.evaluate import fit_crops

__all__ = ["Estimator", "angle_degrees", "as_floats", "dominant_direction", "estimates", "median_of", "quantiles"]

#: An estimator as the checks call it (module docstring).
Estimator = Callable[[torch.Tensor], Any]


# ----------------------------------------------------------------------------------------------
# energy and direction


def dominant_direction(mirror_ball: torch.Tensor) -> torch.Tensor:
    r"""The lighting's dominant direction: the energy-weighted mean of the directions, normalised.

    :math:`d = \mathrm{normalize}(\sum_p \Omega_p \bar L_p \, \omega_p)`, with :math:`\bar L` the mean over R,
    G, B and :math:`\omega_p` the direction of pixel ``p``
    (:func:`~kornia_ilum.geometry.mirror_ball_directions`; light arriving *from* :math:`\omega_p`, in the
    camera frame: +X right, +Y up, +Z toward the camera). A lighting whose weighted sum of directions is
    below 1e-3 of its energy (black, or uniform: the grid's rim leaves 1.5e-4 at ``S = 32``) gives the zero
    vector.

    Args:
        mirror_ball: linear lighting.

    Returns:
        ``(B, 3)`` unit vectors (or zero).

    Shape:
        - mirror_ball: :math:`(B, 3, S, S)`
        - Output: :math:`(B, 3)`

    Convention:
        docs/conventions.rst, "Frames" (light arriving from the direction) and "Mirror ball".

    Examples:
        >>> from kornia_ilum.geometry import direction_to_mirror_ball, mirror_ball_valid, uv_to_pixel
        >>> ball = torch.zeros(1, 3, 32, 32)
        >>> pixel = uv_to_pixel(direction_to_mirror_ball(torch.tensor([0.6, 0.8, 0.0])), 32)
        >>> col, row = pixel.long().tolist()
        >>> ball[..., row, col] = 100.0  # a small source up and to the right
        >>> d = dominant_direction(ball)[0]
        >>> bool(d @ torch.tensor([0.6, 0.8, 0.0]) > 0.99), round(d.norm().item(), 6)
        (True, 1.0)
        >>> dominant_direction(torch.ones(1, 3, 32, 32) * mirror_ball_valid(32))  # uniform: no direction
        tensor([[0., 0., 0.]])
    """
    check_tensor(mirror_ball, "mirror_ball", ["B", "3", "S", "S"])
    s = mirror_ball.shape[-1]
    d, _ = mirror_ball_directions(s, device=mirror_ball.device, dtype=mirror_ball.dtype)
    omega = mirror_ball_solid_angles(s, device=mirror_ball.device, dtype=mirror_ball.dtype)
    w = mirror_ball.mean(1) * omega  # (B, S, S), 0 off the ball
    v = torch.einsum("bhw,hwc->bc", w, d)
    norm = v.norm(dim=-1, keepdim=True)
    vanishes = norm <= 1e-3 * w.abs().sum((-2, -1))[:, None]  # a uniform lighting (up to the grid), or black
    return torch.where(vanishes, torch.zeros_like(v), v / norm.clamp(min=torch.finfo(v.dtype).tiny))


def estimates(estimator: Estimator, batches: Iterator[torch.Tensor], directions: bool = False,
              spreads: bool = False) -> tuple[torch.Tensor, torch.Tensor | None, torch.Tensor | None]:
    """The estimator on each batch of float crops: energies ``(N,)`` float64 (and directions ``(N, 3)``, and
    the estimates' ``log_energy_spread`` ``(N,)`` float64). With ``spreads``, an estimator that gives no spread
    stops the pass at the first batch: its energies so far, ``None``, ``None``."""
    energy, direction, spread = [], [], []
    with torch.inference_mode():
        for crops in batches:
            out = estimator(fit_crops(estimator, crops))
            ball = getattr(out, "mirror_ball", out).double()
            energy.append(lighting_energy(ball))
            if directions:
                direction.append(dominant_direction(ball))
            if spreads:
                b = getattr(out, "log_energy_spread", None)
                if b is None:
                    return torch.cat(energy), None, None
                spread.append(b.double())
    return (torch.cat(energy), torch.cat(direction) if directions else None,
            torch.cat(spread) if spreads else None)


def as_floats(images: torch.Tensor) -> torch.Tensor:
    """uint8 codes to float32 in ``[0, 1]``; float crops as they are (float32)."""
    return images.float() / 255.0 if images.dtype == torch.uint8 else images.float()


# ----------------------------------------------------------------------------------------------
# summaries


def quantiles(x: torch.Tensor) -> dict[str, float | int | None]:
    """Median and quartiles of the finite values of ``x`` (``None`` where there are none), and their count."""
    x = x.double()
    x = x[torch.isfinite(x)]
    if x.numel() == 0:
        return {"median": None, "q25": None, "q75": None, "count": 0}
    q = torch.quantile(x, torch.tensor([0.5, 0.25, 0.75], dtype=torch.float64)).tolist()
    return {"median": q[0], "q25": q[1], "q75": q[2], "count": int(x.numel())}


def median_of(x: torch.Tensor) -> float | None:
    return quantiles(x)["median"]  # type: ignore[return-value]


def angle_degrees(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    r"""The angle between unit vectors, in degrees; NaN where either is the zero vector (no direction).

    Args:
        a, b: unit (or zero) vectors.

    Returns:
        the angles, float64.

    Shape:
        - a, b: :math:`(N, 3)`
        - Output: :math:`(N,)`

    Examples:
        >>> angle_degrees(torch.tensor([[1.0, 0, 0], [1.0, 0, 0]]), torch.tensor([[0.0, 1, 0], [0.0, 0, 0]]))
        tensor([90., nan], dtype=torch.float64)
    """
    a, b = a.double(), b.double()
    cos = (a * b).sum(-1).clamp(-1.0, 1.0)
    none = (a.norm(dim=-1) == 0) | (b.norm(dim=-1) == 0)
    return torch.where(none, float("nan"), torch.rad2deg(torch.arccos(cos)))
