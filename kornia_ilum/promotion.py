r"""LDR-to-HDR promotion of three-sphere photographs (LeGendre et al. 2020, Eq. 1-3).

LeGendre et al. 2020 ("Learning Illumination from Diverse Portraits", SIGGRAPH Asia 2020 Technical
Communications, arXiv 2008.02396), like LeGendre et al. 2019 ("DeepLight: Learning Illumination for
Unconstrained Mobile Mixed Reality", CVPR 2019) before it, record lighting as one LDR photograph of three
spheres: a mirror ball, a matte-silver ball and a diffuse ball. The mirror gives the radiance of every
direction it does not clip; the energy of the clipped (brightest) directions is recovered from the two blurry
balls, which see every light through their reflectance fields, by a non-negative linear solve with a
cross-colour regulariser (``lambda = 0.5``, colour balance from the diffuse ball), in the spirit of Debevec et
al. 2012 ("A single-shot light probe"), who recover saturated lights from diffuse strips by a linear solve.

What is implemented (``S`` = sphere side = lighting side, ``c`` = channel, ``n`` = mirror-ball direction)::

    I_k = gamma_decode(ldr_k, 2.2)                       linear sphere images, k in (mirror, diffuse, matte)
    C   = {n on the ball : max_c ldr_mirror[c, n] >= clip_threshold}       the clipped directions, K = |C|
    L0  = I_mirror / 0.827, clipped channels set to gamma_decode(clip_threshold) / 0.827      (1), >= 0
    L   = L0 + U,   U >= 0 on C,  U = 0 elsewhere                                               (2)
    U   = argmin_{U >= 0}  sum_{k in (diffuse, matte)} sum_{(p, c) : ldr_k[c, p] < clip_threshold}
                               (R_k[p, C] U_c - (I_k[c, p] - R_k[p, :] L0_c))^2
          + lambda s^2 sum_{n in C} sum_c (U_c[n] - w_c sum_c' U_c'[n])^2                           (3)
          + mu s^2 |U|^2

- ``R_k`` is :func:`~kornia_ilum.render.sphere_reflectance_field` of the sphere at ``(S, S)``, shared by the
  channels. At this size the mirror's field is ``0.827`` times the identity, so mirror pixel ``(i, j)`` is
  lighting direction ``(i, j)``.
- Only the clipped directions are unknowns (``3 K`` of them); unclipped mirror pixels pass through
  unchanged, pixels off the ball are ignored (0). Sphere pixels are excluded from the data term per pixel and
  channel where that channel is clipped (the pixel's other channels still count).
- ``w`` is the colour balance ``w_c = m_c / sum_c' m_c'``; with ``balance="residual"`` (default) ``m`` is the
  light of the diffuse ball that the known lighting does not explain, ``m_c = sum_p (I_d - R_d L0)[c, p]``,
  i.e. the colour of the missing energy as the diffuse ball sees it; with ``balance="diffuse"`` it is the
  whole diffuse ball, ``m_c = sum_p I_d[c, p]``. Sums over the on-sphere pixels with no clipped channel;
  fallbacks: the whole ball, then grey.
- ``s^2`` is the mean squared norm of the data term's columns, which makes ``lambda`` dimensionless and
  independent of ``S``: ``lambda = 0.5`` weighs the colour prior on each unknown at half the average weight
  of the data on it. ``mu = 1e-9`` is a ridge that makes the problem strictly convex (one solution) and sends
  directions that no unclipped sphere pixel sees to 0 rather than to an arbitrary value.
- The three-channel problem, data and regulariser, is one NNLS in the ``3 K`` unknowns per probe.

Where the paper is ambiguous, and what this module chose: the exact printed form of Eq. 1-3 was not
retrievable from the copies of the paper available to this project (only its abstract and front page), so
(1)-(3) above are numbered after the issue's "Eq. 1-3", not checked against the paper, and the formulation
follows the description of the method (mirror divided by its reflectivity 0.827 where it is not clipped; a
residual ``U >= 0`` on the clipped directions, solved by non-negative least squares from the diffuse and
matte-silver spheres with their clipped pixels excluded; a cross-colour regulariser with ``lambda = 0.5`` tied
to the colour balance of the diffuse ball). This module's choices: the penalty ``U_c - w_c sum U`` (each
recovered light takes the colour ``w``); the normalisation ``s^2`` of ``lambda``; the residual colour as ``w``
by default (the literal "colour of the diffuse ball" is ``balance="diffuse"``: it pulls a clipped sun towards
the colour of the whole sky and has 2 to 30 times the radiance error in ``benchmarks/bench_promotion.py``);
per-channel exclusion of clipped sphere pixels; the ridge ``mu``; all three channels of a clipped direction as
unknowns, even where only one channel clipped; and the threshold.

Decoding is a pure gamma 2.2 (:func:`~kornia_ilum.color.gamma_decode`, exact inverse of
:func:`~kornia_ilum.color.gamma_encode`), as the issue specifies for the capture, not the piecewise sRGB
curve.
``clip_threshold = 254/255`` marks a channel as clipped from code 254 up: real 8-bit pipelines (rounding,
JPEG) saturate at 254 or 255, and taking a saturated pixel for a measurement costs far more than giving up
a near-white one; a clipped channel's lower bound is then ``gamma_decode(254/255) = 0.991`` of white.

Measured (``benchmarks/bench_promotion.py``: the 10 shared maps x 4 yaw rotations at 32 x 32, exposed so that
the 98th percentile of the mirror sphere is 0.5, which clips 7 directions per probe in the median, 15 at
most), mean absolute relative radiance error: 0.28 % (per-channel NNLS, ``lam=0``: 0.03 %; whole-ball colour
``balance="diffuse"``: 1.9 %; naive clipped lighting: 31 %); with the clipped directions tinted strongly red
or blue, 0.16 % (per-channel 0.03 %, whole-ball colour 3.8 to 4.8 %); with sensor-like noise, 0.9 to 1.0 %
(per-channel 0.6 to 0.7 %). The regulariser assumes one colour for all the clipped light: with a saturated red
and a saturated blue light clipped together the error is 16 % (per-channel 0.04 %). In these simulations
(exact sphere models, 8-bit quantisation, optional noise) per-channel NNLS is the most accurate: the paper's
reason for the regulariser, strongly hued lights in real captures, does not show in them.

Solvers (``method``) solve the same NNLS exactly (their solutions agree to 6e-11 relative on the benchmark):

- ``"torch"``: batched block principal pivoting (Kim & Park 2011, "Fast nonnegative matrix factorization: an
  active-set-like method and comparisons", SIAM J. Sci. Comput.) on the column-scaled normal equations in
  float64 on the inputs' device: one batched Cholesky factorisation per pivoting step for the probes not yet
  converged, warm-started at the variables whose gradient at 0 points inwards. A probe still infeasible after
  50 steps (slow Murty phases on large, ill-conditioned problems) is finished by SciPy.
- ``"scipy"``: :func:`scipy.optimize.nnls` (Lawson-Hanson) per probe on the CPU, applied to the ``3K x 3K``
  Cholesky square root of the normal equations (the same objective up to a constant, and much faster than on
  the stacked rows, about ``5 S^2`` of them).
- ``"auto"``: ``"torch"``, except on the CPU for chunks with more than 240 unknowns (``K > 80``), where SciPy.
  Probes are solved in chunks of 32, sorted by ``K``. The threshold is where the two cross in
  ``benchmarks/bench_promotion.py`` (per probe, whole call): the batched solver keeps up with SciPy on small
  problems and falls behind on large ones (timings in docs/environments.rst, "Measured").

Not differentiable (an active-set solve with thresholds on 8-bit codes): gradcheck and ``torch.compile`` do
not apply; :class:`PromoteSpheres`, the module twin, holds the two reflectance fields as buffers.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Literal

import numpy as np
import torch
from torch import nn

from kornia_ilum.color.transfer import gamma_decode
from kornia_ilum.core.check import check_choice, check_positive_int, check_tensor, checks_active
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry.mirror_ball import mirror_ball_valid
from kornia_ilum.render.spheres import MIRROR_REFLECTIVITY, SPHERE_SIZES, shared_sphere_field

__all__ = ["CLIP_THRESHOLD", "PromoteSpheres", "PromotionResult", "promote_spheres"]

#: Encoded value from which a channel counts as clipped (8-bit code 254; see the module docstring).
CLIP_THRESHOLD = 254.0 / 255.0

Method = Literal["auto", "torch", "scipy"]
_METHODS = ("auto", "torch", "scipy")
Balance = Literal["residual", "diffuse"]
_BALANCES = ("residual", "diffuse")
_RIDGE = 1e-9  # mu, relative to the mean squared column norm s^2
_MAX_PIVOTS = 50  # block-pivoting steps before the torch solver hands a probe to SciPy
_AUTO_TORCH_MAX_UNKNOWNS = 240  # "auto" on the CPU: torch up to 3 K = 240 unknowns in a chunk, SciPy above
_SOLVE_SPHERES = ("diffuse", "matte_silver")
_CHUNK = 32  # probes assembled and solved together (float64 temporaries: about 0.25 GB at K = 100)


@dataclass
class PromotionResult:
    """The promoted lighting and what the solve did.

    Attributes:
        lighting: ``(B, 3, S, S)`` linear HDR mirror-ball lighting (radiance, 0 off the ball), never negative.
        clipped: ``(B, S, S)`` bool, the directions whose mirror pixel had a clipped channel (the unknowns).
        residual: ``(B, 3, S, S)`` the solved ``U >= 0`` (0 off the clipped directions).
        solved: ``(B,)`` bool, whether a solve ran (False when nothing was clipped).

    Examples:
        >>> out = PromotionResult(torch.ones(1, 3, 8, 8), torch.zeros(1, 8, 8, dtype=torch.bool),
        ...                       torch.zeros(1, 3, 8, 8), torch.tensor([False]))  # nothing was clipped
        >>> out.solved.tolist(), int(out.clipped.sum()), tuple(out.lighting.shape)
        ([False], 0, (1, 3, 8, 8))
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
    *,
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
            raise TypeCheckError(
                f"{name} must have the dtype of mirror_ldr ({mirror_ldr.dtype}), got {x.dtype}"
            )
        if x.device != mirror_ldr.device:
            raise ValueCheckError(
                f"{name} must be on the device of mirror_ldr ({mirror_ldr.device}), got {x.device}"
            )
    _check_params(lam=lam, gamma=gamma, clip_threshold=clip_threshold, method=method, balance=balance)


def _check_params(*, lam: float, gamma: float, clip_threshold: float, method: str, balance: str) -> None:
    for name, value in (("lam", lam), ("gamma", gamma), ("clip_threshold", clip_threshold)):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise TypeCheckError(f"{name} must be a float, got {type(value).__name__}")
    if not lam >= 0 or lam == float("inf"):
        raise ValueCheckError(f"lam must be finite and >= 0, got {lam}")
    if not 0 < gamma < float("inf"):
        raise ValueCheckError(f"gamma must be positive and finite, got {gamma}")
    if not 0 < clip_threshold <= 1:
        raise ValueCheckError(f"clip_threshold must be in (0, 1], got {clip_threshold}")
    check_choice(method, "method", _METHODS)
    check_choice(balance, "balance", _BALANCES)


@dataclass
class _System:
    """(3) for a batch of probes, padded to ``K_max`` clipped directions (``n = 3 K_max`` unknowns).

    The NNLS is ``min_{x >= 0} |A x - b|^2`` with the stacked rows ``A`` (data, regulariser, ridge); it is
    kept as its normal equations ``G = A^T A`` and ``c = A^T b``. Padded unknowns have an identity row in
    ``G`` and ``c = 0``, so they stay 0. Unknown ``(channel, j)`` is at ``channel * K_max + j``.
    """

    gram: torch.Tensor  # (B', n, n) float64
    rhs: torch.Tensor  # (B', n)
    free: torch.Tensor  # (B', n) bool: real (not padded) unknowns
    order: torch.Tensor  # (B', K_max) the mirror-ball pixel of each clipped direction (padding: any)
    counts: torch.Tensor  # (B',) K per probe
    # the stacked rows, kept to build A explicitly (tests, the benchmark's baseline)
    sel: torch.Tensor  # (2, B', P, K_max) field columns of the clipped directions
    keep: torch.Tensor  # (2, B', 3, P) data rows used
    target: torch.Tensor  # (2, B', 3, P) I_k - R_k L0
    mix: torch.Tensor  # (B', 3, 3) sqrt(lam) s M, M = I - w 1^T
    ridge: torch.Tensor  # (B',) sqrt(mu) s


def _colour_balance(
    diffuse: torch.Tensor, unexplained: torch.Tensor, ok: torch.Tensor, balance: str
) -> torch.Tensor:
    """``w`` (B', 3): the colour of the diffuse ball's light that the mirror missed, or of the whole ball.

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
    enc: torch.Tensor,
    *,
    lin: torch.Tensor,
    base: torch.Tensor,
    clipped: torch.Tensor,
    thr_enc: float,
    lam: float,
    balance: str,
) -> _System:
    """Assemble (3) for probes that have a clipped direction.

    Args:
        fields: ``(2, P, N)`` fields of the diffuse and matte-silver spheres (float64), ``P = N = S^2``.
        enc, lin: encoded and linear images ``(3, B', 3, P)`` of the mirror, diffuse and matte spheres.
        base: ``(B', 3, N)`` the lower bound ``L0``.
        clipped: ``(B', N)`` bool, at least one True per probe.
        thr_enc: encoded clip threshold.
        lam, balance: the regulariser.
    """
    bsz = clipped.shape[0]
    counts = clipped.sum(1)
    k_max = int(counts.max())
    order = torch.argsort((~clipped).to(torch.int8), dim=1, stable=True)[:, :k_max]  # clipped first
    col_ok = torch.arange(k_max, device=order.device)[None, :] < counts[:, None]  # (B', K)
    n_pix = fields.shape[1]
    sel = torch.gather(
        fields[:, None].expand(-1, bsz, -1, -1), 3, order[None, :, None, :].expand(2, -1, n_pix, -1)
    )
    sel = sel * col_ok[None, :, None, :]  # (2, B', P, K)
    on_sphere = fields.sum(2) > 0  # (2, P)
    keep = (enc[1:] < thr_enc) & on_sphere[:, None, None, :]  # (2, B', 3, P): unclipped sphere pixels
    rendered = (fields.reshape(-1, fields.shape[2]) @ base.reshape(-1, base.shape[2]).T).view(
        2, n_pix, bsz, 3
    )
    target = (lin[1:] - rendered.permute(0, 2, 3, 1)) * keep  # (2, B', 3, P): I_k - R_k L0 on the kept rows
    # per channel, the data rows of both spheres stacked: A_c = keep_c * sel, (B', 3, 2P, K)
    rows = (sel[:, :, None] * keep[..., None]).permute(1, 2, 0, 3, 4).reshape(bsz, 3, 2 * n_pix, k_max)
    gram_c = rows.transpose(-1, -2) @ rows  # (B', 3, K, K)
    rhs_c = (rows.transpose(-1, -2) @ target.permute(1, 2, 0, 3).reshape(bsz, 3, 2 * n_pix, 1))[..., 0]
    scale2 = torch.diagonal(gram_c, dim1=-2, dim2=-1).sum((1, 2)) / (3 * counts).to(gram_c.dtype)
    scale2 = torch.where(scale2 > 0, scale2, torch.ones_like(scale2))  # s^2 (1 if no data at all)
    w = _colour_balance(lin[1], target[0], keep[0].all(1), balance)
    eye3 = torch.eye(3, dtype=w.dtype, device=w.device)
    mix = (lam * scale2).sqrt()[:, None, None] * (eye3[None] - w[:, :, None])  # row c: e_c - w_c 1^T
    couple = mix.transpose(1, 2) @ mix + (_RIDGE * scale2)[:, None, None] * eye3  # (B', 3, 3)
    eye_k = torch.eye(k_max, dtype=w.dtype, device=w.device)
    gram = torch.diag_embed(gram_c.permute(0, 2, 3, 1)).permute(0, 3, 1, 4, 2)  # (B', 3, K, 3, K) blocks
    gram = gram + couple[:, :, None, :, None] * eye_k[None, None, :, None, :]
    n = 3 * k_max
    free = col_ok.repeat(1, 3)  # (B', 3K)
    gram = gram.reshape(bsz, n, n) * (free[:, :, None] & free[:, None, :]) + torch.diag_embed(
        (~free).to(w.dtype)
    )
    rhs = rhs_c.reshape(bsz, n) * free
    return _System(gram, rhs, free, order, counts, sel, keep, target, mix, (_RIDGE * scale2).sqrt())


def _stacked_rows(system: _System, item: int) -> tuple[torch.Tensor, torch.Tensor]:
    """The explicit least-squares rows ``(A, b)`` of one probe, ``A`` of shape ``(m, 3 K)``."""
    k = int(system.counts[item])
    blocks, targets = [], []
    dtype, device = system.gram.dtype, system.gram.device
    for c in range(3):
        for s in range(2):
            rows = system.keep[s, item, c].nonzero().squeeze(1)
            a = torch.zeros(rows.numel(), 3 * k, dtype=dtype, device=device)
            a[:, c * k : (c + 1) * k] = system.sel[s, item][rows, :k]
            blocks.append(a)
            targets.append(system.target[s, item, c, rows])
    eye_k = torch.eye(k, dtype=dtype, device=device)
    blocks += [
        torch.kron(system.mix[item], eye_k),
        system.ridge[item] * torch.eye(3 * k, dtype=dtype, device=device),
    ]
    targets.append(torch.zeros(6 * k, dtype=dtype, device=device))
    return torch.cat(blocks), torch.cat(targets)


def _nnls_torch(
    gram: torch.Tensor, rhs: torch.Tensor, free: torch.Tensor, max_iter: int
) -> tuple[torch.Tensor, torch.Tensor]:
    """Batched block principal pivoting NNLS (Kim & Park 2011, Algorithm 2) on normal equations.

    Minimises ``x^T G x - 2 c^T x`` over ``x >= 0`` for each item (``G`` symmetric positive definite).
    Columns are scaled to unit diagonal, the passive set starts at ``{c > 0}``, and each step solves the
    passive-set systems of the items not yet converged with one batched Cholesky factorisation (batched LU,
    ``torch.linalg.solve``, hangs inside MKL for ``n >= 256`` with two threads on this project's CPUs).

    Returns:
        ``(x, converged)``: ``(B, n)`` and ``(B,)`` bool; ``x`` of unconverged items is not a solution.
    """
    d = torch.diagonal(gram, dim1=-2, dim2=-1).clamp(min=1e-300).rsqrt()
    g_all = gram * d[:, :, None] * d[:, None, :]
    c_all = rhs * d
    bsz, n = c_all.shape
    device = c_all.device
    x_all = torch.zeros_like(c_all)
    done = torch.zeros(bsz, dtype=torch.bool, device=device)
    items = torch.arange(bsz, device=device)  # the items still iterating, compacted after every step
    g, c, free_a = g_all, c_all, free
    tol = 1e-12 * c.abs().amax(1, keepdim=True).clamp(min=1e-300)
    passive = free_a & (c > 0)
    best = torch.full((bsz,), n + 1, dtype=torch.long, device=device)
    backup = torch.full((bsz,), 3, dtype=torch.long, device=device)
    index = torch.arange(n, device=device)
    eye = torch.eye(n, dtype=g.dtype, device=device)
    for _ in range(max_iter):
        system = torch.where(passive[:, :, None] & passive[:, None, :], g, eye)
        factor, _ = torch.linalg.cholesky_ex(system)
        x = torch.cholesky_solve(torch.where(passive, c, 0.0)[..., None], factor)[..., 0]
        x = torch.where(passive, x, 0.0)
        y = torch.where(passive, 0.0, (g @ x[..., None])[..., 0] - c)
        bad = free_a & ((passive & (x < -tol)) | (~passive & (y < -tol)))
        n_bad = bad.sum(1)
        finished = n_bad == 0
        x_all[items[finished]] = x[finished]
        done[items[finished]] = True
        if bool(finished.all()):
            break
        better = n_bad < best  # fewer infeasible: exchange them all, refill the backup count
        spend = ~better & (backup >= 1)  # no progress: exchange them all, at most 3 times in a row
        best = torch.where(better, n_bad, best)
        backup = torch.where(better, torch.full_like(backup, 3), backup - spend.long())
        last = torch.where(bad, index, -1).amax(1)  # otherwise Murty's rule: the largest infeasible index
        passive = passive ^ torch.where((better | spend)[:, None], bad, index[None, :] == last[:, None])
        keep = ~finished
        items, g, c, free_a, tol, passive, best, backup = (
            t[keep] for t in (items, g, c, free_a, tol, passive, best, backup)
        )
    return x_all.clamp(min=0.0) * d * free, done


def _nnls_scipy(gram: torch.Tensor, rhs: torch.Tensor, free: torch.Tensor) -> torch.Tensor:
    """:func:`scipy.optimize.nnls` per item on the ``n x n`` square-root form of the normal equations.

    With ``G = R^T R`` (Cholesky of the column-scaled ``G``), ``|R x - R^{-T} c|^2`` equals the objective up
    to a constant; this is much smaller than the stacked rows (``n`` rows instead of about ``5 S^2``).
    """
    from scipy.linalg import cholesky, solve_triangular  # lazy: SciPy is optional (the dev extra)
    from scipy.optimize import nnls  # lazy: as above

    out = torch.zeros_like(rhs)
    for item in range(rhs.shape[0]):
        keep = free[item]
        g = gram[item][keep][:, keep].cpu().numpy()
        c = rhs[item][keep].cpu().numpy()
        d = 1.0 / np.sqrt(np.maximum(np.diag(g), 1e-300))
        root = cholesky(g * d[:, None] * d[None, :], lower=False)
        x, _ = nnls(root, solve_triangular(root, c * d, trans="T"), maxiter=50 * len(c) + 100)
        out[item, keep] = torch.from_numpy(x * d).to(out)
    return out


def _auto_uses_torch(n: int, device: torch.device) -> bool:
    return device.type != "cpu" or n <= _AUTO_TORCH_MAX_UNKNOWNS


def _solve(system: _System, method: str) -> torch.Tensor:
    """``(B', n)`` the NNLS solution of every probe, by the requested method."""
    n = system.rhs.shape[1]
    if method == "scipy" or (method == "auto" and not _auto_uses_torch(n, system.rhs.device)):
        return _nnls_scipy(system.gram, system.rhs, system.free)
    x, converged = _nnls_torch(system.gram, system.rhs, system.free, _MAX_PIVOTS)
    if not bool(converged.all()):  # rare: cycling of block pivoting on very ill-conditioned, large problems
        stuck = (~converged).nonzero().squeeze(1)
        x[stuck] = _nnls_scipy(system.gram[stuck], system.rhs[stuck], system.free[stuck])
    return x


def _prepare(
    mirror_ldr: torch.Tensor,
    diffuse_ldr: torch.Tensor,
    matte_ldr: torch.Tensor,
    *,
    gamma: float,
    threshold: float,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, float]:
    """Decode the three images and apply (1).

    Returns:
        ``enc, lin`` ``(3, B, 3, P)`` encoded and linear images (mirror, diffuse, matte; float64), the clipped
        directions ``(B, N)``, the lower bound ``L0`` ``(B, 3, N)``, and the encoded threshold used.
    """
    valid = mirror_ball_valid(mirror_ldr.shape[-1], device=mirror_ldr.device).flatten()  # (N,)
    images = torch.stack([mirror_ldr, diffuse_ldr, matte_ldr]).flatten(3)
    enc = images.to(torch.float64) / 255.0 if images.dtype == torch.uint8 else images.to(torch.float64)
    lin = gamma_decode(enc, gamma)
    thr_enc = threshold - 0.5 / 255.0  # the threshold's own code counts, whatever the float rounding
    thr_lin = float(gamma_decode(torch.tensor(threshold, dtype=torch.float64), gamma))
    clipped_c = (enc[0] >= thr_enc) & valid  # (B, 3, N)
    base = torch.where(clipped_c, thr_lin, lin[0]) * valid / MIRROR_REFLECTIVITY  # (1): L0
    return enc, lin, clipped_c.any(1), base, thr_enc


def _promote(
    mirror_ldr: torch.Tensor,
    diffuse_ldr: torch.Tensor,
    matte_ldr: torch.Tensor,
    *,
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
    enc, lin, clipped, base, thr_enc = _prepare(
        mirror_ldr, diffuse_ldr, matte_ldr, gamma=gamma, threshold=clip_threshold
    )
    residual = torch.zeros_like(base)
    solved = clipped.any(1)
    todo = solved.nonzero().squeeze(1)
    todo = todo[torch.argsort(clipped[todo].sum(1), stable=True)]  # similar sizes share a chunk: less padding
    for idx in todo.split(_CHUNK) if todo.numel() else ():
        system = _build_system(
            fields,
            enc[:, idx],
            lin=lin[:, idx],
            base=base[idx],
            clipped=clipped[idx],
            thr_enc=thr_enc,
            lam=lam,
            balance=balance,
        )
        k_max = system.order.shape[1]
        u = _solve(system, method).view(-1, 3, k_max)  # U >= 0, 0 where not free
        res = torch.zeros(idx.numel(), 3, base.shape[-1], dtype=base.dtype, device=device)
        residual[idx] = res.scatter_add_(2, system.order[:, None, :].expand(-1, 3, -1), u)
    shape = (bsz, 3, s, s)
    return PromotionResult(
        lighting=(base + residual).view(shape).to(out_dtype),
        clipped=clipped.view(bsz, s, s),
        residual=residual.view(shape).to(out_dtype),
        solved=solved,
    )


@functools.lru_cache(maxsize=8)
def _fields(size: int, device: torch.device) -> torch.Tensor:
    """The solve's sphere fields ``(2, S^2, S^2)`` float64, stacked once per size and device (read-only)."""
    return torch.stack(
        [
            shared_sphere_field(k, size, lighting_size=size, device=device, dtype=torch.float64)
            for k in _SOLVE_SPHERES
        ]
    )


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
            probe on the CPU) or ``"auto"`` (the faster for the problem's size, as measured by
            ``benchmarks/bench_promotion.py``; see the module docstring).
        balance: the colour ``w`` of the regulariser: ``"residual"``, the diffuse ball's light that the
            unclipped mirror does not explain (the colour of the missing energy), or ``"diffuse"``, the
            whole diffuse ball.

    Returns:
        :class:`PromotionResult` with the linear HDR ``lighting`` (never negative, 0 off the ball), the
        ``clipped`` directions, the solved ``residual`` and the per-probe ``solved`` flag. The tensors are in
        the inputs' float dtype (float32 for ``uint8``) and on their device; everything is computed in
        float64 (a half-precision result can overflow where a sun is brighter than 65504).

    Raises:
        TypeCheckError: an input is no tensor, not uint8/float, or dtypes differ; a parameter is no number.
        ShapeError: wrong or mismatched shapes, or ``S`` not in :data:`~kornia_ilum.render.SPHERE_SIZES`.
        ValueCheckError: values outside ``[0, 1]``, devices differ, or a bad ``lam``/``gamma``/
            ``clip_threshold``/``method``/``balance``.
        NonFiniteError: NaN or Inf in an input.

    Shape:
        - mirror_ldr, diffuse_ldr, matte_ldr: :math:`(B, 3, S, S)`
        - lighting, residual: :math:`(B, 3, S, S)`; clipped: :math:`(B, S, S)`; solved: :math:`(B,)`

    Convention:
        docs/conventions.rst, "Reference spheres": the reference spheres (diffuse albedo 0.8, matte silver
        GGX 0.3, mirror 0.827) seen orthographically along -Z in the mirror-ball grid, which is also the
        lighting's grid (mirror pixel ``(i, j)`` reflects lighting direction ``(i, j)``); lighting in the
        units of the linear photograph.

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
    _check_args(
        mirror_ldr,
        diffuse_ldr,
        matte_ldr,
        lam=lam,
        gamma=gamma,
        clip_threshold=clip_threshold,
        method=method,
        balance=balance,
    )
    fields = _fields(mirror_ldr.shape[-1], mirror_ldr.device)
    return _promote(
        mirror_ldr,
        diffuse_ldr,
        matte_ldr,
        fields=fields,
        lam=float(lam),
        gamma=float(gamma),
        clip_threshold=float(clip_threshold),
        method=method,
        balance=balance,
    )


class PromoteSpheres(nn.Module):
    r"""Module twin of :func:`promote_spheres`; the two reflectance fields are non-persistent buffers.

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
        *,
        lam: float = 0.5,
        gamma: float = 2.2,
        clip_threshold: float = CLIP_THRESHOLD,
        method: Method = "auto",
        balance: Balance = "residual",
    ) -> None:
        super().__init__()
        check_positive_int(size, "size", allowed=SPHERE_SIZES)
        _check_params(lam=lam, gamma=gamma, clip_threshold=clip_threshold, method=method, balance=balance)
        self.size, self.lam, self.gamma, self.clip_threshold = (
            size,
            float(lam),
            float(gamma),
            float(clip_threshold),
        )
        self.method, self.balance = method, balance
        self.register_buffer("fields", _fields(size, torch.device("cpu")).clone(), persistent=False)

    def forward(
        self, mirror_ldr: torch.Tensor, diffuse_ldr: torch.Tensor, matte_ldr: torch.Tensor
    ) -> PromotionResult:
        params = {
            "lam": self.lam,
            "gamma": self.gamma,
            "clip_threshold": self.clip_threshold,
            "method": self.method,
            "balance": self.balance,
        }
        _check_args(mirror_ldr, diffuse_ldr, matte_ldr, **params, size=self.size)
        fields = self.fields.to(device=mirror_ldr.device, dtype=torch.float64)
        return _promote(mirror_ldr, diffuse_ldr, matte_ldr, fields=fields, **params)

    def extra_repr(self) -> str:
        return (
            f"size={self.size}, lam={self.lam}, gamma={self.gamma}, "
            f"clip_threshold={self.clip_threshold:.6g}, method={self.method!r}, balance={self.balance!r}"
        )
