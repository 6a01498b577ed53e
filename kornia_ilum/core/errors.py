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
    "UnknownNameError",
    "MissingWeightsError",
    "WeightsChecksumError",
    "NoFaceError",
]


class IlumError(BaseError):
    """Base class of the errors that only kornia_ilum raises.

    Examples:
        >>> issubclass(HDRIOError, IlumError), issubclass(IlumError, BaseError)
        (True, True)
    """


class NonFiniteError(ValueCheckError):
    """A tensor argument holds NaN or Inf where finite values are required.

    Examples:
        >>> try:
        ...     raise NonFiniteError("x must be finite, but it holds NaN or Inf")
        ... except ValueError as e:  # a ValueCheckError, so a ValueError
        ...     print(type(e).__name__)
        NonFiniteError
    """


class EmptyTensorError(ShapeError):
    """A tensor argument has a zero-sized dimension where data is required.

    Examples:
        >>> issubclass(EmptyTensorError, ShapeError)
        True
    """


class HDRIOError(IlumError, OSError):
    """An image file is missing, unreadable, corrupt, or cannot be written as asked.

    The message always names the path.

    Examples:
        >>> try:
        ...     raise HDRIOError("cannot read missing.exr: no such file")
        ... except OSError as e:  # also an OSError
        ...     print(e)
        cannot read missing.exr: no such file
    """


class TruncatedImageError(HDRIOError):
    """An image file ends before its data does (an interrupted download, copy or write).

    Raised instead of returning a partly decoded image. The message says the file is truncated and names
    the path.

    Examples:
        >>> issubclass(TruncatedImageError, HDRIOError), issubclass(TruncatedImageError, OSError)
        (True, True)
    """


class UnknownNameError(IlumError, ValueError):
    """A name that no registry holds (an estimator, a detector, a training recipe); the message lists the
    registered names. A :class:`ValueError`, as an unknown value is.

    Examples:
        >>> raise UnknownNameError("unknown estimator 'x'. Valid names: ours")
        Traceback (most recent call last):
        ...
        kornia_ilum.core.errors.UnknownNameError: unknown estimator 'x'. Valid names: ours
    """


class MissingWeightsError(IlumError):
    """An estimator's or a detector's pretrained weights are not available.

    Either the estimator ships no trained weights yet (``pretrained=False`` gives the untrained model), or
    one of its weight files is missing from the weights folder. The message names the estimator, and the
    file and folder where one is missing.

    Examples:
        >>> issubclass(MissingWeightsError, IlumError), issubclass(MissingWeightsError, OSError)
        (True, False)
    """


class WeightsChecksumError(IlumError):
    """A weight file's SHA-256 digest differs from the one its estimator declares.

    The file is corrupt, truncated, or from another release; it is never loaded. The message names the
    file and both digests.

    Examples:
        >>> issubclass(WeightsChecksumError, IlumError)
        True
    """


class NoFaceError(IlumError):
    """No face was found in an image where the estimate needs one.

    The message names the image and the detector, and says how to proceed (another detector, a crop with
    ``detector="none"``, or ``fallback="full_image"``).

    Examples:
        >>> try:
        ...     raise NoFaceError("no face in photo.jpg (detector 'mediapipe')")
        ... except IlumError as e:
        ...     print(type(e).__name__)
        NoFaceError
    """
