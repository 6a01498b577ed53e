"""Tests of kornia_ilum.core.seeding: seeds and generators derived from text keys."""

from __future__ import annotations

import hashlib

import torch

from kornia_ilum.core.seeding import hashed_generator, hashed_seed


def test_hashed_seed_is_blake2b_little_endian():
    key = "kornia_ilum.synth:0:5"
    expected = int.from_bytes(hashlib.blake2b(key.encode(), digest_size=8).digest(), "little")
    assert hashed_seed(key) == expected
    assert 0 <= hashed_seed(key) < 2**64


def test_hashed_seed_separates_keys():
    seeds = {hashed_seed(f"subject:{i}") for i in range(100)}
    assert len(seeds) == 100


def test_hashed_generator_repeats_its_stream():
    a = torch.rand(5, generator=hashed_generator("view:3"))
    b = torch.rand(5, generator=hashed_generator("view:3"))
    c = torch.rand(5, generator=hashed_generator("view:4"))
    assert torch.equal(a, b) and not torch.equal(a, c)
    assert hashed_generator("view:3").device == torch.device("cpu")
    assert hashed_generator("view:3").initial_seed() == hashed_seed("view:3")
