r"""Sparse relighting, adaptive per lighting: the lights that carry the energy exactly, the rest folded into a
low-order term.

A sunny sky puts most of its energy into a few directions. :func:`relight_sparse` relights each lighting of
a batch from its own strongest lights only, those that carry all but a fraction ``eps`` of the image's
energy (the rule of :func:`~kornia_ilum.render.relight`'s ``eps``), so a sun and its neighbours cost a few
columns of the field instead of all ``N``. The dropped lights are not lost: with a ``fold`` basis (for
example order-2 spherical harmonics, ``K = 9``) their lighting is projected onto the basis and relit through
the field's precomputed response to it, ``K`` columns more:

.. math::

    I \approx \sum_{n \in \text{kept}} R_{:, n} L_n + \sum_k F_{:, k} a_k,
    \qquad a_k = \sum_{n \in \text{dropped}} P_{n k} L_n, \qquad F_{:, k} = \sum_n R_{:, n} Y_{n k},

with ``P`` the basis' projection (values times solid angles) and ``Y`` its values at the lights. The kept
lights' rows of a light-major copy of the field are summed in one
:func:`torch.nn.functional.embedding_bag` over the whole batch. The number
of kept lights adapts to each lighting: an overcast sky keeps many. Where a lighting would keep more than
:data:`DENSE_FRACTION` of the lights, it is relit densely, which is then the faster way.
:func:`prepare_sparse` does the per-field work once (the lights' norms and the fold's response).
``benchmarks/bench_relight.py`` measures the speed against the error on real maps.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from kornia_ilum.core.check import check_tensor
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.render.relight import kept_lights, light_norms, relight_product

__all__ = ["DENSE_FRACTION", "SparseField", "prepare_sparse", "relight_sparse"]

#: A lighting that keeps more than this fraction of the lights is relit densely.
DENSE_FRACTION = 0.125


@dataclass(frozen=True)
class SparseField:
    """A reflectance field prepared for :func:`relight_sparse` (made by :func:`prepare_sparse`).

    Attributes:
        field: ``(C, P, N)`` channel-major or ``(P, N)`` shared, as given.
        rows: the same field light-major, ``(C', N, P)``, so that a light's column is one contiguous row.
        norms: ``(C', N)`` float64, each light's ``||R[c, :, n]||_1``.
        projection: ``(N, K)`` the fold basis' projection, or ``None`` (no fold).
        response: ``(C', P, K)`` float32, the field's response to the basis, or ``None``.
    """

    field: torch.Tensor
    rows: torch.Tensor
    norms: torch.Tensor
    projection: torch.Tensor | None = None
    response: torch.Tensor | None = None


def prepare_sparse(field: torch.Tensor, fold: tuple[torch.Tensor, torch.Tensor] | None = None) -> SparseField:
    r"""The per-field work of :func:`relight_sparse`, done once: the lights' norms and the fold's response.

    Args:
        field: ``(C, P, N)`` or ``(P, N)``, any floating dtype (the light stage's fields are bfloat16).
        fold: ``(projection, values)``, both ``(N, K)``: the projection of a light list onto the basis (values
            times each light's solid angle) and the basis' values at the lights; ``None``: the dropped lights
            are dropped.

    Raises:
        ShapeError: the fold's shapes do not match the field's ``N``.

    Examples:
        >>> prepared = prepare_sparse(torch.eye(4))
        >>> prepared.norms.tolist()
        [[1.0, 1.0, 1.0, 1.0]]
    """
    check_tensor(field, "field", None)
    if field.dim() not in (2, 3):
        raise ShapeError(f"field must be (C, P, N) or (P, N), got {tuple(field.shape)}")
    n = field.shape[-1]
    rows = field.transpose(-1, -2).contiguous()
    rows = rows[None] if field.dim() == 2 else rows
    if fold is None:
        return SparseField(field, rows, light_norms(field))
    projection, values = fold
    for name, t in (("projection", projection), ("values", values)):
        check_tensor(t, f"fold {name}", [str(n), "K"])
    if projection.shape != values.shape:
        raise ShapeError(f"the fold's projection and values must have one shape, got {tuple(projection.shape)} "
                         f"and {tuple(values.shape)}")
    k = values.shape[1]
    basis = values.T[:, :, None].expand(k, n, field.shape[0] if field.dim() == 3 else 1)  # K "lightings"
    response = relight_product(field, basis.to(field.dtype)).float()  # (K, C', P)
    return SparseField(field, rows, light_norms(field), projection.float(),
                       response.permute(1, 2, 0).contiguous())


def _gather_rows(rows: torch.Tensor, lights: torch.Tensor, keep: torch.Tensor) -> torch.Tensor:
    """``(B, C, P)``: for each item and channel, the weighted sum of its kept lights' rows of ``rows``
    ``(C', N, P)``, in one :func:`torch.nn.functional.embedding_bag` (only those rows are read)."""
    b, n, c = lights.shape
    cf, _, p = rows.shape
    counts = keep.sum(1)
    item, light = keep.nonzero(as_tuple=True)  # item-major
    chan = torch.arange(c, device=keep.device)
    index = light[:, None] + (chan * n if cf > 1 else torch.zeros_like(chan))[None]  # (M, C) rows
    order = (item[:, None] * c + chan[None]).flatten().argsort(stable=True)  # grouped by bag (item, channel)
    sizes = counts.repeat_interleave(c)
    out = torch.nn.functional.embedding_bag(index.flatten()[order], rows.reshape(cf * n, p), sizes.cumsum(0) - sizes,
                                            mode="sum", per_sample_weights=lights[item, light].flatten()[order])
    return out.reshape(b, c, p)


def relight_sparse(prepared: SparseField, lighting: torch.Tensor, eps: float) -> torch.Tensor:
    r"""Relight ``prepared``'s field with each lighting's strongest lights, and fold the rest (module docstring).

    Args:
        prepared: from :func:`prepare_sparse`.
        lighting: ``(B, N, C)`` light lists in radiance, non-negative.
        eps: the fraction of each image's energy whose lights may be dropped (or folded), in ``[0, 1)``.

    Returns:
        ``(B, C, P)`` float32 relit pixels; with ``eps = 0`` the dense product.

    Raises:
        ValueCheckError: ``eps`` outside ``[0, 1)``, or negative lighting.
        ShapeError: ``lighting`` does not match the field.

    Examples:
        >>> prepared = prepare_sparse(torch.eye(4))
        >>> relight_sparse(prepared, torch.tensor([[[5.0], [0.01], [0.0], [0.0]]]), eps=0.01).flatten().tolist()
        [5.0, 0.0, 0.0, 0.0]
    """
    field = prepared.field
    n = field.shape[-1]
    channels = field.shape[0] if field.dim() == 3 else None
    check_tensor(lighting, "lighting", ["B", str(n), str(channels) if channels else "C"], nonnegative=True)
    if not 0.0 <= eps < 1.0:
        raise ValueCheckError(f"eps must be in [0, 1), got {eps!r}")
    lights = lighting.float()
    b, _, c = lights.shape
    p = field.shape[-2]
    if eps == 0.0:
        return relight_product(field, lights.to(field.dtype)).float()
    keep = kept_lights(lights, prepared.norms, eps)
    counts = keep.sum(1)
    out = torch.empty(b, c, p, dtype=torch.float32, device=field.device)
    dense = counts > DENSE_FRACTION * n
    if bool(dense.any()):
        rows = dense.nonzero().flatten()
        out[rows] = relight_product(field, lights[rows].to(field.dtype)).float()
    sparse = (~dense).nonzero().flatten()
    if len(sparse):
        out[sparse] = _gather_rows(prepared.rows, lights[sparse].to(field.dtype), keep[sparse]).float()
    if prepared.response is not None:
        dropped = lights * (~keep & ~dense[:, None])[..., None]  # densely relit items dropped nothing
        coefficients = prepared.projection.T @ dropped.permute(1, 0, 2).reshape(n, b * c)  # (K, B*C)
        coefficients = coefficients.reshape(-1, b, c)
        response = prepared.response  # (C', P, K)
        if response.shape[0] == 1:
            out += (response[0] @ coefficients.reshape(-1, b * c)).reshape(p, b, c).permute(1, 2, 0)
        else:  # (C, P, K) @ (C, K, B) -> (C, P, B)
            out += torch.bmm(response, coefficients.permute(2, 0, 1)).permute(2, 0, 1)
    return out
