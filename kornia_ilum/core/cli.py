"""The small argument types of the ``kornia-ilum`` command line, shared by every sub-command.

Each is an ``argparse`` ``type=`` callable: it turns the option's text into a value or raises
:class:`argparse.ArgumentTypeError`, which ``argparse`` reports as a usage error naming the option. The
top-level command line (:mod:`kornia_ilum.cli`) and the sub-commands that live in their packages
(:mod:`kornia_ilum_lab.synth.cli`, :mod:`kornia_ilum_lab.train.cli`, :mod:`kornia_ilum_lab.evaluation.cli`) import them
from here, so that one option means the same everywhere and no sub-command imports the command line that
imports it.
"""

from __future__ import annotations

import argparse
import ast
import math

__all__ = ["LAB_INSTALL", "fraction", "key_value", "nonnegative_float", "nonnegative_int", "positive_int"]

#: How to install the lab (``kornia_ilum_lab``, this repository's ``plugins/lab``), which the commands that
#: render, train or score name when it is missing.
LAB_INSTALL = "pip install -c constraints.txt -e ./plugins/lab"


def positive_int(text: str) -> int:
    """An integer ``> 0`` (``type=`` of options such as ``--steps`` or ``--size``).

    Args:
        text: the option's text.

    Returns:
        the integer.

    Raises:
        argparse.ArgumentTypeError: ``text`` is no integer, or not positive.

    Examples:
        >>> positive_int("12")
        12
        >>> positive_int("0")
        Traceback (most recent call last):
        ...
        argparse.ArgumentTypeError: must be a positive integer, got '0'
    """
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}")
    return value


def nonnegative_int(text: str) -> int:
    """``0`` (which turns something off, e.g. ``--sheet 0``) or a :func:`positive_int`.

    Args:
        text: the option's text.

    Returns:
        the integer, ``>= 0``.

    Raises:
        argparse.ArgumentTypeError: ``text`` is neither ``0`` nor a positive integer (the message is
            :func:`positive_int`'s).

    Examples:
        >>> nonnegative_int(" 0"), nonnegative_int("48")
        (0, 48)
    """
    return 0 if text.strip() == "0" else positive_int(text)


def nonnegative_float(text: str) -> float:
    """A finite float ``>= 0`` (``type=`` of thresholds such as ``video --time-constant``).

    Args:
        text: the option's text.

    Returns:
        the float.

    Raises:
        argparse.ArgumentTypeError: ``text`` is no number, not finite (``nan``, ``inf``), or negative.

    Examples:
        >>> nonnegative_float("0"), nonnegative_float("0.03")
        (0.0, 0.03)
        >>> nonnegative_float("-1")
        Traceback (most recent call last):
        ...
        argparse.ArgumentTypeError: must be a finite number >= 0, got '-1'
    """
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text!r}") from None
    if not (math.isfinite(value) and value >= 0.0):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text!r}")
    return value


def fraction(text: str) -> float:
    """A float in ``[0, 1)`` (``type=`` of tolerances such as ``synth check-skin --rtol``).

    Args:
        text: the option's text.

    Returns:
        the float.

    Raises:
        argparse.ArgumentTypeError: ``text`` is no number, or outside ``[0, 1)``.

    Examples:
        >>> fraction("0.15")
        0.15
        >>> fraction("1")
        Traceback (most recent call last):
        ...
        argparse.ArgumentTypeError: must be a fraction in [0, 1), got '1'
    """
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a fraction in [0, 1), got {text!r}") from None
    if not 0.0 <= value < 1.0:
        raise argparse.ArgumentTypeError(f"must be a fraction in [0, 1), got {text!r}")
    return value


def key_value(text: str) -> tuple[str, object]:
    """A ``KEY=VALUE`` setting (``type=`` of ``train --data`` and ``--model``, ``evaluate --portraits``): the
    key, an identifier, and the value read as a Python literal where it is one (``0.3``, ``True``,
    ``(1, 2)``), else kept as text.

    Args:
        text: the option's text.

    Returns:
        ``(key, value)``.

    Raises:
        argparse.ArgumentTypeError: no ``=``, or a key that is not an identifier.

    Examples:
        >>> key_value("colour_looks=0.3"), key_value("crop=face")
        (('colour_looks', 0.3), ('crop', 'face'))
    """
    key, sep, value = text.partition("=")
    if not sep or not key.isidentifier():
        raise argparse.ArgumentTypeError(f"must be KEY=VALUE, got {text!r}")
    try:
        return key, ast.literal_eval(value)
    except (ValueError, SyntaxError):
        return key, value
