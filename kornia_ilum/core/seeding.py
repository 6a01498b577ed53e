"""Seeds derived from text keys: the same key gives the same random stream on every machine and Python."""

from __future__ import annotations

import hashlib

import torch

__all__ = ["hashed_generator", "hashed_seed"]


def hashed_seed(key: str) -> int:
    """The first 8 bytes of ``blake2b(key)``, little-endian: a 64-bit seed that no ``PYTHONHASHSEED`` changes.

    Examples:
        >>> hashed_seed("kornia_ilum.synth:0:5") == hashed_seed("kornia_ilum.synth:0:5")
        True
    """
    return int.from_bytes(hashlib.blake2b(key.encode(), digest_size=8).digest(), "little")


def hashed_generator(key: str) -> torch.Generator:
    """A CPU :class:`torch.Generator` seeded with :func:`hashed_seed` ``(key)``."""
    return torch.Generator().manual_seed(hashed_seed(key))
