r"""Face detectors by name, in timm's style: :func:`list_detectors`, :func:`create_detector`,
:func:`register_detector`, :func:`describe_detector`.

A registered entry is a factory (usually a :class:`~kornia_ilum.detection.FaceDetector` subclass) that
:func:`create_detector` calls with the keyword arguments it is given. Built-ins: ``"yunet"`` (the
default), ``"opencv"`` and ``"none"``. :data:`DETECTORS` is a read-only view of the registry.
"""

from __future__ import annotations

import fnmatch
from collections.abc import Callable
from types import MappingProxyType
from typing import Any, Literal

from kornia_ilum.core.check import check_positive_int
from kornia_ilum.core.errors import TypeCheckError, UnknownNameError, ValueCheckError
from kornia_ilum.detection.detectors import (
    FaceDetector,
    NoFaceDetector,
    OpenCVFaceDetector,
    YuNetFaceDetector,
)

__all__ = [
    "DEFAULT_DETECTOR",
    "DETECTORS",
    "list_detectors",
    "create_detector",
    "register_detector",
    "describe_detector",
]

#: The detector :func:`kornia_ilum.estimate_lighting`, the CLI and the video tracker use unless told otherwise:
#: YuNet, with its packaged weights, chosen by measurement over Haar (docs/bench.rst, "The default detector").
DEFAULT_DETECTOR = "yunet"

_REGISTRY: dict[str, Callable[..., FaceDetector]] = {
    cls.name: cls for cls in (OpenCVFaceDetector, YuNetFaceDetector, NoFaceDetector)
}
#: Read-only view of the registry: name -> factory.
DETECTORS = MappingProxyType(_REGISTRY)


def _factory(name: str) -> Callable[..., FaceDetector]:
    if not isinstance(name, str):
        raise TypeCheckError(f"detector name must be a str, got {type(name).__name__}")
    try:
        return _REGISTRY[name]
    except KeyError:
        raise UnknownNameError(
            f"unknown detector {name!r}; registered detectors: {', '.join(list_detectors())}"
        ) from None


def list_detectors(pattern: str = "*") -> list[str]:
    """The registered detector names matching a shell-style ``pattern``, sorted.

    Args:
        pattern: a :mod:`fnmatch` pattern (``*``, ``?``, ``[...]``), matched case-sensitively.

    Returns:
        the matching names, sorted; empty when none matches.

    Examples:
        >>> list_detectors()
        ['none', 'opencv', 'yunet']
        >>> list_detectors("o*")
        ['opencv']
    """
    return sorted(n for n in _REGISTRY if fnmatch.fnmatchcase(n, pattern))


def create_detector(name: str = DEFAULT_DETECTOR, *, max_side: int | None | Literal["auto"] = "auto",
                    **kwargs: Any) -> FaceDetector:
    """Build the detector registered as ``name`` with ``kwargs`` (e.g. ``confidence_threshold=`` for ``"yunet"``).

    ``max_side`` makes it detect on a copy whose longer side is at most that many pixels
    (:attr:`FaceDetector.max_side <kornia_ilum.detection.FaceDetector>`): faster, but blind to faces smaller than
    its window at that scale. By default (``"auto"``) a detector detects at its own
    :attr:`~kornia_ilum.detection.FaceDetector.default_max_side`: 240 for ``"yunet"``, full size for the others.

    Args:
        name: a registered detector name (:func:`list_detectors`).
        max_side: the longest side, in pixels, of the copy the detector sees; ``None`` detects at full size;
            ``"auto"``: the detector's ``default_max_side``.
        kwargs: passed to the registered factory.

    Returns:
        the detector, a :class:`~kornia_ilum.detection.FaceDetector` with ``max_side`` set.

    Raises:
        UnknownNameError: ``name`` is not registered (a ``ValueError``); the message lists the registered names.
        TypeCheckError: the factory did not return a :class:`~kornia_ilum.detection.FaceDetector`.
        MissingWeightsError: ``"yunet"`` found no local weights (the message says where it looked).

    Examples:
        >>> create_detector("none")
        NoFaceDetector()
        >>> create_detector("haar")
        Traceback (most recent call last):
        ...
        kornia_ilum.core.errors.UnknownNameError: unknown detector 'haar'; registered detectors: none, opencv, yunet
    """
    if max_side is not None and max_side != "auto":
        check_positive_int(max_side, "max_side")
    detector = _factory(name)(**kwargs)
    if not isinstance(detector, FaceDetector):
        raise TypeCheckError(f"detector {name!r} must build a FaceDetector, got {type(detector).__name__}")
    detector.max_side = detector.default_max_side if max_side == "auto" else max_side
    return detector


def register_detector(
    name: str, factory: Callable[..., FaceDetector], clobber: bool = False
) -> Callable[..., FaceDetector]:
    """Register ``factory`` (a :class:`~kornia_ilum.detection.FaceDetector` subclass or a function returning
    one) under ``name``, for this process.

    Args:
        name: the name :func:`create_detector` and the CLI's ``--detector`` will know it by.
        factory: called with :func:`create_detector`'s keyword arguments; must return a
            :class:`~kornia_ilum.detection.FaceDetector`.
        clobber: replace an entry registered under ``name`` already.

    Returns:
        ``factory``, unchanged.

    Raises:
        TypeCheckError: ``name`` is not a non-empty str or ``factory`` is not callable.
        ValueCheckError: ``name`` is registered already and ``clobber`` is False.

    Examples:
        >>> class Centre(NoFaceDetector):
        ...     description = "the whole image"
        >>> _ = register_detector("centre", Centre)
        >>> "centre" in list_detectors(), describe_detector("centre")
        (True, 'the whole image')
        >>> _ = register_detector("centre", Centre)
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: detector 'centre' is already registered; pass clobber=True to replace it
        >>> del _REGISTRY["centre"]  # tidy up the doctest
    """
    if not isinstance(name, str) or not name:
        raise TypeCheckError(f"detector name must be a non-empty str, got {name!r}")
    if not callable(factory):
        raise TypeCheckError(
            f"factory must be callable (a FaceDetector subclass), got {type(factory).__name__}"
        )
    if name in _REGISTRY and not clobber:
        raise ValueCheckError(f"detector {name!r} is already registered; pass clobber=True to replace it")
    _REGISTRY[name] = factory
    return factory


def describe_detector(name: str) -> str:
    """One line about the detector registered as ``name``, without building it (for ``kornia-ilum list``).

    The factory's ``description`` attribute, else the first line of its docstring.

    Args:
        name: a registered detector name (:func:`list_detectors`).

    Returns:
        the description, one line; empty when the factory has neither.

    Raises:
        UnknownNameError: ``name`` is not registered (a ``ValueError``); the message lists the registered names.

    Examples:
        >>> describe_detector("none")
        'no detection: each input already is a face crop (one box, the whole image)'
    """
    factory = _factory(name)
    text = getattr(factory, "description", "") or (factory.__doc__ or "").strip().split("\n")[0]
    return str(text)
