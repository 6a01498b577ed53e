"""Keeping functions out of Dynamo's graphs (:mod:`kornia_ilum.core.compiler`)."""

from __future__ import annotations

from functools import lru_cache

import torch

from kornia_ilum.core.compiler import compiler_disable


@compiler_disable
@lru_cache(maxsize=4)
def _table(n: int) -> torch.Tensor:
    x = torch.arange(n, dtype=torch.float64)
    return x + float(x.sum())  # a host sync: a graph break if Dynamo traced it


def test_compiler_disable_keeps_the_function():
    assert _table.__name__ == "_table" and hasattr(_table, "cache_info")  # functools.wraps
    assert _table._torchdynamo_disable  # what Dynamo reads: never inlined
    assert torch.equal(_table(3), torch.tensor([3.0, 4.0, 5.0], dtype=torch.float64))


def test_compiler_disable_under_compile():
    def f(x: torch.Tensor, n: int) -> torch.Tensor:
        return x * _table(n).to(x.dtype) + 1

    compiled = torch.compile(f, backend="eager")
    for n in (4, 4, 5):
        x = torch.rand(n)
        torch.testing.assert_close(compiled(x, n), f(x, n))
