r"""A lazy :func:`torch.compiler.disable`: keeps ``import kornia_ilum`` free of Dynamo.

``torch.compiler.disable`` imports ``torch._dynamo`` (and with it Inductor, SymPy and the distributed package,
and a ``torchinductor_<user>`` folder in ``TMPDIR``) the moment it decorates a function.
:func:`compiler_disable` defers that work to the first call made while Dynamo is loaded. Until Dynamo is
imported nothing can be compiling, so the function is called directly; once it is imported, calls go through
``torch.compiler.disable(fn)`` (built once), which runs ``fn`` with Dynamo's frame hook off. While Dynamo
traces, it sees the wrapper marked the way ``torch.compiler.disable`` marks its own wrappers
(``_torchdynamo_disable``), so it does not inline it and calls it eagerly instead, as with the plain
decorator.
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from typing import Any, TypeVar

import torch

__all__ = ["compiler_disable"]

_F = TypeVar("_F", bound=Callable[..., Any])


def compiler_disable(fn: _F) -> _F:
    r"""Decorator: ``torch.compiler.disable(fn)``, applied on the first call made with Dynamo loaded.

    The wrapper keeps ``fn``'s name and docstring (``functools.wraps``), and an ``lru_cache``'s
    ``cache_info`` and ``cache_clear``.

    Args:
        fn: the function that Dynamo must not trace.

    Returns:
        a wrapper with ``fn``'s signature: ``fn`` itself is called until Dynamo is loaded,
        ``torch.compiler.disable(fn)`` afterwards.

    Examples:
        >>> @compiler_disable
        ... def table(n):
        ...     return torch.arange(n)
        >>> table(3)
        tensor([0, 1, 2])
    """
    disabled: list[Callable[..., Any]] = []

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        if "torch._dynamo" not in sys.modules:  # nothing can be tracing or running compiled code
            return fn(*args, **kwargs)
        if not disabled:
            disabled.append(torch.compiler.disable(fn))
            _skip_frames_of(wrapper)
        return disabled[0](*args, **kwargs)

    for name in ("cache_info", "cache_clear", "cache_parameters"):  # an lru_cache's methods stay reachable
        if hasattr(fn, name):
            setattr(wrapper, name, getattr(fn, name))
    # the markers Dynamo reads on torch.compiler.disable's own wrappers: never inline, call eagerly
    wrapper._torchdynamo_disable = True  # type: ignore[attr-defined]
    wrapper._torchdynamo_disable_msg = None  # type: ignore[attr-defined]
    wrapper._torchdynamo_disable_recursive = True  # type: ignore[attr-defined]
    wrapper._torchdynamo_orig_callable = fn  # type: ignore[attr-defined]
    return wrapper  # type: ignore[return-value]


def _skip_frames_of(wrapper: Callable[..., Any]) -> None:
    """Tell Dynamo never to convert the wrapper's own frame (called eagerly after the graph break).

    Without this, Dynamo would trace the wrapper's frame at run time (it sits between compiled code and
    the disabled function), once per distinct argument value. All wrappers share one code object.
    """
    try:
        from torch._dynamo.eval_frame import skip_code  # lazy: at module level it would load Dynamo
    except ImportError:  # pragma: no cover - a torch without it still works, with extra frame conversions
        return
    skip_code(wrapper.__code__)
