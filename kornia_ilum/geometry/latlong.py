r"""The lat-long (equirectangular) grid of docs/conventions.rst ("Lat-long").

Convention:
    An ``H x 2H`` image. Pixel centre of row ``i``, column ``j``: ``phi = 2 pi (j + 0.5) / W - pi``,
    ``el = pi/2 - pi (i + 0.5) / H`` and ``d = (sin(phi) cos(el), sin(el), -cos(phi) cos(el))``.
    The centre column looks forward (-Z), the left half is -X, the top row is +Y. This is the common
    orientation of lat-long files (centre column = forward), so files need no extra rotation.
"""

from __future__ import annotations

import math

import torch

from kornia_ilum.core.check import check_positive_int, check_tensor

__all__ = [
    "latlong_angles",
    "latlong_directions",
    "latlong_solid_angles",
    "latlong_to_direction",
    "direction_to_latlong",
    "angles_to_latlong_pixel",
]


def latlong_angles(
    height: int, *, device: torch.device | str | None = None, dtype: torch.dtype = torch.float32
) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Azimuth ``phi`` and elevation ``el`` of the pixel centres, each ``(H, 2H)``.

    Args:
        height: the map's height ``H``; its width is ``2H``.
        device: device of the result.
        dtype: dtype of the result (computed in float64).

    Returns:
        ``(phi, el)`` in radians: ``phi`` in ``(-pi, pi)`` across the columns, ``el`` in ``(-pi/2, pi/2)``
        down the rows.

    Raises:
        TypeCheckError: ``height`` is not an int.
        ValueCheckError: ``height`` is not positive.

    Shape:
        - Output: :math:`(H, 2H)` and :math:`(H, 2H)`

    Convention:
        docs/conventions.rst, "Lat-long": ``phi = 2 pi (j + 0.5) / W - pi``, ``el = pi/2 - pi (i + 0.5) / H``;
        the centre column looks forward (-Z), the top row is +Y.

    Examples:
        >>> phi, el = latlong_angles(2)
        >>> phi.shape
        torch.Size([2, 4])
        >>> [round(v, 4) for v in phi[0].tolist()], [round(v, 4) for v in el[:, 0].tolist()]  # pi/4 steps
        ([-2.3562, -0.7854, 0.7854, 2.3562], [0.7854, -0.7854])
    """
    check_positive_int(height, "height")
    w = 2 * height
    j = torch.arange(w, device=device, dtype=torch.float64)
    i = torch.arange(height, device=device, dtype=torch.float64)
    phi = 2 * math.pi * (j + 0.5) / w - math.pi
    el = math.pi / 2 - math.pi * (i + 0.5) / height
    el_g, phi_g = torch.meshgrid(el, phi, indexing="ij")
    return phi_g.to(dtype), el_g.to(dtype)


def latlong_to_direction(phi: torch.Tensor, el: torch.Tensor) -> torch.Tensor:
    r"""Unit directions ``(..., 3)`` for azimuth and elevation tensors of the same shape.

    Args:
        phi: azimuth in radians (0 looks along -Z, ``pi/2`` along +X).
        el: elevation in radians (``pi/2`` is +Y), the shape of ``phi``.

    Returns:
        ``(sin(phi) cos(el), sin(el), -cos(phi) cos(el))``, in the dtype of the angles.

    Shape:
        - phi: :math:`(*)`
        - el: :math:`(*)`
        - Output: :math:`(*, 3)`

    Convention:
        docs/conventions.rst, "Lat-long" (the direction of an azimuth and an elevation) and "Frames".

    Examples:
        >>> phi, el = torch.tensor([0.0, math.pi / 2, 0.0]), torch.tensor([0.0, 0.0, math.pi / 2])
        >>> d = latlong_to_direction(phi, el)  # forward, right, up
        >>> torch.allclose(d, torch.tensor([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]), atol=1e-6)
        True
    """
    ce = torch.cos(el)
    return torch.stack([torch.sin(phi) * ce, torch.sin(el), -torch.cos(phi) * ce], dim=-1)


def direction_to_latlong(d: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Azimuth ``phi`` in ``(-pi, pi]`` and elevation ``el`` in ``[-pi/2, pi/2]`` of directions ``(..., 3)``.

    The inverse of :func:`latlong_to_direction`; the directions need not be unit vectors.

    Args:
        d: directions, any length but 0.

    Returns:
        ``(phi, el)`` in radians, in the dtype of ``d``.

    Raises:
        ShapeError: ``d``'s last dimension is not 3.
        NonFiniteError: NaN or Inf in ``d``.

    Shape:
        - d: :math:`(*, 3)`
        - Output: :math:`(*)` and :math:`(*)`

    Convention:
        docs/conventions.rst, "Lat-long" and "Frames": ``phi = 0``, ``el = 0`` is forward (-Z).

    Examples:
        >>> phi, el = direction_to_latlong(torch.tensor([0.0, 0.0, -1.0]))
        >>> float(phi), float(el)
        (0.0, 0.0)
    """
    check_tensor(d, "d", ["*", "3"])
    d = d / d.norm(dim=-1, keepdim=True).clamp(min=torch.finfo(d.dtype).tiny)
    phi = torch.atan2(d[..., 0], -d[..., 2])
    el = torch.asin(d[..., 1].clamp(-1.0, 1.0))
    return phi, el


def angles_to_latlong_pixel(phi: torch.Tensor, el: torch.Tensor, height: int) -> torch.Tensor:
    r"""Continuous pixel coordinates ``(col, row)`` of angles in an ``H x 2H`` map; centres are integers.

    The inverse of :func:`latlong_angles`: ``col = (phi + pi) W / (2 pi) - 0.5`` and
    ``row = (pi/2 - el) H / pi - 0.5``.
    Nothing is checked or wrapped: ``phi`` outside ``[-pi, pi]`` gives columns outside the map.

    Args:
        phi: azimuth in radians.
        el: elevation in radians, the shape of ``phi``.
        height: the map's height ``H``.

    Returns:
        ``(col, row)`` stacked on the last dimension, in the dtype of the angles.

    Shape:
        - phi: :math:`(*)`
        - el: :math:`(*)`
        - Output: :math:`(*, 2)`

    Convention:
        docs/conventions.rst, "Lat-long": ``phi = 2 pi (j + 0.5) / W - pi``, ``el = pi/2 - pi (i + 0.5) / H``;
        the centre column looks forward (-Z), the top row is +Y.

    Examples:
        >>> angles_to_latlong_pixel(torch.tensor(0.0), torch.tensor(0.0), 4).tolist()  # forward: the centre
        [3.5, 1.5]
        >>> phi, el = latlong_angles(4)
        >>> angles_to_latlong_pixel(phi, el, 4)[1, 2].tolist()  # row 1, column 2
        [2.0, 1.0]
    """
    w = 2 * height
    col = (phi + math.pi) * w / (2 * math.pi) - 0.5
    row = (math.pi / 2 - el) * height / math.pi - 0.5
    return torch.stack([col, row], dim=-1)


def latlong_directions(
    height: int, *, device: torch.device | str | None = None, dtype: torch.dtype = torch.float32
) -> torch.Tensor:
    r"""Directions of the pixel centres of an ``H x 2H`` lat-long map, ``(H, 2H, 3)``.

    Args:
        height: the map's height ``H``; its width is ``2H``.
        device: device of the result.
        dtype: dtype of the result (computed in float64).

    Returns:
        unit directions, light arriving from them.

    Raises:
        TypeCheckError: ``height`` is not an int.
        ValueCheckError: ``height`` is not positive.

    Shape:
        - Output: :math:`(H, 2H, 3)`

    Convention:
        docs/conventions.rst, "Lat-long" and "Frames": the centre column looks forward (-Z), the left half is
        -X, the top row is +Y.

    Examples:
        >>> d = latlong_directions(4)
        >>> d[0, 4]  # top row, just right of the centre column: mostly up
        tensor([ 0.1464,  0.9239, -0.3536])
    """
    phi, el = latlong_angles(height, device=device, dtype=torch.float64)
    return latlong_to_direction(phi, el).to(dtype)


def latlong_solid_angles(
    height: int, *, device: torch.device | str | None = None, dtype: torch.dtype = torch.float32
) -> torch.Tensor:
    r"""Exact solid angle of every lat-long pixel, ``(H, 2H)``; they sum to ``4 pi``.

    A pixel spans ``(2 pi / W) (sin el_top - sin el_bottom)`` steradians.

    Args:
        height: the map's height ``H``; its width is ``2H``.
        device: device of the result.
        dtype: dtype of the result (computed in float64).

    Returns:
        solid angles in steradians, the same along each row.

    Raises:
        TypeCheckError: ``height`` is not an int.
        ValueCheckError: ``height`` is not positive.

    Shape:
        - Output: :math:`(H, 2H)`

    Convention:
        docs/conventions.rst, "Lat-long": ``phi = 2 pi (j + 0.5) / W - pi``, ``el = pi/2 - pi (i + 0.5) / H``;
        the centre column looks forward (-Z), the top row is +Y.

    Examples:
        >>> abs(latlong_solid_angles(16, dtype=torch.float64).sum().item() - 4 * math.pi) < 1e-12
        True
    """
    check_positive_int(height, "height")
    edges = math.pi / 2 - math.pi * torch.arange(height + 1, device=device, dtype=torch.float64) / height
    band = torch.sin(edges[:-1]) - torch.sin(edges[1:])
    return (band[:, None] * (math.pi / height)).expand(height, 2 * height).to(dtype).contiguous()
