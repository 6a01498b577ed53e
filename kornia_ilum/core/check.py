"""Input checks for every public entry point.

One function, :func:`check_tensor`, validates a tensor argument and raises a typed error whose
message names the argument and the expected shape. It honours Kornia's global switch
(:func:`kornia.core.check.disable_checks` or ``KORNIA_CHECKS=0``), and it skips the value checks
(NaN/Inf) while :func:`torch.compile` traces, so that compiled graphs stay free of host syncs.
"""

from __future__ import annotations

import contextlib
import contextvars
import math
from collections.abc import Iterator, Sequence
from typing import Any

import torch
from kornia.core.check import are_checks_enabled

from kornia_ilum.core.errors import (
    EmptyTensorError,
    NonFiniteError,
    ShapeError,
    TypeCheckError,
    ValueCheckError,
)

__all__ = [
    "check_choice",
    "check_positive_int",
    "check_same_device",
    "check_tensor",
    "checks_active",
    "trusted",
    "value_range",
]

_TRUSTED: contextvars.ContextVar[bool] = contextvars.ContextVar("kornia_ilum_trusted", default=False)


def checks_active() -> bool:
    """Whether input checks run now: Kornia's global switch, not while tracing, not inside :func:`trusted`.

    Returns:
        ``True`` when :func:`check_tensor` and the other checks validate their arguments now.

    Examples:
        >>> checks_active()
        True
        >>> with trusted():
        ...     checks_active()
        False
    """
    if not are_checks_enabled() or torch.jit.is_scripting():
        return False
    return torch.compiler.is_compiling() or not _TRUSTED.get()  # Dynamo cannot trace a ContextVar


@contextlib.contextmanager
def trusted() -> Iterator[None]:
    """Skip the input checks inside the block, in this thread (or asyncio task) only.

    For pipelines that validate their inputs once where they enter and then call public functions many
    times on data they made themselves (:class:`~kornia_ilum_lab.synth.lightstage.PortraitDataset`): a check scans
    every value of a tensor, which is a large part of the cost of cheap operations on large images. Code that
    :func:`torch.compile` traces ignores it (compiled checks never scan values).

    Returns:
        a context manager; the checks run again when its block ends.

    Examples:
        >>> with trusted():
        ...     check_tensor(torch.tensor([float("nan")]), "x")  # not checked
        >>> checks_active()
        True
    """
    token = _TRUSTED.set(True)
    try:
        yield
    finally:
        _TRUSTED.reset(token)


def _fmt(shape: Sequence[str]) -> str:
    return "(" + ", ".join(shape) + ")"


def check_tensor(
    x: Any,
    name: str,
    shape: Sequence[str] | None = None,
    *,
    floating: bool = True,
    finite: bool = True,
    nonempty: bool = True,
    nonnegative: bool = False,
) -> None:
    """Validate a tensor argument.

    Args:
        x: the value to check.
        name: the argument's name, used in the message.
        shape: expected shape as a list of dimension names. A name that is a number must match exactly,
            a leading ``"*"`` accepts any number of leading dimensions, ``"3|1"`` accepts either size, and a
            name used twice (``"S", "S"``) requires equal sizes.
        floating: require a floating-point dtype.
        finite: require every value to be finite (skipped while compiling, and for a ``meta`` tensor, which
            has no values).
        nonempty: require no zero-sized dimension.
        nonnegative: require every value to be ``>= 0`` (skipped while compiling and for ``meta``).

    Returns:
        ``None``; the checks raise on a bad argument.

    Raises:
        TypeCheckError: ``x`` is no tensor, or has the wrong dtype.
        ShapeError: ``x`` has the wrong number of dimensions or a wrong fixed size.
        EmptyTensorError: ``x`` has a zero-sized dimension.
        NonFiniteError: ``x`` holds NaN or Inf.
        ValueCheckError: ``x`` holds negative values where they are not allowed.

    Examples:
        >>> check_tensor(torch.zeros(2, 9, 3), "sh", ["B", "9", "3"])
        >>> check_tensor(torch.zeros(2, 8, 3), "sh", ["B", "9", "3"])
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ShapeError: sh must have shape (B, 9, 3), got (2, 8, 3)
        >>> check_tensor(torch.zeros(4, 2), "x", ["S", "S"])  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ShapeError: x must have shape (S, S), got (4, 2) (its two S sizes differ: ...)
    """
    if not checks_active():
        return
    if not isinstance(x, torch.Tensor):
        want = f" of shape {_fmt(shape)}" if shape is not None else ""
        raise TypeCheckError(f"{name} must be a torch.Tensor{want}, got {type(x).__name__}")
    got = tuple(int(d) if isinstance(d, torch.Tensor) else d for d in x.shape)  # jit.trace: 0-d tensors
    if shape is not None:
        dims = list(shape)
        if dims and dims[0] == "*":
            dims = dims[1:]
            ok = x.dim() >= len(dims)
            tail = got[len(got) - len(dims) :] if dims else ()
        else:
            ok = x.dim() == len(dims)
            tail = got
        unequal = ""
        if ok:
            named: dict[str, int] = {}  # a name used twice ("S", "S") means one size
            for want_dim, have in zip(dims, tail):
                options = want_dim.split("|")
                if all(o.isdigit() for o in options) and have not in {int(o) for o in options}:
                    ok = False
                    break
                if not want_dim.isdigit() and named.setdefault(want_dim, have) != have:
                    ok, unequal = False, f" (its two {want_dim} sizes differ: it must be square)"
                    break
        if not ok:
            raise ShapeError(f"{name} must have shape {_fmt(shape)}, got {got}{unequal}")
    if floating and not x.is_floating_point():
        raise TypeCheckError(f"{name} must be a floating-point tensor, got dtype {x.dtype}")
    if nonempty and x.numel() == 0:
        expected = f" {_fmt(shape)}" if shape is not None else ""
        raise EmptyTensorError(
            f"{name} must not be empty, got shape {got} (expected{expected} with sizes > 0)"
        )
    if torch.compiler.is_compiling() or torch.jit.is_tracing():  # a value scan would be baked into the graph
        return
    if not (finite or nonnegative) or not x.is_floating_point() or x.numel() == 0 or x.is_meta:
        return  # a meta tensor has a shape and no values: a shape-only pass checks what it can
    lo, hi = torch.aminmax(x.detach())  # one pass over the data; NaN propagates into both
    lo, hi = float(lo), float(hi)
    if finite and not (math.isfinite(lo) and math.isfinite(hi)):
        raise NonFiniteError(f"{name} must be finite, but it holds NaN or Inf")
    if nonnegative and lo < 0:
        raise ValueCheckError(f"{name} must be non-negative (lighting is never negative), got min {lo:g}")


def value_range(x: torch.Tensor, name: str) -> tuple[float, float] | None:
    """The ``(min, max)`` of a floating-point tensor in one pass over it, which also finds NaN and Inf: for a
    caller that checks a range of its own (an image in ``[0, 1]``) without scanning the data twice.

    Args:
        x: the tensor to scan.
        name: the argument's name, used in the message.

    Returns:
        ``(min, max)`` as floats; ``None`` when checks are off (:func:`checks_active`), while compiling, or for
        an empty, integer or ``meta`` tensor.

    Raises:
        NonFiniteError: ``x`` holds NaN or Inf.

    Examples:
        >>> value_range(torch.tensor([0.25, 0.5, 1.0]), "image")
        (0.25, 1.0)
        >>> value_range(torch.tensor([0.5, float("nan")]), "image")
        Traceback (most recent call last):
        ...
        kornia_ilum.core.errors.NonFiniteError: image must be finite, but it holds NaN or Inf
    """
    if (not checks_active() or torch.compiler.is_compiling() or torch.jit.is_tracing() or not x.is_floating_point()
            or x.numel() == 0 or x.is_meta):
        return None
    lo, hi = (float(v) for v in torch.aminmax(x.detach()))  # one pass; NaN propagates into both
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise NonFiniteError(f"{name} must be finite, but it holds NaN or Inf")
    return lo, hi


def check_same_device(*named: tuple[str, torch.Tensor]) -> None:
    """Raise :class:`ValueCheckError` unless all tensors share one device.

    Args:
        named: ``(name, tensor)`` pairs; the names are used in the message.

    Returns:
        ``None``; fewer than two tensors, or checks off (:func:`checks_active`), check nothing.

    Raises:
        ValueCheckError: the tensors are on more than one device; the message names each one's.

    Examples:
        >>> check_same_device(("a", torch.zeros(1)), ("b", torch.ones(2)))
        >>> check_same_device(("a", torch.zeros(1)), ("b", torch.zeros(1, device="meta")))
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: tensors must be on one device, got a on cpu, b on meta
    """
    if not checks_active() or len(named) < 2:
        return
    devices = {t.device for _, t in named}
    if len(devices) > 1:
        desc = ", ".join(f"{n} on {t.device}" for n, t in named)
        raise ValueCheckError(f"tensors must be on one device, got {desc}")


def check_positive_int(value: Any, name: str, allowed: Sequence[int] | None = None) -> None:
    """Raise :class:`TypeCheckError` / :class:`ValueCheckError` unless ``value`` is a positive int.

    Args:
        value: the value to check.
        name: the argument's name, used in the message.
        allowed: if given, the values that are accepted.

    Returns:
        ``None``; it raises on a bad value.

    Raises:
        TypeCheckError: ``value`` is not an ``int`` (a ``bool`` is not one).
        ValueCheckError: ``value`` is not positive, or not in ``allowed``.

    Examples:
        >>> check_positive_int(8, "bits", allowed=range(1, 17))
        >>> check_positive_int(0, "bits")
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: bits must be positive, got 0
    """
    if isinstance(value, bool) or not isinstance(value, int):
        raise TypeCheckError(f"{name} must be an int, got {type(value).__name__}")
    if value <= 0:
        raise ValueCheckError(f"{name} must be positive, got {value}")
    if allowed is not None and value not in allowed:
        raise ValueCheckError(f"{name} must be one of {tuple(allowed)}, got {value}")


def check_choice(value: Any, name: str, choices: Sequence[str]) -> None:
    """Require ``value`` to be one of the strings ``choices`` (for ints: :func:`check_positive_int`).

    Args:
        value: the value to check.
        name: the argument's name, used in the message.
        choices: the accepted strings.

    Returns:
        ``None``; it raises on a bad value.

    Raises:
        ValueCheckError: ``value`` is not one of ``choices``; the message lists them.

    Examples:
        >>> check_choice("mean", "reduction", ("mean", "sum", "none"))
        >>> check_choice("avg", "reduction", ("mean", "sum", "none"))
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: reduction must be one of ('mean', 'sum', 'none'), got 'avg'
    """
    if not isinstance(value, str) or value not in tuple(choices):
        raise ValueCheckError(f"{name} must be one of {tuple(choices)}, got {value!r}")
