r"""Sparse relighting, adaptive per lighting: each lighting's brightest lights exactly, the rest through a
low-rank field.

A sunny sky puts most of its energy into a few directions and is smooth elsewhere, and a face's reflectance
field is close to low rank: its images under the ``N`` lights of the ball are mostly mixtures of a few
(the shading by a smooth lighting changes slowly with its direction). :func:`relight_sparse` splits each
lighting ``L`` of a batch in two:

- **kept lights**: those that alone carry more than ``eps`` of the image's energy (a sun, its brightest
  neighbours, a lamp), the brightest :data:`KEPT_FRACTION` of the lights at most. The energy of light ``n`` is
  ``sum_c L[n, c] ||R[c, :, n]||_1``, the rule of :func:`~kornia_ilum.render.kept_lights`. An overcast sky
  keeps none. Their columns of the field relight them exactly: the sharp shadows and highlights of a sun.
- **the rest**: relit through the field's best rank-``r`` approximation ``R V V^T``, where the columns of
  ``V`` (``N x r``) are the top ``r`` right singular vectors of ``R`` (per channel): ``(R V)(V^T L)``, one
  product of ``r`` columns instead of ``N``.

.. math::

    I \approx \sum_{n \in \text{kept}} R_{:, n} L_n + (R V) \left(V^\top L_{\text{rest}}\right),
    \qquad L_{\text{rest}} = L \text{ with the kept lights set to } 0.

The kept lights are exact. What is left is the part of the field outside its top ``r`` singular directions,
seen through the lighting that remains, which a smooth sky barely excites. The cap on the kept lights bounds
the time: each kept light costs a row of the field per lighting, while the dense product reads the field once
for the whole batch, so past the cap sparse would be the slower way.

:func:`prepare_sparse` does the per-field work once: the light-major rows, the lights' norms and the rank-``r``
factors. ``benchmarks/bench_relight.py`` measures the speed against the error on real maps
(docs/skipping.rst). To drop the weak lights instead, use :func:`~kornia_ilum.render.relight`'s ``eps``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import nn

from kornia_ilum.core.check import check_positive_int, check_tensor
from kornia_ilum.core.errors import ShapeError
from kornia_ilum.render.relight import check_eps, light_norms, relight_product

__all__ = ["KEPT_FRACTION", "SPARSE_RANK", "RelightSparse", "SparseField", "prepare_sparse", "relight_sparse",
           "sparse_kept"]

#: The most lights a lighting keeps exactly, as a fraction of the field's lights (the rest go to the low rank).
KEPT_FRACTION = 1 / 32

#: The default rank of the rest: the lowest of 16, 24, 32 and 48 that kept ``L_rec`` within 1 % for each of 6
#: training subjects under each sun-dominated outdoor training map at ``eps = 0.01`` (docs/skipping.rst).
SPARSE_RANK = 48


@dataclass(frozen=True)
class SparseField:
    """A reflectance field prepared for :func:`relight_sparse` (made by :func:`prepare_sparse`).

    Attributes:
        field: ``(C, P, N)`` channel-major or ``(P, N)`` shared, as given.
        rows: the field light-major, ``(C' * N + 1, P)``, so that a light's column is one contiguous row; the
            last row is zero (where the bags of :func:`torch.nn.functional.embedding_bag` are padded).
        norms: ``(C', N)`` float32, each light's ``||R[c, :, n]||_1``.
        basis: ``(C', P, r)`` the field's images of its top ``r`` singular directions, ``R V``, in the field's
            dtype.
        directions: ``(C', r, N)`` float32, those directions, ``V^T``.

    Examples:
        >>> prepared = prepare_sparse(torch.rand(3, 16, 4), rank=2)  # 4 lights
        >>> prepared.rows.shape, prepared.norms.shape, prepared.basis.shape, prepared.directions.shape
        (torch.Size([13, 16]), torch.Size([3, 4]), torch.Size([3, 16, 2]), torch.Size([3, 2, 4]))
    """

    field: torch.Tensor
    rows: torch.Tensor
    norms: torch.Tensor
    basis: torch.Tensor
    directions: torch.Tensor


def prepare_sparse(field: torch.Tensor, rank: int = SPARSE_RANK) -> SparseField:
    r"""The per-field work of :func:`relight_sparse`, done once: the light-major rows, the lights' norms and
    the field's rank-``rank`` factors.

    The factors come from the eigenvectors of each channel's ``N x N`` Gram matrix ``R^T R``, in float64: its
    top ``rank`` eigenvectors are ``R``'s top right singular vectors, found without decomposing the ``P x N``
    field itself, and deterministically.

    Args:
        field: ``(C, P, N)`` or ``(P, N)``, any floating dtype (the light stage's fields are bfloat16).
        rank: how many singular directions relight the lights not kept (more than ``N`` is cut to ``N``).

    Returns:
        a :class:`SparseField` on the field's device.

    Raises:
        ShapeError: ``field`` is neither ``(C, P, N)`` nor ``(P, N)``.
        TypeCheckError: ``rank`` is not an int.
        ValueCheckError: ``rank`` is not positive.

    Shape:
        - field: :math:`(C, P, N)` or :math:`(P, N)`
        - Output: see :class:`SparseField`

    Examples:
        >>> field = torch.tensor([[1.0, 1.0, 0.0], [0.0, 0.0, 1.0]])  # lights 0 and 1 light alike: rank 2
        >>> prepared = prepare_sparse(field, rank=2)
        >>> prepared.basis.shape, prepared.norms.tolist()
        (torch.Size([1, 2, 2]), [[1.0, 1.0, 1.0]])
        >>> bool(torch.allclose(prepared.basis @ prepared.directions, field, atol=1e-6))  # exact at its rank
        True
    """
    check_tensor(field, "field", None)
    if field.dim() not in (2, 3):
        raise ShapeError(f"field must be (C, P, N) or (P, N), got {tuple(field.shape)}")
    check_positive_int(rank, "rank")
    n, p = field.shape[-1], field.shape[-2]
    grouped = field if field.dim() == 3 else field[None]
    rows = torch.cat([grouped.transpose(-1, -2).reshape(-1, p), grouped.new_zeros(1, p)])
    wide = grouped.double()
    _, vectors = torch.linalg.eigh(wide.transpose(1, 2) @ wide)  # ascending eigenvalues
    top = vectors[..., -min(rank, n):].flip(-1)  # (C', N, r), the largest first
    basis = (wide @ top).to(field.dtype)
    return SparseField(field, rows, light_norms(field).float(), basis, top.transpose(1, 2).float().contiguous())


def _check(prepared: SparseField, lighting: torch.Tensor, eps: float) -> torch.Tensor:
    field = prepared.field
    channels = field.shape[0] if field.dim() == 3 else None
    check_tensor(lighting, "lighting", ["B", str(field.shape[-1]), str(channels) if channels else "C"],
                 nonnegative=True)
    check_eps(eps)
    return lighting.float()


def _select(prepared: SparseField, lights: torch.Tensor, eps: float) -> tuple[torch.Tensor, torch.Tensor]:
    """``(order, used)``: each lighting's brightest lights, :data:`KEPT_FRACTION` of them at most and only as many
    as the brightest carries more than ``eps`` of its energy, ``(B, k)``; and which of them do, ``(B, k)`` (a
    prefix of each row, since ``order`` is sorted)."""
    energy = (lights * prepared.norms.T).sum(-1)  # (B, N)
    most = min(energy.shape[1], math.ceil(KEPT_FRACTION * energy.shape[1]))  # no full sort needed
    top, order = energy.topk(most, dim=1)
    used = top > eps * energy.sum(1, keepdim=True)
    k = int(used.sum(1).max())
    return order[:, :k], used[:, :k]


def sparse_kept(prepared: SparseField, lighting: torch.Tensor, eps: float) -> torch.Tensor:
    """``(B,)`` long: how many lights :func:`relight_sparse` keeps exactly for each lighting.

    Args:
        prepared: from :func:`prepare_sparse`.
        lighting: ``(B, N, C)`` light lists in radiance, non-negative.
        eps: the threshold of :func:`relight_sparse`, in ``[0, 1)``.

    Returns:
        the number of kept lights per lighting, at most ``ceil(KEPT_FRACTION * N)``.

    Raises:
        ValueCheckError: ``eps`` outside ``[0, 1)``, or negative lighting.
        ShapeError: ``lighting`` does not match the field.

    Shape:
        - lighting: :math:`(B, N, C)`
        - Output: :math:`(B,)`

    Examples:
        >>> prepared = prepare_sparse(torch.eye(4), rank=1)
        >>> sparse_kept(prepared, torch.tensor([[[5.0], [0.0], [1.0], [1.0]]]), eps=0.2).tolist()
        [1]
    """
    return _select(prepared, _check(prepared, lighting, eps), eps)[1].sum(1)


def relight_sparse(prepared: SparseField, lighting: torch.Tensor, eps: float) -> torch.Tensor:
    r"""Relight ``prepared``'s field: each lighting's brightest lights exactly, the rest through the field's
    low-rank factors (module docstring).

    Args:
        prepared: from :func:`prepare_sparse`.
        lighting: ``(B, N, C)`` light lists in radiance, non-negative.
        eps: a light that alone carries more than this fraction of the image's energy is kept exactly (the
            brightest :data:`KEPT_FRACTION` of the lights at most), in ``[0, 1)``; ``0``: dense.

    Returns:
        ``(B, C, P)`` float32 relit pixels; with ``eps = 0`` the dense product.

    Raises:
        ValueCheckError: ``eps`` outside ``[0, 1)``, or negative lighting.
        ShapeError: ``lighting`` does not match the field.

    Shape:
        - lighting: :math:`(B, N, C)`
        - Output: :math:`(B, C, P)`

    Examples:
        >>> field = torch.tensor([[1.0, 0.0, 0.0], [0.0, 1.0, 1.0]])  # lights 1 and 2 light alike: rank 2
        >>> prepared = prepare_sparse(field, rank=2)
        >>> lighting = torch.tensor([[[5.0], [1.0], [1.0]]])  # a sun (kept), and the rest at rank 2: exact
        >>> [round(v, 4) for v in relight_sparse(prepared, lighting, eps=0.2).flatten().tolist()]
        [5.0, 2.0]
    """
    lights = _check(prepared, lighting, eps)
    if eps == 0.0:
        return relight_product(prepared.field, lights.to(prepared.field.dtype)).float()
    return _relight_kept(prepared, lights, *_select(prepared, lights, eps))


def _relight_kept(prepared: SparseField, lights: torch.Tensor, order: torch.Tensor, used: torch.Tensor
                  ) -> torch.Tensor:
    """``(B, C, P)``: the rest relit through the low-rank factors, plus each item's kept lights, the latter as
    one :func:`torch.nn.functional.embedding_bag` of ``k`` rows per (item, channel)."""
    b, n, c = lights.shape
    k = order.shape[1]
    where = order[..., None].expand(b, k, c)
    top = lights.gather(1, where)  # (B, k, C): each lighting's brightest, the kept ones first (``used``)
    rest = lights.scatter(1, where, top * ~used[..., None])  # (B, N, C): the kept lights set to 0
    basis, directions = prepared.basis, prepared.directions
    shared = basis.shape[0] == 1  # one field for all channels: the products of (P, r) and (r, N)
    weights = relight_product(directions[0] if shared else directions, rest)  # (B, C, r): V^T L
    out = relight_product(basis[0] if shared else basis, weights.transpose(1, 2).to(basis.dtype)).float()
    if k == 0:
        return out
    kept = top.transpose(1, 2) * used[:, None]  # (B, C, k)
    chan = torch.arange(c, device=lights.device) * (0 if shared else n)
    # past each count the bag points at the zero row, weight 0 (embedding_bag's padding_idx is a slower path)
    index = torch.where(used[:, None], order[:, None] + chan[None, :, None], prepared.rows.shape[0] - 1)  # (B, C, k)
    return out.add_(torch.nn.functional.embedding_bag(
        index.reshape(b * c, k), prepared.rows, mode="sum",
        per_sample_weights=kept.reshape(b * c, k).to(prepared.rows.dtype)).view(b, c, -1))


class RelightSparse(nn.Module):
    r"""Module twin of :func:`relight_sparse`: the field is prepared once (:func:`prepare_sparse`) and its parts
    are non-persistent buffers, so ``.to(device)`` moves them.

    Args:
        field: reflectance field, ``(C, P, N)`` or ``(P, N)``, any floating dtype.
        eps: a light that alone carries more than this fraction of the image's energy is kept exactly, in
            ``[0, 1)``; ``0``: dense.
        rank: how many singular directions relight the lights not kept.

    Raises:
        ShapeError: ``field`` is neither ``(C, P, N)`` nor ``(P, N)``.
        ValueCheckError: ``eps`` outside ``[0, 1)`` or ``rank`` not positive.

    Shape:
        - Input: :math:`(B, N, C)` lighting
        - Output: :math:`(B, C, P)` float32

    Examples:
        >>> relight_module = RelightSparse(torch.tensor([[1.0, 0.0, 0.0], [0.0, 1.0, 1.0]]), eps=0.2, rank=2)
        >>> [round(v, 4) for v in relight_module(torch.tensor([[[5.0], [1.0], [1.0]]])).flatten().tolist()]
        [5.0, 2.0]
    """

    def __init__(self, field: torch.Tensor, eps: float, rank: int = SPARSE_RANK) -> None:
        super().__init__()
        self.eps = check_eps(eps)
        prepared = prepare_sparse(field, rank)
        for name in ("field", "rows", "norms", "basis", "directions"):
            self.register_buffer(name, getattr(prepared, name), persistent=False)

    def forward(self, lighting: torch.Tensor) -> torch.Tensor:
        prepared = SparseField(self.field, self.rows, self.norms, self.basis, self.directions)
        return relight_sparse(prepared, lighting, self.eps)

    def extra_repr(self) -> str:
        return f"eps={self.eps}, rank={self.basis.shape[-1]}, lights={self.field.shape[-1]}"
