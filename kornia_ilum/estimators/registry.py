r"""Lighting estimators by name: discovery through entry points, runtime registration, creation.

After timm (``list_models`` / ``create_model``), xarray (entry-point plugins, merged lazily and cached,
broken plugins warn) and fsspec (a read-only :class:`~types.MappingProxyType` view, ``clobber``).

- **Plugins.** A package declares, in its ``pyproject.toml``::

      [project.entry-points."kornia_ilum.estimators"]
      uniform = "kornia_ilum_uniform:UniformEstimator"

  The built-in ``ours`` registers the same way, from kornia_ilum's own ``pyproject.toml``. Entry points
  are read with :func:`importlib.metadata.entry_points` on first use of the registry (never at import),
  loaded, checked and cached. A plugin that fails to import, is not a :class:`LightingEstimator`
  subclass with an :class:`EstimatorInfo`, or reuses a name from another distribution gives a
  :class:`RuntimeWarning` naming the entry point and its distribution and is skipped; the others load.
  For two distributions with one name, the first found on ``sys.path`` wins.
- **Runtime registration.** :func:`register_estimator` adds a class, or a ``"module:attr"`` string that
  is imported on first use. Runtime names take precedence over entry points.
- **Defaults.** :data:`DEFAULT_ESTIMATOR` is ``"ours"``, with the weights that ship inside kornia_ilum
  (trained by ``kornia-ilum train``; model card ``kornia_ilum/estimators/weights/MODEL_CARD.md``).
- **Weights.** ``create_estimator(name)`` (``pretrained=True``) calls
  :meth:`LightingEstimator.from_pretrained`: weight files are SHA-256-checked and read with safetensors.
  Estimators without trained parameters declare ``EstimatorInfo(needs_weights=False)`` and are built as
  they are; a registered name without shipped weights raises
  :class:`~kornia_ilum.core.errors.MissingWeightsError` that says so.
"""

from __future__ import annotations

import fnmatch
import importlib
import importlib.metadata
import threading
import warnings
from types import MappingProxyType
from typing import Any

from kornia_ilum.core.errors import MissingWeightsError, UnknownNameError, ValueCheckError
from kornia_ilum.estimators.base import EstimatorInfo, LightingEstimator
from kornia_ilum.estimators.runtime import RUNTIMES, with_runtime

__all__ = [
    "ENTRY_POINT_GROUP",
    "DEFAULT_ESTIMATOR",
    "list_estimators",
    "create_estimator",
    "register_estimator",
    "estimator_info",
    "estimator_registry",
]

#: The entry-point group that plugins (and the built-ins) declare estimators in.
ENTRY_POINT_GROUP = "kornia_ilum.estimators"
#: The estimator used when none is named: ``"ours"``, with its shipped weights.
DEFAULT_ESTIMATOR = "ours"


_lock = threading.RLock()
_plugins: dict[str, type[LightingEstimator]] | None = None  # from entry points; None until discovered
_runtime: dict[str, type[LightingEstimator] | str] = {}  # register_estimator; "module:attr" until imported
_classes: dict[str, type[LightingEstimator]] = {}  # the merged, resolved view (runtime over plugins)
_VIEW = MappingProxyType(_classes)


def _distribution(ep: Any) -> str:
    dist = getattr(ep, "dist", None)
    return getattr(dist, "name", None) or "an unknown distribution"


def _check_class(obj: Any, where: str) -> type[LightingEstimator]:
    """Return ``obj`` if it is a usable estimator class, else raise :class:`TypeError` naming ``where``."""
    if not (isinstance(obj, type) and issubclass(obj, LightingEstimator)):
        raise TypeError(f"{where} is {obj!r}, not a subclass of kornia_ilum.estimators.LightingEstimator")
    if not isinstance(getattr(obj, "info", None), EstimatorInfo):
        raise TypeError(f"{where} ({obj.__qualname__}) has no class attribute info of type EstimatorInfo")
    return obj


def _discover() -> dict[str, type[LightingEstimator]]:
    """Load every entry point of :data:`ENTRY_POINT_GROUP`; warn about and skip the broken ones."""
    found: dict[str, type[LightingEstimator]] = {}
    origin: dict[str, tuple[str, str]] = {}
    for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        dist = _distribution(ep)
        where = f"entry point '{ep.name} = {ep.value}' (group {ENTRY_POINT_GROUP}) of distribution '{dist}'"
        if ep.name in origin:
            if origin[ep.name] != (ep.value, dist):
                warnings.warn(
                    f"kornia_ilum: estimator name '{ep.name}' is declared twice: by {where} and by "
                    f"'{origin[ep.name][0]}' of distribution '{origin[ep.name][1]}'; keeping the latter "
                    "(first on sys.path). Uninstall one of the two distributions.",
                    RuntimeWarning,
                    stacklevel=2,
                )
            continue
        try:
            cls = _check_class(ep.load(), where)
        except Exception as e:  # a plugin must never break the import or the other plugins
            warnings.warn(
                f"kornia_ilum: skipping estimator plugin {where}: {type(e).__name__}: {e}",
                RuntimeWarning,
                stacklevel=2,
            )
            continue
        found[ep.name] = cls
        origin[ep.name] = (ep.value, dist)
    return found


def _rebuild() -> None:
    _classes.clear()
    _classes.update(_plugins or {})
    _classes.update({k: v for k, v in _runtime.items() if not isinstance(v, str)})
    for name, target in _runtime.items():  # a pending string hides a plugin of the same name
        if isinstance(target, str):
            _classes.pop(name, None)


def _ensure_discovered() -> None:
    global _plugins
    with _lock:
        if _plugins is None:
            _plugins = _discover()
            _rebuild()


def _names() -> list[str]:
    _ensure_discovered()
    with _lock:
        return sorted(set(_plugins or {}) | set(_runtime))


def _resolve(name: str) -> type[LightingEstimator]:
    """The class registered as ``name``; imports a pending ``"module:attr"`` registration."""
    _ensure_discovered()
    with _lock:
        target = _runtime.get(name, (_plugins or {}).get(name))
        if target is None:
            raise UnknownNameError(unknown_estimator_message(name))
        if isinstance(target, str):
            module, _, attr = target.partition(":")
            obj: Any = importlib.import_module(module)
            for part in attr.split("."):
                obj = getattr(obj, part)
            target = _check_class(obj, f"estimator {name!r} registered as {target!r}")
            _runtime[name] = target
            _rebuild()
        return target


def _pretrained_names() -> list[str]:
    """Names that ``create_estimator(name)`` with ``pretrained=True`` can build (for error messages).

    Installed as :func:`kornia_ilum.estimators.pretrained.pretrained_names`'s lookup below, so that
    :meth:`LightingEstimator.from_pretrained` can name them without importing this module.
    """
    ready = []
    for name in _names():
        try:
            if _resolve(name).info.pretrained_available:
                ready.append(name)
        except Exception:  # a broken runtime registration is reported when it is used, not here
            continue
    return ready


def unknown_estimator_message(name: str) -> str:
    """The message of the :class:`~kornia_ilum.core.errors.UnknownNameError` for an estimator ``name`` that no
    installed package registers: the registered names, and where estimators come from.

    Examples:
        >>> unknown_estimator_message("nope")  # doctest: +ELLIPSIS
        "unknown estimator 'nope'. Valid names: ...; an estimator plugin registers its estimators in the \
entry-point group 'kornia_ilum.estimators' (this repository's plugins/ holds some: pip install ./plugins/NAME)"
    """
    valid = ", ".join(_names()) or "none"
    return (f"unknown estimator {name!r}. Valid names: {valid}; an estimator plugin registers its estimators in "
            f"the entry-point group {ENTRY_POINT_GROUP!r} (this repository's plugins/ holds some: pip install "
            "./plugins/NAME)")


def missing_weights_message(name: str) -> str:
    """The message of the :class:`~kornia_ilum.core.errors.MissingWeightsError` for a registered estimator
    ``name`` that ships no trained weights: ``pretrained=False``, or the registered estimators that do."""
    ready = ", ".join(_pretrained_names()) or "none installed"
    return (f"{name!r} is registered but ships no trained weights yet; pass pretrained=False for an untrained model "
            f"or pick one of: {ready}")


def list_estimators(pattern: str = "*") -> list[str]:
    r"""Names of the registered estimators that match a shell-style pattern, sorted.

    Args:
        pattern: :func:`fnmatch.fnmatchcase` pattern, such as ``"*"`` or ``"u*"``.

    Returns:
        the sorted names: installed plugins, the built-ins and runtime registrations.

    Examples:
        >>> "ours" in list_estimators()
        True
        >>> list_estimators("ou*")
        ['ours']
    """
    return [n for n in _names() if fnmatch.fnmatchcase(n, pattern)]


def estimator_registry() -> MappingProxyType[str, type[LightingEstimator]]:
    r"""The registry as a read-only live mapping ``name -> estimator class`` (fsspec style).

    Pending ``"module:attr"`` registrations are imported first (an import failure raises).

    Returns:
        a :class:`types.MappingProxyType` of name -> :class:`~kornia_ilum.estimators.LightingEstimator`
        subclass; it follows later registrations and cannot be written to.

    Examples:
        >>> reg = estimator_registry()
        >>> reg["ours"].info.name
        'ours'
        >>> reg["x"] = None
        Traceback (most recent call last):
        ...
        TypeError: 'mappingproxy' object does not support item assignment
    """
    for name in _names():
        if isinstance(_runtime.get(name), str):
            _resolve(name)
    return _VIEW


def estimator_info(name: str) -> EstimatorInfo:
    r"""The metadata of a registered estimator (description, paper, input size, weight files).

    Args:
        name: a name from :func:`list_estimators`.

    Returns:
        the class attribute ``info`` (:class:`~kornia_ilum.estimators.EstimatorInfo`) of the estimator; nothing is
        built and no weights are read.

    Raises:
        UnknownNameError: unknown name (a ``ValueError``); the message lists the valid names.

    Examples:
        >>> estimator_info("ours").input_size
        256
    """
    return _resolve(name).info


def create_estimator(name: str, pretrained: bool = True, runtime: str = "eager", **kw: Any) -> LightingEstimator:
    r"""Build a registered estimator by name.

    Args:
        name: a name from :func:`list_estimators`.
        pretrained: load the estimator's pretrained weights through
            :meth:`~kornia_ilum.estimators.LightingEstimator.from_pretrained` (SHA-256 checked,
            safetensors). Estimators without trained parameters (``info.needs_weights == False``) are the
            same either way. ``False`` builds ``cls(**kw)`` untrained.
        runtime: what computes the estimate (:func:`~kornia_ilum.estimators.runtime.with_runtime`):
            ``"eager"`` (PyTorch, the default), ``"bf16"`` (bfloat16 autocast, where the CPU has it),
            ``"onnx"`` / ``"onnx-int8"`` (ONNX Runtime in float32 / int8, ``pip install kornia_ilum[onnx]``)
            or ``"auto"`` (the fastest of those that run here and pass their parity check, else eager).
        **kw: constructor arguments (and ``weights_dir`` with ``pretrained=True``).

    Returns:
        the estimator module (in ``eval()`` mode when pretrained).

    Raises:
        UnknownNameError: unknown name (a ``ValueError``); the message lists the valid names.
        ValueCheckError: unknown runtime, or one that cannot run here (the message says why).
        MissingWeightsError: ``pretrained=True`` for an estimator that ships no trained weights yet, or
            whose weight file is missing.
        WeightsChecksumError: a weight file fails its SHA-256 check.

    Examples:
        >>> net = create_estimator("ours", pretrained=False)
        >>> net.info.input_size
        256
    """
    cls = _resolve(name)
    if runtime not in RUNTIMES:  # before the weights are read
        raise ValueCheckError(f"runtime must be one of {', '.join(RUNTIMES)}, got {runtime!r}")
    if pretrained and cls.info.needs_weights and not cls.info.weights:
        raise MissingWeightsError(missing_weights_message(name))
    model = cls.from_pretrained(**kw) if pretrained else cls(**kw)
    return with_runtime(model, runtime)


def register_estimator(name: str, target: type[LightingEstimator] | str, clobber: bool = False) -> None:
    r"""Register an estimator class under a name, at runtime.

    Args:
        name: the registry name.
        target: a :class:`~kornia_ilum.estimators.LightingEstimator` subclass, or a ``"module:attr"``
            string imported on first use (as an entry point's value).
        clobber: replace an existing registration (runtime or entry point) of ``name``.

    Returns:
        None; :func:`create_estimator` and :func:`list_estimators` know ``name`` from now on, in this process.

    Raises:
        ValueCheckError: ``name`` is taken and ``clobber`` is ``False``, or ``target`` is a malformed string.
        TypeError: ``target`` is not an estimator class (with an :class:`EstimatorInfo`) nor a string.

    Examples:
        >>> from kornia_ilum.estimators import OursEstimator
        >>> register_estimator("ours_alias", OursEstimator)
        >>> "ours_alias" in list_estimators()
        True
        >>> register_estimator("ours_alias", OursEstimator)  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: estimator 'ours_alias' is already registered (OursEstimator); pass clobber=True ...
        >>> register_estimator("ours_alias", "kornia_ilum.estimators.ours:OursEstimator", clobber=True)
        >>> _reset()  # doctest cleanup: forget the runtime registrations
    """
    if not isinstance(name, str) or not name:
        raise ValueCheckError(f"name must be a non-empty string, got {name!r}")
    if isinstance(target, str):
        module, sep, attr = target.partition(":")
        if not (sep and module and attr):
            raise ValueCheckError(f"target must be a class or a 'module:attr' string, got {target!r}")
    else:
        target = _check_class(target, f"target for estimator {name!r}")
    _ensure_discovered()
    with _lock:
        current = _runtime.get(name, (_plugins or {}).get(name))
        if current is not None and not clobber:
            shown = current if isinstance(current, str) else current.__qualname__
            raise ValueCheckError(
                f"estimator {name!r} is already registered ({shown}); pass clobber=True to replace it"
            )
        _runtime[name] = target
        _rebuild()


def _reset(runtime: bool = True) -> None:
    """Forget discovered plugins (re-read on next use) and, with ``runtime``, runtime registrations."""
    global _plugins
    with _lock:
        _plugins = None
        if runtime:
            _runtime.clear()
        _rebuild()
