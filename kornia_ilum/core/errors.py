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
    "TruncatedImageError",
    "MissingWeightsError",
    "WeightsChecksumError",
    "NoFaceError",
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


class TruncatedImageError(HDRIOError):
    """An image file ends before its data does (an interrupted download, copy or write).

    Raised instead of returning a partly decoded image. The message says the file is truncated and names
    the path.
    """


class MissingWeightsError(IlumError):
    """An estimator's or a detector's pretrained weights are not available.

    Either the estimator ships no trained weights yet (``pretrained=False`` gives the untrained model), or
    one of its weight files is missing from the weights folder. The message names the estimator, and the
    file and folder where one is missing.
    """


class WeightsChecksumError(IlumError):
    """A weight file's SHA-256 digest differs from the one its estimator declares.

    The file is corrupt, truncated, or from another release; it is never loaded. The message names the
    file and both digests.
    """


class NoFaceError(IlumError):
    """No face was found in an image where the estimate needs one.

    The message names the image and the detector, and says how to proceed (another detector, a crop with
    ``detector="none"``, or ``fallback="full_image"``).
    """
