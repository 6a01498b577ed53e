r"""Numerical stress of the public ops: every op on lighting across eight orders of magnitude and three dtypes.

Lighting spans about eight orders of magnitude (a night sky near 1e-3, a sun near 1e5), and float16 tops out
at 65504. :func:`stress_ops` runs each op of :data:`OPS` on each case of :func:`lighting_cases` in float32,
bfloat16 and float16, backpropagates the sum of its outputs, and sorts what happened into one of:

- ``"ok"``: outputs and gradients finite;
- ``"typed error"``: the op refused with one of the library's typed errors (a subclass of Kornia's
  ``BaseError``: :class:`~kornia_ilum.core.errors.NonFiniteError`, ``ValueCheckError``, ...), which is
  the documented answer where a dtype cannot hold the value;
- ``"garbage"``: NaN or Inf in an output or a gradient without an error (a failure);
- ``"untyped error"``: any other exception, such as a ``RuntimeError`` from deep inside torch (a failure).

:func:`stress_meta` runs the same ops on ``meta`` tensors (a shape-only pass): each must give its output's
shape or a typed error. The test suite runs both (``tests/bench/test_stress.py``);
``python benchmarks/bench_stress.py`` prints the table of every input and its outcome.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import torch
from kornia.core.exceptions import BaseError

from kornia_ilum.color import gamma_encode, linear_to_srgb, normalize_exposure, srgb_to_linear
from kornia_ilum.estimators import OursEstimator
from kornia_ilum.filters import blur_pool2d, soft_clip
from kornia_ilum.geometry import (
    latlong_to_mirror_ball,
    mirror_ball_to_latlong,
    mirror_ball_valid,
    resize_mirror_ball,
    rotate_lighting,
)
from kornia_ilum.metrics import reconstruction_loss, relative_radiance, total_radiance
from kornia_ilum.render import render_spheres
from kornia_ilum.sh import sh_project, sh_reconstruct

__all__ = ["DTYPES", "FAILURES", "OPS", "StressRow", "format_stress", "lighting_cases", "stress_meta",
           "stress_ops"]

DTYPES = (torch.float32, torch.bfloat16, torch.float16)
#: The outcomes that are failures.
FAILURES = ("garbage", "untyped error")
#: The radiance levels of the cases: a night sky to beyond a sun.
LEVELS = (1e-6, 1e-3, 1.0, 1e3, 1e5, 1e6)
#: The log radiance that the estimator's head is made to output (``exp(y)`` is the lighting).
LOG_LEVELS = (-20.0, -5.0, 0.0, 5.0, 11.0, 20.0)


def _rotation() -> torch.Tensor:
    """Yaw 37 degrees about +Y, then pitch 21 degrees about +X: no symmetry of the grids helps."""
    a, b = math.radians(37.0), math.radians(21.0)
    yaw = torch.tensor([[math.cos(a), 0.0, math.sin(a)], [0.0, 1.0, 0.0], [-math.sin(a), 0.0, math.cos(a)]])
    pitch = torch.tensor([[1.0, 0.0, 0.0], [0.0, math.cos(b), -math.sin(b)], [0.0, math.sin(b), math.cos(b)]])
    return pitch @ yaw


def _ours_head(y: torch.Tensor) -> torch.Tensor:
    """``ours``'s output stage for a head that outputs log radiance ``y`` everywhere (weights zeroed)."""
    est = OursEstimator(normalize_exposure=False).eval()
    with torch.no_grad():
        est.head.weight.zero_()
        est.head.bias.fill_(float(y.float().mean()) if not y.is_meta else 0.0)
    est = est.to(device=y.device, dtype=y.dtype)
    crops = torch.full((1, 3, 256, 256), 0.5, dtype=y.dtype, device=y.device)
    return est(crops).mirror_ball


#: name -> (what the op takes: "mirror_ball", "latlong" or "log", the op on that input).
OPS: dict[str, tuple[str, Callable[[torch.Tensor], torch.Tensor | dict[str, torch.Tensor]]]] = {
    "latlong_to_mirror_ball": ("latlong", lambda x: latlong_to_mirror_ball(x, 32)),
    "mirror_ball_to_latlong": ("mirror_ball", lambda x: mirror_ball_to_latlong(x, 32)),
    "resize_mirror_ball": ("mirror_ball", lambda x: resize_mirror_ball(x, 16)),
    "rotate_lighting": ("mirror_ball", lambda x: rotate_lighting(x, _rotation().to(x.device))),
    "render_spheres": ("mirror_ball", lambda x: render_spheres(x, 32)),
    "reconstruction_loss": ("mirror_ball", lambda x: reconstruction_loss(x, 0.5 * x, brdf="diffuse")),
    "total_radiance": ("mirror_ball", total_radiance),
    "relative_radiance": ("mirror_ball", lambda x: relative_radiance(0.5 * x, x)),
    "sh_project": ("mirror_ball", sh_project),
    "sh_reconstruct": ("mirror_ball", lambda x: sh_reconstruct(sh_project(x), 32)),
    "soft_clip": ("mirror_ball", soft_clip),
    "gamma_encode": ("mirror_ball", gamma_encode),
    "linear_to_srgb": ("mirror_ball", linear_to_srgb),
    "srgb_to_linear": ("mirror_ball", srgb_to_linear),
    "normalize_exposure": ("mirror_ball", lambda x: normalize_exposure(x)[0]),
    "blur_pool2d": ("mirror_ball", blur_pool2d),
    "ours output exp(y)": ("log", _ours_head),
}


def lighting_cases(kind: str, dtype: torch.dtype, device: str | torch.device = "cpu"
                   ) -> dict[str, torch.Tensor]:
    """The inputs of one op's kind in ``dtype``: name -> tensor (``(1, 3, 32, 32)`` mirror balls with 0 outside
    the ball, ``(1, 3, 32, 64)`` lat-long maps, or a ``(1,)`` log radiance for the estimator's head).

    The lighting cases are a uniform map at each of :data:`LEVELS`, a sun (one pixel at 1e6) over a dim sky
    (1e-3), and a map with a NaN pixel; values a dtype cannot hold are what the cast makes of them (Inf in
    float16 above 65504).

    Args:
        kind: ``"mirror_ball"``, ``"latlong"`` or ``"log"`` (the first element of an :data:`OPS` entry).
        dtype: the cases' dtype.
        device: the cases' device.

    Returns:
        case name -> tensor: ``"uniform 1e-06"`` ... ``"uniform 1e+06"``, ``"sun 1e6 over 1e-3"`` and
        ``"NaN pixel"``; ``"log -20"`` ... ``"log 20"`` for ``"log"``.

    Shape:
        - Output: :math:`(1, 3, 32, 32)` mirror balls, :math:`(1, 3, 32, 64)` lat-long maps, or :math:`(1,)`

    Convention:
        Linear lighting (docs/conventions.rst, "Mirror ball", "Lat-long" and "Units of lighting").

    Examples:
        >>> cases = lighting_cases("mirror_ball", torch.float16)
        >>> len(cases), tuple(cases["sun 1e6 over 1e-3"].shape)
        (8, (1, 3, 32, 32))
        >>> bool(cases["uniform 1e+06"].isinf().any()), bool(cases["uniform 1000"].isfinite().all())
        (True, True)
        >>> list(lighting_cases("log", torch.float32))[:2]
        ['log -20', 'log -5']
    """
    if kind == "log":
        return {f"log {y:g}": torch.tensor([y], dtype=dtype, device=device) for y in LOG_LEVELS}
    shape = (1, 3, 32, 32) if kind == "mirror_ball" else (1, 3, 32, 64)
    valid = mirror_ball_valid(32) if kind == "mirror_ball" else torch.ones(32, 64, dtype=torch.bool)  # on the CPU
    cases = {f"uniform {v:g}": torch.full(shape, v, dtype=torch.float64) for v in LEVELS}
    sun = torch.full(shape, 1e-3, dtype=torch.float64)
    sun[..., 10, 20] = 1e6
    cases["sun 1e6 over 1e-3"] = sun
    nan = torch.full(shape, 1.0, dtype=torch.float64)
    nan[..., 10, 20] = float("nan")
    cases["NaN pixel"] = nan
    return {k: torch.where(valid, v, 0.0).to(device=device, dtype=dtype) for k, v in cases.items()}


@dataclass(frozen=True)
class StressRow:
    """One op on one input: ``outcome`` is one of ``ok``, ``typed error``, ``garbage``, ``untyped error``.

    Args:
        op: the op's name (a key of :data:`OPS`).
        dtype: the input's dtype without ``torch.`` (``"meta"`` for :func:`stress_meta`).
        case: the input's name (:func:`lighting_cases`).
        outcome: what happened.
        detail: the error, or the largest output, or the output shapes.

    Examples:
        >>> row = StressRow("soft_clip", "float16", "NaN pixel", "garbage", "NaN or Inf in an output")
        >>> row.failed, StressRow("soft_clip", "float32", "uniform 1", "ok").failed
        (True, False)
    """

    op: str
    dtype: str
    case: str
    outcome: str
    detail: str = ""

    @property
    def failed(self) -> bool:
        return self.outcome in FAILURES


def _tensors(out: torch.Tensor | dict[str, torch.Tensor]) -> list[torch.Tensor]:
    return list(out.values()) if isinstance(out, dict) else [out]


def _run(op: Callable, x: torch.Tensor) -> tuple[str, str]:
    x = x.detach().clone().requires_grad_(x.is_floating_point())
    try:
        outs = _tensors(op(x))
        total = sum(o.float().sum() for o in outs if o.is_floating_point())
        if isinstance(total, torch.Tensor) and total.requires_grad:
            total.backward()
    except BaseError as e:
        return "typed error", f"{type(e).__name__}: {e}"[:160]
    except Exception as e:  # noqa: BLE001 - what the stress test exists to find
        return "untyped error", f"{type(e).__name__}: {e}"[:160]
    bad = [o for o in outs if o.is_floating_point() and not torch.isfinite(o).all()]
    if bad:
        return "garbage", "NaN or Inf in an output"
    if x.grad is not None and not torch.isfinite(x.grad).all():
        return "garbage", "NaN or Inf in the gradient"
    peak = max(float(o.detach().float().abs().max()) for o in outs if o.is_floating_point())
    return "ok", f"max |output| {peak:.3g}"


def stress_ops(ops: dict[str, tuple[str, Callable]] | None = None,
               dtypes: tuple[torch.dtype, ...] = DTYPES) -> list[StressRow]:
    """Every op of ``ops`` (default :data:`OPS`) on every case of :func:`lighting_cases` in every dtype.

    Each runs on a copy of the case that requires gradients, and the sum of its floating-point outputs is
    backpropagated; the outcomes are those of the module docstring.

    Args:
        ops: name -> (input kind, op), as :data:`OPS`.
        dtypes: the dtypes of the inputs.

    Returns:
        one row per op, dtype and case, in that order.

    Examples:
        >>> rows = stress_ops({"soft_clip": OPS["soft_clip"]}, (torch.float32,))
        >>> len(rows), [r.case for r in rows if r.failed]
        (8, [])
    """
    rows = []
    for name, (kind, op) in (OPS if ops is None else ops).items():
        for dtype in dtypes:
            for case, x in lighting_cases(kind, dtype).items():
                outcome, detail = _run(op, x)
                rows.append(StressRow(name, str(dtype).removeprefix("torch."), case, outcome, detail))
    return rows


def stress_meta(ops: dict[str, tuple[str, Callable]] | None = None) -> list[StressRow]:
    """Every op on ``meta`` tensors (float32): its output's shape, or a typed error.

    Args:
        ops: name -> (input kind, op), as :data:`OPS` (the default).

    Returns:
        one row per op, of dtype ``"meta"`` and case ``"uniform 1"`` (``"log 0"`` for the head).

    Examples:
        >>> row, = stress_meta({"gamma_encode": OPS["gamma_encode"]})
        >>> row.outcome, row.detail
        ('ok', 'shapes [(1, 3, 32, 32)]')
    """
    rows = []
    for name, (kind, op) in (OPS if ops is None else ops).items():
        x = lighting_cases(kind, torch.float32)["uniform 1" if kind != "log" else "log 0"].to("meta")
        try:
            shapes = [tuple(o.shape) for o in _tensors(op(x))]
            outcome, detail = "ok", f"shapes {shapes}"
        except BaseError as e:
            outcome, detail = "typed error", f"{type(e).__name__}: {e}"[:160]
        except Exception as e:  # noqa: BLE001 - what the stress test exists to find
            outcome, detail = "untyped error", f"{type(e).__name__}: {e}"[:160]
        rows.append(StressRow(name, "meta", "uniform 1" if kind != "log" else "log 0", outcome, detail))
    return rows


def format_stress(rows: list[StressRow]) -> str:
    """The rows as a Markdown table, failures first, and a count per outcome.

    Args:
        rows: the rows of :func:`stress_ops` or :func:`stress_meta`.

    Returns:
        the table (a ``|`` in a detail becomes ``/``), then a line with the number of runs and the count of each
        outcome.

    Examples:
        >>> rows = [StressRow("soft_clip", "float32", "uniform 1", "ok", "max |output| 0.5"),
        ...         StressRow("soft_clip", "float16", "NaN pixel", "garbage", "NaN or Inf in an output")]
        >>> print(format_stress(rows))
        | op | dtype | input | outcome | detail |
        |---|---|---|---|---|
        | soft_clip | float16 | NaN pixel | garbage | NaN or Inf in an output |
        | soft_clip | float32 | uniform 1 | ok | max /output/ 0.5 |
        <BLANKLINE>
        2 runs; garbage: 1, ok: 1
        <BLANKLINE>
    """
    counts: dict[str, int] = {}
    for r in rows:
        counts[r.outcome] = counts.get(r.outcome, 0) + 1
    lines = ["| op | dtype | input | outcome | detail |", "|---|---|---|---|---|"]
    for r in sorted(rows, key=lambda r: (not r.failed, r.op, r.dtype)):
        lines.append(f"| {r.op} | {r.dtype} | {r.case} | {r.outcome} | {r.detail.replace('|', '/')} |")
    summary = ", ".join(f"{k}: {v}" for k, v in sorted(counts.items()))
    return "\n".join(lines) + f"\n\n{len(rows)} runs; {summary}\n"
