r"""Which registered estimators ship pretrained weights: the lookup below both the contract and the registry.

When an estimator ships no weights, :meth:`LightingEstimator.from_pretrained
<kornia_ilum.estimators.base.LightingEstimator.from_pretrained>` names those that do. The names are the
registry's, and the registry (:mod:`kornia_ilum.estimators.registry`) builds on the contract
(:mod:`kornia_ilum.estimators.base`), so the contract cannot import it. Instead both import this module,
which imports neither: the registry installs its lookup here when it is imported
(:func:`set_pretrained_lookup`), and the contract asks :func:`pretrained_names`.
"""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["pretrained_names", "set_pretrained_lookup"]

_lookup: Callable[[], list[str]] | None = None


def set_pretrained_lookup(lookup: Callable[[], list[str]]) -> None:
    r"""Install the function that lists the estimators buildable with ``pretrained=True`` (the registry's).

    Args:
        lookup: called with no arguments; returns the names, in the order they are shown.

    Returns:
        None; :func:`pretrained_names` calls ``lookup`` from now on.

    Examples:
        >>> import kornia_ilum.estimators
        >>> from kornia_ilum.estimators import pretrained
        >>> registry_lookup = pretrained._lookup
        >>> set_pretrained_lookup(lambda: ["mine"])
        >>> pretrained_names()
        ['mine']
        >>> set_pretrained_lookup(registry_lookup)  # restore the registry's
        >>> "ours" in pretrained_names()
        True
    """
    global _lookup
    _lookup = lookup


def pretrained_names() -> list[str]:
    r"""Names that ``create_estimator(name)`` with ``pretrained=True`` can build, for error messages.

    Returns:
        the installed lookup's names; empty before one is installed (importing
        :mod:`kornia_ilum.estimators` installs the registry's, so in practice never).

    Examples:
        >>> import kornia_ilum.estimators
        >>> "ours" in pretrained_names()
        True
    """
    return [] if _lookup is None else list(_lookup())
