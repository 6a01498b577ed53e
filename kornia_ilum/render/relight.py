r"""Image-based relighting with a reflectance field: ``I = R . L`` (Debevec et al. 2000).

A reflectance field ``R`` holds, for every pixel ``p`` and every light ``n`` of a lighting basis (here the
pixels of a mirror-ball lighting image), the pixel's response to unit radiance from that light. Relighting
under any lighting ``L`` is then a matrix product, linear in ``L``:
``I[b, c, p] = sum_n R[c, p, n] L[b, n, c]`` (Debevec et al. 2000, "Acquiring the reflectance field of a
human face"; LeGendre et al. 2020 render their reference spheres and training portraits this way).

Memory layout, chosen by measurement at ``P = 256^2``, ``N = 1024`` (a 32 x 32 mirror ball), ``C = 3``
(the times are in the docs' render page, ``benchmarks/bench_ops.py``, section relight):

- channel-major field ``(C, P, N)``: one ``torch.bmm`` with the lighting transposed to ``(C, N, B)``. The
  light-major ``(C, N, P)`` product is as fast in float32 but slower in bfloat16; a loop over channels is
  slower too.
- shared field ``(P, N)``: one ``torch.mm`` with ``(N, B * C)``, the fastest of all (one matrix for the
  three channels). A broadcast ``matmul`` of ``(P, N)`` with ``(B, N, C)`` is far slower.
- ``einsum("cpn,bnc->bcp")`` of a bfloat16 field with float32 lighting upcasts the whole field on every
  call, which costs many times the ``bmm``.
"""

from __future__ import annotations

import math

import torch
from torch import nn

from kornia_ilum.core.check import check_tensor
from kornia_ilum.core.errors import ShapeError, ValueCheckError

__all__ = ["Relight", "check_eps", "kept_lights", "light_norms", "relight", "relight_product"]

_HALF = (torch.float16, torch.bfloat16)


def _check_field(field: torch.Tensor, finite: bool) -> None:
    if isinstance(field, torch.Tensor) and field.dim() == 2:
        check_tensor(field, "field", ["P", "N"], finite=finite)
    else:
        check_tensor(field, "field", ["C", "P", "N"], finite=finite)


def _check_lighting(field: torch.Tensor, lighting: torch.Tensor) -> None:
    check_tensor(lighting, "lighting", ["B", "N", "C"])
    if lighting.shape[1] != field.shape[-1]:
        raise ShapeError(
            f"lighting must have N = {field.shape[-1]} lights to match field {tuple(field.shape)}, "
            f"got lighting of shape {tuple(lighting.shape)}"
        )
    if field.dim() == 3 and lighting.shape[2] != field.shape[0]:
        raise ShapeError(
            f"lighting must have C = {field.shape[0]} channels to match the channel-major field "
            f"{tuple(field.shape)}, got lighting of shape {tuple(lighting.shape)}"
        )


def _image_size(num_pixels: int, size: int | tuple[int, int] | None) -> tuple[int, int]:
    if size is None:
        s = math.isqrt(num_pixels)
        if s * s != num_pixels:
            raise ShapeError(f"field has P = {num_pixels} pixels, which is no square: pass size=(H, W)")
        return s, s
    hw = (size, size) if isinstance(size, int) else tuple(size)
    if len(hw) != 2 or not all(isinstance(x, int) and not isinstance(x, bool) and x > 0 for x in hw):
        raise ValueCheckError(f"size must be a positive int or a pair (H, W) of them, got {size!r}")
    if hw[0] * hw[1] != num_pixels:
        raise ShapeError(f"size {hw} has {hw[0] * hw[1]} pixels but field has P = {num_pixels}")
    return hw[0], hw[1]


def check_eps(eps: float, name: str = "eps") -> float:
    """``eps`` as a float, checked: a number in ``[0, 1)``, the fraction of the energy a relighting may leave out.

    Args:
        eps: the value.
        name: the argument's name, used in the message.

    Returns:
        ``float(eps)``.

    Raises:
        ValueCheckError: not a number in ``[0, 1)`` (a ``bool`` is refused).

    Examples:
        >>> check_eps(0)
        0.0
        >>> check_eps(1.0, "relight_eps")
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: relight_eps must be a number in [0, 1), got 1.0
    """
    if isinstance(eps, bool) or not isinstance(eps, (int, float)) or not 0.0 <= eps < 1.0:
        raise ValueCheckError(f"{name} must be a number in [0, 1), got {eps!r}")
    return float(eps)


def _dtypes(field: torch.Tensor, lighting: torch.Tensor) -> tuple[torch.dtype, torch.dtype]:
    """(compute dtype, output dtype): half fields are never copied, the lighting is cast to them."""
    out = torch.promote_types(field.dtype, lighting.dtype)
    return (field.dtype if field.dtype in _HALF else out), out


def relight_product(field: torch.Tensor, lights: torch.Tensor) -> torch.Tensor:
    r"""The dense product of :func:`relight`, without its checks, dtype rule or reshape.

    ``out[b, c, p] = sum_n R[c, p, n] L[b, n, c]`` for a channel-major field (one ``torch.bmm``), or
    ``sum_n R[p, n] L[b, n, c]`` for a field shared by the channels (one ``torch.mm`` with the lighting laid
    out as ``(N, B C)``). For callers that checked their inputs and hold ``field`` and ``lights`` in one
    dtype: nothing is validated, and the result stays flat over the pixels.

    Args:
        field: reflectance field ``(C, P, N)`` or ``(P, N)``.
        lights: light list ``(B, N, C)`` in the dtype of ``field``.

    Returns:
        ``(B, C, P)``, possibly a non-contiguous view of the product.

    Shape:
        - field: :math:`(C, P, N)` or :math:`(P, N)`
        - lights: :math:`(B, N, C)`
        - Output: :math:`(B, C, P)`

    Examples:
        >>> relight_product(torch.eye(2), torch.tensor([[[1.0, 2.0], [3.0, 4.0]]]))
        tensor([[[1., 3.],
                 [2., 4.]]])
    """
    b, n, c = lights.shape
    if field.dim() == 2:  # (P, N) @ (N, B*C) -> (P, B*C)
        out = field @ lights.permute(1, 0, 2).reshape(n, b * c)
        return out.reshape(field.shape[0], b, c).permute(1, 2, 0)
    return torch.bmm(field, lights.permute(2, 1, 0)).permute(2, 0, 1)  # (C, P, N) @ (C, N, B) -> (C, P, B)


def light_norms(field: torch.Tensor) -> torch.Tensor:
    """Per-light L1 norms ``||R[c, :, n]||_1``, ``(C', N)`` in float64 (``C' = 1`` for a shared field).

    The ``norms`` of :func:`kept_lights`. Nothing is checked; the result is detached from autograd.

    Args:
        field: reflectance field, channel-major ``(C, P, N)`` or shared ``(P, N)``.

    Returns:
        the norms in float64, on the field's device.

    Shape:
        - field: :math:`(C, P, N)` or :math:`(P, N)`
        - Output: :math:`(C, N)` or :math:`(1, N)`

    Examples:
        >>> light_norms(torch.eye(3)).tolist()
        [[1.0, 1.0, 1.0]]
    """
    norms = field.detach().abs().sum(-2, dtype=torch.float64)
    return norms[None] if field.dim() == 2 else norms


def kept_lights(lighting: torch.Tensor, norms: torch.Tensor, eps: float) -> torch.Tensor:
    """Boolean ``(B, N)``: the lights kept after dropping the weakest (at most ``eps`` of the energy).

    The energy of light ``n`` in batch item ``b`` is ``E[b, n] = sum_c |L[b, n, c]| ||R[c, :, n]||_1`` (``norms``
    from :func:`light_norms`). The lights are sorted by energy and the longest prefix of the weakest whose
    cumulative energy is ``<= eps * sum_n E[b, n]`` is dropped. Computed in float64.

    Nothing is checked; the selection is not differentiable.

    Args:
        lighting: light list ``(B, N, C)``.
        norms: per-light norms ``(C', N)`` from :func:`light_norms`, ``C'`` 1 or ``C``.
        eps: fraction of the energy that may be dropped, in ``[0, 1)``; 0 keeps every light of non-zero
            energy.

    Returns:
        ``torch.bool`` mask, ``True`` for the lights kept.

    Shape:
        - lighting: :math:`(B, N, C)`
        - norms: :math:`(C, N)` or :math:`(1, N)`
        - Output: :math:`(B, N)`

    Examples:
        >>> kept_lights(torch.tensor([[[5.0], [0.01], [1.0]]]), torch.ones(1, 3), 0.01).tolist()
        [[True, False, True]]
    """
    energy = (lighting.detach().abs().to(torch.float64) * norms.to(torch.float64).T[None]).sum(-1)
    sorted_energy, order = energy.sort(dim=1)
    cumulative = sorted_energy.cumsum(dim=1)
    keep_sorted = cumulative > eps * cumulative[:, -1:]
    return torch.zeros_like(keep_sorted).scatter(1, order, keep_sorted)


def _relight_light_major(field_t: torch.Tensor, lights: torch.Tensor, keep: torch.Tensor) -> torch.Tensor:
    """``(B, C, P)`` product of a light-major field ``(C', N, P)`` with each item's kept lights only.

    With few kept lights in all (at most ``N`` summed over the batch) every ``(item, channel)`` is one
    weighted bag of field rows (:func:`torch.nn.functional.embedding_bag`): only the kept rows are read and
    nothing of the field's size is allocated. Otherwise one dense product with the dropped lights zeroed.
    """
    b, n, c = lights.shape
    cf, _, p = field_t.shape
    counts = keep.sum(1)
    if int(counts.sum()) > n:  # bags of up to N rows cost at most one dense pass; beyond, the product wins
        lights = lights * keep[..., None].to(lights.dtype)
        if cf == 1:  # shared: (B*C, N) @ (N, P)
            return (lights.permute(0, 2, 1).reshape(b * c, n) @ field_t[0]).reshape(b, c, p)
        return torch.bmm(lights.permute(2, 0, 1), field_t).transpose(0, 1)  # (C, B, N) @ (C, N, P)
    item, light = keep.nonzero(as_tuple=True)  # (M,) each, item-major
    chan = torch.arange(c, device=keep.device)
    rows = light[:, None] + (chan * n if cf > 1 else torch.zeros_like(chan))[None]  # (M, C) rows of the field
    order = (item[:, None] * c + chan[None]).flatten().argsort(stable=True)  # group by bag (item, channel)
    sizes = counts.repeat_interleave(c)
    out = nn.functional.embedding_bag(
        rows.flatten()[order],
        field_t.reshape(cf * n, p),
        sizes.cumsum(0) - sizes,
        mode="sum",
        per_sample_weights=lights[item, light].flatten()[order],
    )
    return out.reshape(b, c, p)


def relight(
    field: torch.Tensor,
    lighting: torch.Tensor,
    size: int | tuple[int, int] | None = None,
    *,
    eps: float = 0.0,
) -> torch.Tensor:
    r"""Relight a reflectance field: ``I[b, c, p] = sum_n R[c, p, n] L[b, n, c]``.

    Dense mode (``eps == 0``) is exactly linear in the lighting: ``relight(R, a L1 + b L2) =
    a relight(R, L1) + b relight(R, L2)``.

    Energy-truncated mode (``eps > 0``) skips, per batch item, the weakest lights that together carry at
    most a fraction ``eps`` of the energy. The energy of light ``n`` is
    ``E[n] = sum_c |L[n, c]| ||R[c, :, n]||_1``; lights are sorted by energy and the longest run of the
    weakest with cumulative energy ``<= eps * sum_n E[n]`` is dropped (set ``D``). Error bound, exact
    arithmetic:

    - per pixel: ``|I[c, p] - I_eps[c, p]| <= sum_{n in D} |R[c, p, n]| |L[n, c]|``;
    - whole image: ``sum_{c, p} |I - I_eps| <= sum_{n in D} E[n] <= eps * sum_n E[n]``;
    - for non-negative ``R`` and ``L`` (every physical field and lighting) ``sum_n E[n] = sum_{c, p} I``,
      so ``0 <= I - I_eps`` everywhere and the truncation loses at most ``eps`` of the image's total
      energy: ``sum (I - I_eps) <= eps * sum I``.

    Each batch item's result depends only on its own lighting. The selection is not differentiable: the
    gradient with respect to dropped lights is 0. This functional recomputes the light norms (a full pass
    over ``R``) and then multiplies densely with the dropped lights zeroed, so it is never faster than dense
    mode; :class:`Relight` precomputes the norms and a light-major copy of ``R`` once and multiplies only the
    kept lights, which is where the speed-up is.

    Args:
        field: reflectance field ``R``, channel-major ``(C, P, N)`` or shared across channels ``(P, N)``.
            It is not scanned for NaN/Inf on every call (at ``P = 256^2``, ``N = 1024`` that scan costs
            many times the product); :class:`Relight` checks it once.
        lighting: ``L`` as a light list ``(B, N, C)`` in radiance (for a mirror-ball image use
            :func:`~kornia_ilum.geometry.mirror_ball_to_lights`). Any finite values; negative lighting is
            allowed (for example differences of lightings).
        size: output ``(H, W)`` with ``H * W = P``, or an int for a square; default: the square ``sqrt(P)``.
        eps: fraction of the energy that may be dropped, in ``[0, 1)``; 0 is exact.

    Returns:
        the relit images ``(B, C, H, W)``. The result may be a non-contiguous view of the product (it is
        laid out as the matrix product writes it); call ``.contiguous()`` if you need one.

    Raises:
        ShapeError: wrong ranks, ``N`` or ``C`` mismatch, or ``P`` no square without ``size``.
        TypeCheckError: non-tensor or non-floating inputs.
        NonFiniteError: ``lighting`` holds NaN or Inf.
        EmptyTensorError: an empty input.
        ValueCheckError: ``eps`` outside ``[0, 1)`` or a malformed ``size``.

    Shape:
        - field: :math:`(C, P, N)` or :math:`(P, N)`
        - lighting: :math:`(B, N, C)`
        - Output: :math:`(B, C, H, W)`, :math:`H W = P`

    Convention:
        Output dtype: ``torch.promote_types(field.dtype, lighting.dtype)``. A float16 / bfloat16 field is
        never copied: the lighting is cast to the field's dtype and the product runs in it (float32
        accumulation inside the BLAS), then the result is cast to the output dtype. So a bfloat16 field with
        float32 lighting returns float32 at bfloat16 speed, with bfloat16 rounding of the lighting and of
        the result (relative error ~2^-8); float16 lighting above 65504 overflows, use bfloat16. Other
        dtype pairs compute in the promoted dtype. Units: ``I`` is in the units of ``L`` times those of
        ``R`` (docs/conventions.rst: radiance in, linear pixel values out).

    Examples:
        >>> field = torch.eye(4)  # 2 x 2 pixels, each lit by its own light
        >>> relight(field, torch.arange(8.0).reshape(1, 4, 2))
        tensor([[[[0., 2.],
                  [4., 6.]],
        <BLANKLINE>
                 [[1., 3.],
                  [5., 7.]]]])
    """
    _check_field(field, finite=False)
    _check_lighting(field, lighting)
    eps = check_eps(eps)
    h, w = _image_size(field.shape[-2], size)
    compute, out_dtype = _dtypes(field, lighting)
    lights = lighting.to(compute)
    if eps > 0.0:
        keep = kept_lights(lighting, light_norms(field), eps)
        lights = lights * keep[..., None].to(compute)
    out = relight_product(field.to(compute), lights)
    return out.reshape(out.shape[0], out.shape[1], h, w).to(out_dtype)


class Relight(nn.Module):
    r"""Module twin of :func:`relight` holding the field as a non-persistent buffer.

    The field is checked once here (shape, dtype, finite), not on every call. With ``eps > 0`` the module
    stores the field light-major ``(C', N, P)`` and the per-light norms ``||R[c, :, n]||_1`` instead, so that
    truncated relighting reads only the field rows of each item's kept lights: its cost is proportional to
    the number of kept lights summed over the batch, ``K``. While ``K <= N`` each (item, channel) is a
    weighted sum of ``K`` field rows (:func:`torch.nn.functional.embedding_bag`); beyond that, one dense
    product in the light-major layout with the dropped lights zeroed, which is slower than dense mode (the
    BLAS prefers the channel-major layout), so use ``eps > 0`` for peaky (HDR, sunny) lighting: with a sun
    over 2 pixels and a dim sky, ``eps = 0.05`` keeps 2 lights (L1 error 2.5% of the image) and reads 2 rows
    of the field instead of all of it (the measured times are in the docs' render page). Results equal
    :func:`relight` with the same ``eps``, including the error bound documented there.

    Args:
        field: reflectance field, ``(C, P, N)`` or ``(P, N)``.
        size: output ``(H, W)`` (or an int for a square); default ``sqrt(P)``.
        eps: energy fraction that may be dropped, in ``[0, 1)``.

    Shape:
        - Input: :math:`(B, N, C)` lighting
        - Output: :math:`(B, C, H, W)`, :math:`H W = P`

    Examples:
        >>> relight_module = Relight(torch.eye(4), eps=0.1)
        >>> relight_module(torch.tensor([[[1.0], [0.01], [1.0], [1.0]]])).flatten()
        tensor([1., 0., 1., 1.])
    """

    def __init__(
        self, field: torch.Tensor, size: int | tuple[int, int] | None = None, eps: float = 0.0
    ) -> None:
        super().__init__()
        _check_field(field, finite=True)
        self.eps = check_eps(eps)
        self.size = _image_size(field.shape[-2], size)
        self.shared = field.dim() == 2
        if self.eps == 0.0:
            self.register_buffer("field", field, persistent=False)
        else:
            field_t = field.transpose(-1, -2).contiguous()
            self.register_buffer("field_t", field_t[None] if self.shared else field_t, persistent=False)
            self.register_buffer("light_norms", light_norms(field), persistent=False)

    def forward(self, lighting: torch.Tensor) -> torch.Tensor:
        if self.eps == 0.0:
            return relight(self.field, lighting, self.size)
        # the same checks and dtype rule as relight(), on the light-major field
        field_t = self.field_t
        view = field_t[0].T if self.shared else field_t.transpose(-1, -2)
        _check_lighting(view, lighting)
        compute, out_dtype = _dtypes(field_t, lighting)
        keep = kept_lights(lighting, self.light_norms, self.eps)
        out = _relight_light_major(field_t.to(compute), lighting.to(compute), keep)
        return out.reshape(out.shape[0], out.shape[1], *self.size).to(out_dtype)

    def extra_repr(self) -> str:
        channels = "shared" if self.shared else "channel-major"
        return f"size={self.size}, eps={self.eps}, field={channels}"
