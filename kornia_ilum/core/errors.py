"""Typed errors of kornia_ilum.

Input-validation errors reuse Kornia's exception classes (:mod:`kornia.core.exceptions`), so that an
``except ValueError`` or ``except TypeError`` clause catches them, and code that already handles
Kornia's checks handles ours. Errors that Kornia has no class for derive from :class:`IlumError`.
"""

from __future__ import annotations

from kornia.core.exceptions import BaseError, ShapeError, TypeCheckError, ValueCheckError

__all__ = [
    "BaseError",
    "ShapeError",
    "TypeCheckError",
    "ValueCheckError",
    "NonFiniteError",
    "EmptyTensorError",
    "IlumError",
    "HDRIOError",
]


class IlumError(BaseError):
    """Base class of the errors that only kornia_ilum raises."""


class NonFiniteError(ValueCheckError):
    """A tensor argument holds NaN or Inf where finite values are required."""


class EmptyTensorError(ShapeError):
    """A tensor argument has a zero-sized dimension where data is required."""


class HDRIOError(IlumError, OSError):
    """An image file is missing, unreadable, corrupt, or cannot be written as asked.

    The message always names the path.
    """
