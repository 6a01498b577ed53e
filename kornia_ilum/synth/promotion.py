r"""LDR-to-HDR promotion of three-sphere photographs (LeGendre et al. 2020, Eq. 1-3).

LeGendre et al. 2020 ("Learning Illumination from Diverse Portraits", SIGGRAPH Asia 2020 Technical
Communications, arXiv 2008.02396), like LeGendre et al. 2019 ("DeepLight: Learning Illumination for
Unconstrained Mobile Mixed Reality", CVPR 2019) before it, record lighting as one LDR photograph of three
spheres: a mirror ball, a matte-silver ball and a diffuse ball. The mirror ball gives the radiance of every
direction it does not clip; the energy of the clipped (brightest) directions is recovered from the two
blurry balls, which see every light through their reflectance fields, by a non-negative linear solve with a
cross-colour regulariser (``lambda = 0.5``, colour balance from the diffuse ball). In the spirit of Debevec et
al. 2012 ("A single-shot light probe"), which recovers saturated lights from diffuse strips.

What is implemented (``S`` = sphere side = lighting side, ``c`` = channel, ``n`` = mirror-ball direction)::

    I_k  = gamma_decode(ldr_k, 2.2)                                           (linear sphere images)
    C    = {n on the ball : max_c I_mirror[c, n] >= t},  t = gamma_decode(clip_threshold)
    L0   = I_mirror / 0.827,  with clipped channels set to t / 0.827          (Eq. 1, a lower bound)
    L    = L0 + U,  U >= 0 and U = 0 off C                                    (Eq. 2)
    U*   = argmin_{U >= 0}  sum_{k in (diffuse, matte_silver)} sum_{(p, c): I_k[c, p] < t}
                                (R_k[p, C] U_c - (I_k[c, p] - R_k[p, :] L0_c))^2
           + lambda s^2 sum_{n in C} sum_c (U_c[n] - w_c sum_c' U_c'[n])^2                  (Eq. 3)
           + mu s^2 |U|^2

- ``R_k`` is :func:`~kornia_ilum.render.sphere_reflectance_field` of the sphere, shared by the channels.
- Only the clipped directions are unknowns (``3 K`` of them for ``K = |C|``); unclipped mirror pixels pass
  through unchanged. Sphere pixels with a clipped channel are excluded from the data term (per pixel and
  channel: the other channels of that pixel still count).
- ``w`` is the colour balance of the diffuse ball: ``w_c = sum_p I_d[c, p] / sum_{p, c'} I_d[c', p]`` over the
  on-sphere pixels with no clipped channel (``(1, 1, 1) / 3`` when there are none).
- ``s^2`` is the mean squared norm of the data term's columns, which makes ``lambda`` dimensionless and
  independent of ``S``: ``lambda = 0.5`` weighs the colour prior on each unknown at half the average weight
  of the data on it. ``mu = 1e-9`` is a ridge that makes the problem strictly convex (unique solution); it
  sends directions that no unclipped sphere pixel sees to 0 instead of leaving them arbitrary.
- The whole three-channel problem, data and regulariser, is one NNLS in the ``3 K`` unknowns per probe.

Where the text is ambiguous (documented choices): the exact published form of Eq. 1-3 could not be
retrieved from the stored copies of the paper available to this project; the formulation above follows the
paper's description (mirror divided by its reflectivity 0.827 where unclipped, a residual ``U >= 0`` on the
clipped directions solved by NNLS from the diffuse and matte-silver spheres with clipped pixels excluded,
and a cross-colour regulariser with ``lambda = 0.5`` tied to the diffuse ball's colour balance). The
penalty form ``U_c - w_c sum U`` (each recovered light takes the colour of the diffuse ball), the
normalisation ``s^2`` of ``lambda``, per-channel exclusion of clipped sphere pixels, the ridge ``mu``, and
the threshold below are this module's choices.

Decoding uses a pure gamma 2.2 (:func:`~kornia_ilum.color.gamma_decode`, as the issue states for the
capture), not the piecewise sRGB curve. ``clip_threshold = 254/255`` marks a channel as clipped from code
254 up: real 8-bit pipelines (rounding, JPEG) saturate at 254 or 255, and mistaking a saturated pixel for a
measurement costs far more than giving up one near-white measurement; the clipped lower bound is then
``gamma_decode(254/255) = 0.991`` of white.

Solvers (``method``), both exact NNLS of the same objective, agree to about 1e-6 relative:

- ``"torch"``: a batched block principal pivoting active-set method (Kim & Park 2011, "Fast nonnegative
  matrix factorization: an active-set-like method and comparisons", SIAM J. Sci. Comput.) on the
  column-scaled normal equations in float64, all probes of the batch in lock-step (one batched
  ``torch.linalg.solve`` per pivoting step; finite termination by the backup rule). Runs on the inputs'
  device.
- ``"scipy"``: :func:`scipy.optimize.nnls` (Lawson-Hanson) per probe on the stacked rows on the CPU.
- ``"auto"``: ``"torch"``, the faster on every problem of ``benchmarks/bench_promotion.py`` (its table gives
  the medians per probe).

Not differentiable (an active-set solve with thresholds on 8-bit codes): gradcheck and ``torch.compile`` are
not meaningful here and are not supported; the module twin :class:`PromoteSpheres` only caches the fields.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import torch
from torch import nn

from kornia_ilum.color.transfer import gamma_decode
from kornia_ilum.core.check import check_tensor, checks_active
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry.mirror_ball import mirror_ball_valid
from kornia_ilum.render.spheres import MIRROR_REFLECTIVITY, SPHERE_SIZES, _shared_field

__all__ = ["CLIP_THRESHOLD", "PromotionResult", "PromoteSpheres", "promote_spheres"]

#: Encoded value from which a channel counts as clipped (8-bit code 254; see the module docstring).
CLIP_THRESHOLD = 254.0 / 255.0

Method = Literal["auto", "torch", "scipy"]
_METHODS = ("auto", "torch", "scipy")
Balance = Literal["residual", "diffuse"]
_BALANCES = ("residual", "diffuse")
_RIDGE = 1e-9  # mu, relative to the mean squared column norm s^2
_SOLVE_SPHERES = ("diffuse", "matte_silver")


@dataclass
class PromotionResult:
    """The promoted lighting and what the solve did.

    Attributes:
        lighting: ``(B, 3, S, S)`` linear HDR mirror-ball lighting (radiance, 0 off the ball), never negative.
        clipped: ``(B, S, S)`` bool, the directions whose mirror pixel had a clipped channel (the unknowns).
        residual: ``(B, 3, S, S)`` the solved ``U >= 0`` (0 off the clipped directions).
        solved: ``(B,)`` bool, whether a solve ran (False when nothing was clipped).
    """

    lighting: torch.Tensor
    clipped: torch.Tensor
    residual: torch.Tensor
    solved: torch.Tensor


def _check_ldr(x: object, name: str, size: int | None) -> None:
    if not isinstance(x, torch.Tensor):
        raise TypeCheckError(f"{name} must be a torch.Tensor of shape (B, 3, S, S), got {type(x).__name__}")
    if x.dtype != torch.uint8 and not x.is_floating_point():
        raise TypeCheckError(f"{name} must be uint8 or floating point (sRGB in [0, 1]), got dtype {x.dtype}")
    check_tensor(x, name, ["B", "3", "S", "S"], floating=False)
    s = x.shape[-1]
    if x.shape[-2] != s or s not in SPHERE_SIZES or (size is not None and s != size):
        want = f"S = {size}" if size is not None else f"S in {SPHERE_SIZES}"
        raise ShapeError(f"{name} must have shape (B, 3, S, S) with {want}, got {tuple(x.shape)}")
    if x.is_floating_point() and checks_active():
        lo, hi = torch.aminmax(x.detach())
        if float(lo) < 0.0 or float(hi) > 1.0:
            raise ValueCheckError(
                f"{name} must hold encoded values in [0, 1], got range [{float(lo):g}, {float(hi):g}]"
            )


def _check_args(
    mirror_ldr: torch.Tensor,
    diffuse_ldr: torch.Tensor,
    matte_ldr: torch.Tensor,
    lam: float,
    gamma: float,
    clip_threshold: float,
    method: str,
    balance: str,
    size: int | None = None,
) -> None:
    named = (("mirror_ldr", mirror_ldr), ("diffuse_ldr", diffuse_ldr), ("matte_ldr", matte_ldr))
    for name, x in named:
        _check_ldr(x, name, size)
    for name, x in named[1:]:
        if x.shape != mirror_ldr.shape:
            raise ShapeError(
                f"{name} must have the shape of mirror_ldr {tuple(mirror_ldr.shape)}, got {tuple(x.shape)}"
            )
        if x.dtype != mirror_ldr.dtype:
            raise TypeCheckError(f"{name} must have the dtype of mirror_ldr ({mirror_ldr.dtype}), got {x.dtype}")
        if x.device != mirror_ldr.device:
            raise ValueCheckError(f"{name} must be on the device of mirror_ldr ({mirror_ldr.device}), got {x.device}")
    _check_params(lam, gamma, clip_threshold, method, balance)


def _check_params(lam: float, gamma: float, clip_threshold: float, method: str, balance: str) -> None:
    for name, value in (("lam", lam), ("gamma", gamma), ("clip_threshold", clip_threshold)):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise TypeCheckError(f"{name} must be a float, got {type(value).__name__}")
    if not lam >= 0 or lam == float("inf"):
        raise ValueCheckError(f"lam must be finite and >= 0, got {lam}")
    if not 0 < gamma < float("inf"):
        raise ValueCheckError(f"gamma must be positive and finite, got {gamma}")
    if not 0 < clip_threshold <= 1:
        raise ValueCheckError(f"clip_threshold must be in (0, 1], got {clip_threshold}")
    if method not in _METHODS:
        raise ValueCheckError(f"method must be one of {_METHODS}, got {method!r}")
    if balance not in _BALANCES:
        raise ValueCheckError(f"balance must be one of {_BALANCES}, got {balance!r}")


def _decode(x: torch.Tensor, gamma: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Encoded values in [0, 1] and their linear decoding, float64."""
    enc = x.to(torch.float64) / 255.0 if x.dtype == torch.uint8 else x.to(torch.float64)
    return enc, gamma_decode(enc, gamma)


@dataclass
class _System:
    """The per-probe NNLS, batched and padded: ``min_{x >= 0} x^T G x - 2 c^T x`` over ``n = 3 K_max``."""

    gram: torch.Tensor  # (B', n, n) float64, ridge included, padded variables: identity
    rhs: torch.Tensor  # (B', n)
    free: torch.Tensor  # (B', n) bool, real (not padded) unknowns
    rows: list[tuple[torch.Tensor, torch.Tensor]]  # per probe: stacked A (m, 3K), b (m,) for SciPy


def _colour_balance(
    diffuse: torch.Tensor, unexplained: torch.Tensor, ok: torch.Tensor, balance: str
) -> torch.Tensor:
    """``w`` (B', 3): the colour of the diffuse ball's light the mirror missed, or of the whole ball.

    Sums over the on-sphere pixels ``ok`` with no clipped channel; ``"residual"`` sums ``I_d - R_d L0``
    (clamped at 0 per channel), ``"diffuse"`` sums ``I_d``. Falls back to the whole ball, then to grey.
    """
    whole = (diffuse * ok[:, None]).sum(-1).clamp(min=0.0)  # (B', 3)
    sums = whole
    if balance == "residual":
        missing = (unexplained * ok[:, None]).sum(-1).clamp(min=0.0)
        sums = torch.where(missing.sum(-1, keepdim=True) > 0, missing, whole)
    total = sums.sum(-1, keepdim=True)
    return torch.where(total > 0, sums / total.clamp(min=1e-300), torch.full_like(sums, 1.0 / 3.0))


def _build_system(
    fields: torch.Tensor,
    enc: dict[str, torch.Tensor],
    lin: dict[str, torch.Tensor],
    base: torch.Tensor,
    clipped_flat: torch.Tensor,
    thr_enc: float,
    lam: float,
    balance: str,
    want_rows: bool,
) -> _System:
    """Assemble Eq. 3 for the probes with a clipped direction (all inputs restricted to those probes).

    Args:
        fields: ``(2, P, N)`` fields of the diffuse and matte-silver spheres (float64).
        enc, lin: encoded and linear sphere images ``(B', 3, P)`` by name.
        base: ``(B', 3, N)`` the lower bound ``L0``.
        clipped_flat: ``(B', N)`` bool.
    """
    bsz, n_dirs = clipped_flat.shape
    counts = clipped_flat.sum(1)
    k_max = int(counts.max())
    # column index of each probe's clipped directions, padded with direction 0 (masked below)
    order = torch.argsort((~clipped_flat).to(torch.int8), dim=1, stable=True)[:, :k_max]  # (B', K)
    col_ok = torch.arange(k_max, device=order.device)[None, :] < counts[:, None]  # (B', K)
    fields_b = fields[:, None].expand(-1, bsz, -1, -1)  # (2, B', P, N)
    sel = torch.gather(fields_b, 3, order[None, :, None, :].expand(2, -1, fields.shape[1], -1))
    sel = sel * col_ok[None, :, None, :]  # (2, B', P, K)
    rendered = torch.einsum("spn,bcn->sbcp", fields, base)  # (2, B', 3, P): R_k L0
    names = _SOLVE_SPHERES
    obs = torch.stack([lin[k] for k in names])  # (2, B', 3, P)
    keep = torch.stack([enc[k] < thr_enc for k in names])  # (2, B', 3, P)
    on_sphere = fields.sum(2) > 0  # (2, P)
    keep = keep & on_sphere[:, None, None, :]
    target = (obs - rendered) * keep  # (2, B', 3, P)
    # data term per channel: G_c = sum_k A_kc^T A_kc, c_c = sum_k A_kc^T b_kc
    gram_c = torch.einsum("sbpk,sbcp,sbpl->bckl", sel, keep.to(sel.dtype), sel)  # (B', 3, K, K)
    rhs_c = torch.einsum("sbpk,sbcp->bck", sel, target)  # (B', 3, K)
    diag = torch.diagonal(gram_c, dim1=-2, dim2=-1)  # (B', 3, K)
    n_free = (3 * counts).clamp(min=1).to(diag.dtype)
    scale2 = diag.sum((1, 2)) / n_free  # s^2: mean squared column norm of the data term
    scale2 = torch.where(scale2 > 0, scale2, torch.ones_like(scale2))
    w = _colour_balance(lin["diffuse"], target[0], keep[0].all(1), balance)
    eye3 = torch.eye(3, dtype=w.dtype, device=w.device)
    m = eye3[None] - w[:, :, None]  # (B', 3, 3): row c is e_c - w_c 1^T
    mtm = m.transpose(1, 2) @ m  # (B', 3, 3)
    n = 3 * k_max
    eye_k = torch.eye(k_max, dtype=w.dtype, device=w.device)
    gram = torch.zeros(bsz, 3, k_max, 3, k_max, dtype=w.dtype, device=w.device)
    for c in range(3):
        gram[:, c, :, c, :] = gram_c[:, c]
    reg = (lam * scale2)[:, None, None] * mtm  # (B', 3, 3)
    gram = gram + reg[:, :, None, :, None] * eye_k[None, None, :, None, :]
    ridge = (_RIDGE * scale2)[:, None, None, None, None] * torch.eye(3, dtype=w.dtype, device=w.device)[
        None, :, None, :, None
    ] * eye_k[None, None, :, None, :]
    gram = gram + ridge
    free = col_ok[:, None, :].expand(-1, 3, -1).reshape(bsz, n)
    gram = gram.reshape(bsz, n, n)
    gram = gram * (free[:, :, None] & free[:, None, :]) + torch.diag_embed((~free).to(gram.dtype))
    rhs = rhs_c.reshape(bsz, n) * free
    rows: list[tuple[torch.Tensor, torch.Tensor]] = []
    if want_rows:
        for b in range(bsz):
            k = int(counts[b])
            blocks, targets = [], []
            for c in range(3):
                for s in range(2):
                    r = keep[s, b, c].nonzero().squeeze(1)
                    a = torch.zeros(r.numel(), 3 * k, dtype=w.dtype, device=w.device)
                    a[:, c * k : (c + 1) * k] = sel[s, b][r][:, :k]
                    blocks.append(a)
                    targets.append(target[s, b, c, r])
            root = float(scale2[b]) ** 0.5
            blocks.append((lam**0.5 * root) * torch.kron(m[b], torch.eye(k, dtype=w.dtype, device=w.device)))
            blocks.append((_RIDGE**0.5 * root) * torch.eye(3 * k, dtype=w.dtype, device=w.device))
            targets.append(torch.zeros(6 * k, dtype=w.dtype, device=w.device))
            rows.append((torch.cat(blocks), torch.cat(targets)))
    return _System(gram, rhs, free, rows)


def _nnls_bpp(gram: torch.Tensor, rhs: torch.Tensor, free: torch.Tensor, max_iter: int = 500) -> torch.Tensor:
    """Batched block principal pivoting NNLS on normal equations (Kim & Park 2011, Algorithm 2).

    Solves ``min_{x >= 0} x^T G x - 2 c^T x`` for each item; ``G`` must be symmetric positive definite.
    Columns are scaled to unit diagonal first. Items converge independently and freeze once the KKT
    conditions hold; an item still infeasible after ``max_iter`` steps raises (it never happened in tests).
    """
    d = torch.diagonal(gram, dim1=-2, dim2=-1).clamp(min=1e-300).rsqrt()  # (B, n)
    g = gram * d[:, :, None] * d[:, None, :]
    c = rhs * d
    bsz, n = c.shape
    tol = 1e-12 * c.abs().amax(1, keepdim=True).clamp(min=1e-300)  # scaled variables: one scale for x and y
    passive = torch.zeros_like(free)
    x = torch.zeros_like(c)
    best = torch.full((bsz,), n + 1, dtype=torch.long, device=c.device)
    backup = torch.full((bsz,), 3, dtype=torch.long, device=c.device)
    done = torch.zeros(bsz, dtype=torch.bool, device=c.device)
    index = torch.arange(n, device=c.device)
    eye = torch.eye(n, dtype=g.dtype, device=g.device)
    for _ in range(max_iter):
        both = passive[:, :, None] & passive[:, None, :]
        system = torch.where(both, g, eye)
        x = torch.linalg.solve(system, torch.where(passive, c, 0.0)[..., None])[..., 0]
        x = torch.where(passive, x, 0.0)
        y = torch.where(passive, 0.0, (g @ x[..., None])[..., 0] - c)
        bad = free & ((passive & (x < -tol)) | (~passive & (y < -tol)))
        n_bad = bad.sum(1)
        done = done | (n_bad == 0)
        if bool(done.all()):
            return (x.clamp(min=0.0) * d) * free
        better = n_bad < best
        best = torch.where(better, n_bad, best)
        backup = torch.where(better, torch.full_like(backup, 3), backup)
        flip_all = better | (backup >= 1)
        backup = torch.where(~better & flip_all, backup - 1, backup)
        last = torch.where(bad, index, -1).amax(1)  # the largest infeasible index (Murty's rule)
        single = index[None, :] == last[:, None]
        flip = torch.where(flip_all[:, None], bad, single) & ~done[:, None]
        passive = passive ^ flip
    raise RuntimeError(f"NNLS did not converge in {max_iter} block-pivoting steps")


def _nnls_scipy(rows: list[tuple[torch.Tensor, torch.Tensor]]) -> list[torch.Tensor]:
    from scipy.optimize import nnls

    out = []
    for a, b in rows:
        a_np, b_np = a.cpu().numpy(), b.cpu().numpy()
        x, _ = nnls(a_np, b_np, maxiter=50 * a_np.shape[1] + 100)
        out.append(torch.from_numpy(np.asarray(x)))
    return out


def _promote(
    mirror_ldr: torch.Tensor,
    diffuse_ldr: torch.Tensor,
    matte_ldr: torch.Tensor,
    fields: torch.Tensor,
    lam: float,
    gamma: float,
    clip_threshold: float,
    method: str,
    balance: str,
) -> PromotionResult:
    bsz, _, s, _ = mirror_ldr.shape
    device = mirror_ldr.device
    out_dtype = mirror_ldr.dtype if mirror_ldr.is_floating_point() else torch.get_default_dtype()
    valid = mirror_ball_valid(s, device=device).flatten()  # (N,)
    enc, lin = {}, {}
    for name, x in (("mirror", mirror_ldr), ("diffuse", diffuse_ldr), ("matte_silver", matte_ldr)):
        e, li = _decode(x.flatten(2), gamma)
        enc[name], lin[name] = e, li
    thr_enc = float(clip_threshold) - 1e-9  # codes are exact multiples of 1/255: keep 254/255 itself clipped
    thr_lin = float(gamma_decode(torch.tensor(float(clip_threshold), dtype=torch.float64), gamma))
    clipped_c = (enc["mirror"] >= thr_enc) & valid  # (B, 3, N)
    clipped = clipped_c.any(1)  # (B, N)
    base = torch.where(clipped_c, torch.full_like(lin["mirror"], thr_lin), lin["mirror"])
    base = base * valid / MIRROR_REFLECTIVITY  # (B, 3, N): Eq. 1, L0
    residual = torch.zeros_like(base)
    solved = clipped.any(1)
    idx = solved.nonzero().squeeze(1)
    if idx.numel() > 0:
        sub = lambda t: t[idx]  # noqa: E731
        use_scipy = method == "scipy"
        system = _build_system(
            fields,
            {k: sub(v) for k, v in enc.items()},
            {k: sub(v) for k, v in lin.items()},
            sub(base),
            sub(clipped),
            thr_enc,
            lam,
            balance,
            want_rows=use_scipy,
        )
        k_max = system.rhs.shape[1] // 3
        if use_scipy:
            sol = torch.zeros_like(system.rhs)
            for b, x in enumerate(_nnls_scipy(system.rows)):
                k = x.numel() // 3
                sol[b].view(3, k_max)[:, :k] = x.view(3, k).to(sol)
        else:
            sol = _nnls_bpp(system.gram, system.rhs, system.free)
        sol = sol.view(-1, 3, k_max).clamp(min=0.0)
        clipped_sub = clipped[idx]
        order = torch.argsort((~clipped_sub).to(torch.int8), dim=1, stable=True)[:, :k_max]
        ok = torch.arange(k_max, device=device)[None, :] < clipped_sub.sum(1)[:, None]
        res_sub = torch.zeros(idx.numel(), 3, base.shape[-1], dtype=base.dtype, device=device)
        res_sub.scatter_add_(2, order[:, None, :].expand(-1, 3, -1), sol * ok[:, None, :])
        residual[idx] = res_sub
    lighting = base + residual
    shape = (bsz, 3, s, s)
    return PromotionResult(
        lighting=lighting.view(shape).to(out_dtype),
        clipped=clipped.view(bsz, s, s),
        residual=residual.view(shape).to(out_dtype),
        solved=solved,
    )


def _fields(size: int, device: torch.device) -> torch.Tensor:
    return torch.stack([_shared_field(k, size, size, device, torch.float64) for k in _SOLVE_SPHERES])


def promote_spheres(
    mirror_ldr: torch.Tensor,
    diffuse_ldr: torch.Tensor,
    matte_ldr: torch.Tensor,
    *,
    lam: float = 0.5,
    gamma: float = 2.2,
    clip_threshold: float = CLIP_THRESHOLD,
    method: Method = "auto",
    balance: Balance = "residual",
) -> PromotionResult:
    r"""Promote an 8-bit photograph of the three reference spheres to HDR mirror-ball lighting.

    The unclipped mirror pixels, divided by the mirror's reflectivity 0.827, give the radiance of their
    directions; the energy missing from the clipped directions is a residual ``U >= 0`` solved from the
    diffuse and matte-silver spheres by non-negative least squares with a cross-colour regulariser
    (LeGendre et al. 2020, Eq. 1-3; the formulation and the documented choices are in the module
    docstring). Probes with no clipped direction skip the solve.

    Args:
        mirror_ldr: the mirror sphere, 8-bit sRGB: ``uint8`` codes, or floats in ``[0, 1]`` (normally
            multiples of 1/255), ``(B, 3, S, S)`` in the mirror-ball pixel grid, ``S`` in
            :data:`~kornia_ilum.render.SPHERE_SIZES` (32 in the paper).
        diffuse_ldr: the diffuse sphere, same shape and dtype.
        matte_ldr: the matte-silver sphere, same shape and dtype.
        lam: weight ``lambda`` of the cross-colour regulariser (dimensionless, see the module docstring);
            0 gives independent per-channel NNLS.
        gamma: display gamma of the encoding (decoded as ``x^gamma``, not the sRGB curve).
        clip_threshold: encoded value from which a channel counts as clipped (code 254 by default).
        method: ``"torch"`` (batched, on the inputs' device), ``"scipy"`` (:func:`scipy.optimize.nnls` per
            probe on the CPU) or ``"auto"`` (``"torch"``, the faster; see ``benchmarks/bench_promotion.py``).

    Returns:
        :class:`PromotionResult` with the linear HDR ``lighting`` (never negative, 0 off the ball), the
        ``clipped`` directions, the solved ``residual`` and the per-probe ``solved`` flag. The tensors are in
        the inputs' float dtype (float32 for ``uint8``) and on their device; everything is computed in
        float64 (a half-precision result can overflow where a sun is brighter than 65504).

    Shape:
        - mirror_ldr, diffuse_ldr, matte_ldr: :math:`(B, 3, S, S)`
        - lighting, residual: :math:`(B, 3, S, S)`; clipped: :math:`(B, S, S)`; solved: :math:`(B,)`

    Convention:
        SPEC.md: the reference spheres (diffuse albedo 0.8, matte silver GGX 0.3, mirror 0.827) seen
        orthographically along -Z in the mirror-ball grid, which is also the lighting's grid (mirror pixel
        ``(i, j)`` reflects lighting direction ``(i, j)``); lighting in the units of the linear photograph.

    Raises:
        TypeCheckError: an input is no tensor, not uint8/float, or dtypes differ; a parameter is no number.
        ShapeError: wrong or mismatched shapes, or ``S`` not in :data:`~kornia_ilum.render.SPHERE_SIZES`.
        ValueCheckError: values outside ``[0, 1]``, devices differ, or a bad ``lam``/``gamma``/
            ``clip_threshold``/``method``.
        NonFiniteError: NaN or Inf in an input.

    Examples:
        >>> from kornia_ilum.color import gamma_encode, quantize
        >>> from kornia_ilum.render import render_spheres
        >>> truth = torch.full((1, 3, 16, 16), 0.5)
        >>> truth[0, :, 5, 9] = torch.tensor([400.0, 250.0, 120.0])  # a sun
        >>> spheres = render_spheres(truth, size=16)
        >>> ldr = {k: quantize(gamma_encode(v)) for k, v in spheres.items()}
        >>> out = promote_spheres(ldr["mirror"], ldr["diffuse"], ldr["matte_silver"])
        >>> out.solved.tolist(), out.clipped.sum().item()
        ([True], 1)
        >>> [round(v, -1) for v in out.lighting[0, :, 5, 9].tolist()]  # the sun, from 8-bit spheres
        [400.0, 250.0, 120.0]
    """
    _check_args(mirror_ldr, diffuse_ldr, matte_ldr, lam, gamma, clip_threshold, method, balance)
    fields = _fields(mirror_ldr.shape[-1], mirror_ldr.device)
    return _promote(
        mirror_ldr,
        diffuse_ldr,
        matte_ldr,
        fields,
        float(lam),
        float(gamma),
        float(clip_threshold),
        method,
        balance,
    )


class PromoteSpheres(nn.Module):
    r"""Module twin of :func:`promote_spheres`; the diffuse and matte-silver fields are non-persistent buffers.

    Args:
        size: side ``S`` of the sphere images and of the lighting.
        lam: weight of the cross-colour regulariser.
        gamma: display gamma of the encoding.
        clip_threshold: encoded value from which a channel counts as clipped.
        method: ``"auto"``, ``"torch"`` or ``"scipy"``.

    Examples:
        >>> promote = PromoteSpheres(size=16)
        >>> ldr = torch.full((2, 3, 16, 16), 128, dtype=torch.uint8)
        >>> out = promote(ldr, ldr, ldr)
        >>> out.solved.tolist(), out.lighting.shape
        ([False, False], torch.Size([2, 3, 16, 16]))
    """

    def __init__(
        self,
        size: int = 32,
        lam: float = 0.5,
        gamma: float = 2.2,
        clip_threshold: float = CLIP_THRESHOLD,
        method: Method = "auto",
        balance: Balance = "residual",
    ) -> None:
        super().__init__()
        if isinstance(size, bool) or not isinstance(size, int):
            raise TypeCheckError(f"size must be an int, got {type(size).__name__}")
        if size not in SPHERE_SIZES:
            raise ValueCheckError(f"size must be one of {SPHERE_SIZES}, got {size}")
        _check_params(lam, gamma, clip_threshold, method, balance)
        self.size, self.lam, self.gamma, self.clip_threshold = size, float(lam), float(gamma), float(clip_threshold)
        self.method, self.balance = method, balance
        self.register_buffer("fields", _fields(size, torch.device("cpu")), persistent=False)

    def forward(
        self, mirror_ldr: torch.Tensor, diffuse_ldr: torch.Tensor, matte_ldr: torch.Tensor
    ) -> PromotionResult:
        args = (self.lam, self.gamma, self.clip_threshold, self.method, self.balance)
        _check_args(mirror_ldr, diffuse_ldr, matte_ldr, *args, self.size)
        fields = self.fields.to(device=mirror_ldr.device, dtype=torch.float64)
        return _promote(mirror_ldr, diffuse_ldr, matte_ldr, fields, *args)

    def extra_repr(self) -> str:
        return (
            f"size={self.size}, lam={self.lam}, gamma={self.gamma}, "
            f"clip_threshold={self.clip_threshold:.6g}, method={self.method!r}, balance={self.balance!r}"
        )
