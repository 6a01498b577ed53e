r"""Sparse relighting, adaptive per lighting: each lighting's brightest lights exactly, the rest through a
coarse field of light clusters.

A sunny sky puts most of its energy into a few directions and is smooth elsewhere. :func:`relight_sparse`
splits each lighting ``L`` of a batch in two:

- **kept lights**: those that alone carry more than ``eps`` of the image's energy (a sun, its brightest
  neighbours, a lamp), the brightest :data:`KEPT_FRACTION` of the lights at most. The energy of light ``n`` is
  ``sum_c L[n, c] ||R[c, :, n]||_1``, the rule of :func:`~kornia_ilum.render.kept_lights`. An overcast sky
  keeps none.
- **the rest**: every light ``n`` belongs to one cluster ``g(n)`` of neighbouring lights
  (:func:`light_clusters`: square blocks of the mirror ball). Within each cluster, the lighting left is
  replaced by its mean ``m_g``, weighted by each light's reach (the norm of its column of ``R``), and that
  piecewise constant lighting is relit through the field's clusters, ``R_g = sum_{n in g} R_{:, n}``: one
  small product of ``G`` columns instead of ``N``.

.. math::

    I \approx \sum_g R_g m_g + \sum_{n \in \text{kept}} R_{:, n} \left(L_n - m_{g(n)}\right),
    \qquad m_g = \frac{\sum_{n \in g \setminus \text{kept}} \|R_{:, n}\|_1 L_n}
                      {\sum_{n \in g \setminus \text{kept}} \|R_{:, n}\|_1}.

The kept lights are exact, and the image's energy is exact (the means are reach-weighted). What is left is
the error of a piecewise constant lighting, ``sum_{n not kept} (R_n - ||R_n||_1 R_g / ||R_g||_1) (L_n - m_g)``:
small where the lighting is smooth within a cluster, or where a cluster's lights light the subject alike.
The cap on the kept lights bounds the time: each kept light costs a row of the field per lighting, while the
dense product reads the field once for the whole batch, so past the cap sparse would be the slower way.

:func:`prepare_sparse` does the per-field work once (the light-major rows, the lights' norms and the coarse
field). ``benchmarks/bench_relight.py`` measures the speed against the error on real maps
(docs/skipping.rst). To drop the weak lights instead, use :func:`~kornia_ilum.render.relight`'s ``eps``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from kornia_ilum.core.check import check_positive_int, check_tensor
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.render.relight import check_eps, light_norms, relight_product

__all__ = ["KEPT_FRACTION", "SparseField", "light_clusters", "prepare_sparse", "relight_sparse", "sparse_kept"]

#: The most lights a lighting keeps exactly, as a fraction of the field's lights (the rest go to the means).
KEPT_FRACTION = 1 / 32


def light_clusters(size: int, block: int, light_index: torch.Tensor | None = None) -> torch.Tensor:
    r"""``(N,)`` long: the cluster of each light of a ``size x size`` mirror ball, square blocks of ``block``
    pixels, numbered ``0 .. G - 1`` in row-major order of the blocks.

    Args:
        size: the mirror ball's side ``S``.
        block: the blocks' side in pixels (``S`` or more: one cluster).
        light_index: ``(N,)`` the field's lights as row-major pixel indices (a compact field's
            ``light_index``); ``None``: all ``S * S`` pixels.

    Returns:
        each light's cluster, ``0 .. G - 1``; only the blocks that hold a light are numbered.

    Raises:
        TypeCheckError: ``size`` or ``block`` is not an int.
        ValueCheckError: ``size`` or ``block`` is not positive.

    Shape:
        - light_index: :math:`(N,)`
        - Output: :math:`(N,)`, with :math:`N = S^2` without ``light_index``

    Convention:
        docs/conventions.rst, "Mirror ball": the lights are the ball's pixels in row-major order (row ``i``,
        column ``j`` is light ``i S + j``).

    Examples:
        >>> light_clusters(4, 2).reshape(4, 4).tolist()
        [[0, 0, 1, 1], [0, 0, 1, 1], [2, 2, 3, 3], [2, 2, 3, 3]]
        >>> light_clusters(4, 2, torch.tensor([1, 2, 13])).tolist()  # only the blocks in use are numbered
        [0, 1, 2]
    """
    check_positive_int(size, "size")
    check_positive_int(block, "block")
    pixels = torch.arange(size * size) if light_index is None else light_index.long()
    row, col = pixels // size, pixels % size
    per_row = -(-size // block)
    return torch.unique(row // block * per_row + col // block, return_inverse=True)[1]


@dataclass(frozen=True)
class SparseField:
    """A reflectance field prepared for :func:`relight_sparse` (made by :func:`prepare_sparse`).

    Attributes:
        field: ``(C, P, N)`` channel-major or ``(P, N)`` shared, as given.
        rows: the field light-major, ``(C' * N + 1, P)``, so that a light's column is one contiguous row; the
            last row is zero (where the bags of :func:`torch.nn.functional.embedding_bag` are padded).
        norms: ``(C', N)`` float32, each light's ``||R[c, :, n]||_1``.
        clusters: ``(N,)`` long, each light's cluster.
        members: ``(N, G)`` float32, one-hot of ``clusters`` (the cluster means as one product).
        coarse: ``(C', P, G)`` the field summed over each cluster's lights, in the field's dtype.

    Examples:
        >>> prepared = prepare_sparse(torch.rand(3, 16, 4), light_clusters(2, 1))  # 4 lights, 4 clusters
        >>> prepared.rows.shape, prepared.norms.shape, prepared.members.shape, prepared.coarse.shape
        (torch.Size([13, 16]), torch.Size([3, 4]), torch.Size([4, 4]), torch.Size([3, 16, 4]))
    """

    field: torch.Tensor
    rows: torch.Tensor
    norms: torch.Tensor
    clusters: torch.Tensor
    members: torch.Tensor
    coarse: torch.Tensor


def prepare_sparse(field: torch.Tensor, clusters: torch.Tensor) -> SparseField:
    r"""The per-field work of :func:`relight_sparse`, done once: the light-major rows, the lights' norms and
    the coarse field of the clusters.

    Args:
        field: ``(C, P, N)`` or ``(P, N)``, any floating dtype (the light stage's fields are bfloat16).
        clusters: ``(N,)`` each light's cluster, ``0 .. G - 1`` (:func:`light_clusters`).

    Returns:
        a :class:`SparseField` on the field's device (``G`` is the largest cluster plus one).

    Raises:
        ShapeError: ``clusters`` does not have the field's ``N`` entries.
        TypeCheckError: ``clusters`` is not an integer tensor.
        ValueCheckError: a negative cluster.

    Shape:
        - field: :math:`(C, P, N)` or :math:`(P, N)`
        - clusters: :math:`(N,)`
        - Output: see :class:`SparseField`

    Examples:
        >>> prepared = prepare_sparse(torch.eye(4), torch.tensor([0, 0, 1, 1]))
        >>> prepared.norms.tolist(), prepared.coarse.shape
        ([[1.0, 1.0, 1.0, 1.0]], torch.Size([1, 4, 2]))
    """
    check_tensor(field, "field", None)
    if field.dim() not in (2, 3):
        raise ShapeError(f"field must be (C, P, N) or (P, N), got {tuple(field.shape)}")
    n, p = field.shape[-1], field.shape[-2]
    check_tensor(clusters, "clusters", [str(n)], floating=False)
    if clusters.is_floating_point() or clusters.is_complex() or clusters.dtype == torch.bool:
        raise TypeCheckError(f"clusters must be an integer tensor, got dtype {clusters.dtype}")
    if bool((clusters < 0).any()):
        raise ValueCheckError(f"clusters must be non-negative, got a minimum of {int(clusters.min())}")
    grouped = field if field.dim() == 3 else field[None]
    rows = torch.cat([grouped.transpose(-1, -2).reshape(-1, p), grouped.new_zeros(1, p)])
    clusters = clusters.long().to(field.device)
    members = torch.nn.functional.one_hot(clusters).float()  # (N, G)
    coarse = torch.bmm(grouped.float(), members.expand(grouped.shape[0], n, -1)).to(field.dtype)
    return SparseField(field, rows, light_norms(field).float(), clusters, members, coarse)


def _check(prepared: SparseField, lighting: torch.Tensor, eps: float) -> torch.Tensor:
    field = prepared.field
    channels = field.shape[0] if field.dim() == 3 else None
    check_tensor(lighting, "lighting", ["B", str(field.shape[-1]), str(channels) if channels else "C"],
                 nonnegative=True)
    check_eps(eps)
    return lighting.float()


def _select(prepared: SparseField, lights: torch.Tensor, eps: float) -> tuple[torch.Tensor, torch.Tensor]:
    """``(order, counts)``: each lighting's brightest lights, :data:`KEPT_FRACTION` of them, and how many of
    them carry more than ``eps`` of its energy each."""
    energy = (lights * prepared.norms.T).sum(-1)  # (B, N)
    most = min(energy.shape[1], math.ceil(KEPT_FRACTION * energy.shape[1]))  # no full sort needed
    top, order = energy.topk(most, dim=1)
    counts = (top > eps * energy.sum(1, keepdim=True)).sum(1)
    return order, counts


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
        >>> prepared = prepare_sparse(torch.eye(4), torch.tensor([0, 0, 1, 1]))
        >>> sparse_kept(prepared, torch.tensor([[[5.0], [0.0], [1.0], [1.0]]]), eps=0.2).tolist()
        [1]
    """
    return _select(prepared, _check(prepared, lighting, eps), eps)[1]


def relight_sparse(prepared: SparseField, lighting: torch.Tensor, eps: float) -> torch.Tensor:
    r"""Relight ``prepared``'s field: each lighting's brightest lights exactly, the rest through its cluster
    means (module docstring).

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
        >>> prepared = prepare_sparse(torch.eye(4), torch.tensor([0, 0, 1, 1]))
        >>> lighting = torch.tensor([[[5.0], [0.0], [1.0], [1.0]]])  # a sun beside a dark light; a flat pair
        >>> relight_sparse(prepared, lighting, eps=0.2).flatten().tolist()
        [5.0, 0.0, 1.0, 1.0]
    """
    lights = _check(prepared, lighting, eps)
    if eps == 0.0:
        return relight_product(prepared.field, lights.to(prepared.field.dtype)).float()
    return _relight_kept(prepared, lights, *_select(prepared, lights, eps))


def _relight_kept(prepared: SparseField, lights: torch.Tensor, order: torch.Tensor, counts: torch.Tensor
                  ) -> torch.Tensor:
    """``(B, C, P)``: the coarse product of the cluster means plus each item's kept lights' corrections, the
    latter as one :func:`torch.nn.functional.embedding_bag` of ``k`` rows per (item, channel)."""
    b, n, c = lights.shape
    cf = prepared.norms.shape[0]
    p = prepared.rows.shape[1]
    k = int(counts.max())
    top = order[:, :k]  # (B, k)
    used = torch.arange(k, device=lights.device)[None] < counts[:, None]  # (B, k): past each count, padding
    reach = (torch.ones(b, n, device=lights.device).scatter_(1, top, (~used).float())[..., None]
             * prepared.norms.T)  # (B, N, C): the lights left to the means, by reach
    both = torch.cat([lights * reach, reach.expand(b, n, c)], dim=2)  # (B, N, 2C)
    sums = (both.permute(0, 2, 1).reshape(b * 2 * c, n) @ prepared.members).view(b, 2, c, -1)
    means = sums[:, 0] / sums[:, 1].clamp_min(torch.finfo(torch.float32).tiny)  # (B, C, G)
    coarse = prepared.coarse
    if cf == 1:  # shared: (P, G) @ (G, B * C)
        out = (coarse[0] @ means.permute(2, 0, 1).reshape(-1, b * c).to(coarse.dtype)).view(p, b, c).permute(1, 2, 0)
    else:  # (C, P, G) @ (C, G, B)
        out = torch.bmm(coarse, means.permute(1, 2, 0).to(coarse.dtype)).permute(2, 0, 1)
    out = out.float()
    if k == 0:
        return out
    weights = lights.gather(1, top[..., None].expand(b, k, c))  # (B, k, C)
    weights = (weights - means.gather(2, prepared.clusters[top][:, None].expand(b, c, k)).transpose(1, 2))
    chan = torch.arange(c, device=lights.device) * (n if cf > 1 else 0)
    # padding points at the zero row, with weight 0 (embedding_bag's padding_idx takes a slower path)
    index = torch.where(used[:, None], top[:, None] + chan[None, :, None], cf * n)  # (B, C, k)
    return out.add_(torch.nn.functional.embedding_bag(
        index.reshape(b * c, k), prepared.rows, mode="sum",
        per_sample_weights=(weights * used[..., None]).transpose(1, 2).reshape(b * c, k).to(prepared.rows.dtype),
    ).view(b, c, p))
