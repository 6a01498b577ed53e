"""Seeds derived from text keys: the same key gives the same random stream on every machine and Python."""

from __future__ import annotations

import hashlib

import torch

__all__ = ["hashed_generator", "hashed_seed"]


def hashed_seed(key: str) -> int:
    """The first 8 bytes of ``blake2b(key)``, little-endian: a 64-bit seed that no ``PYTHONHASHSEED`` changes.

    Args:
        key: the text that names the random stream.

    Returns:
        an integer in ``[0, 2^64)``.

    Examples:
        >>> hashed_seed("kornia_ilum_lab.synth:0:5") == hashed_seed("kornia_ilum_lab.synth:0:5")
        True
    """
    return int.from_bytes(hashlib.blake2b(key.encode(), digest_size=8).digest(), "little")


def hashed_generator(key: str) -> torch.Generator:
    """A CPU :class:`torch.Generator` seeded with :func:`hashed_seed` ``(key)``.

    Args:
        key: the text that names the random stream.

    Returns:
        a new generator; two with the same key draw the same numbers.

    Examples:
        >>> a = torch.rand(3, generator=hashed_generator("scene:7"))
        >>> torch.equal(a, torch.rand(3, generator=hashed_generator("scene:7")))
        True
    """
    return torch.Generator().manual_seed(hashed_seed(key))
