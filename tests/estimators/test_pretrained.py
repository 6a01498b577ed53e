"""kornia_ilum.estimators.pretrained: the pretrained names, read by base and filled by the registry."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import kornia_ilum.estimators.base as base
import kornia_ilum.estimators.pretrained as pretrained
from kornia_ilum.estimators import registry
from kornia_ilum.estimators.pretrained import pretrained_names, set_pretrained_lookup


def test_the_registry_installs_its_lookup():
    names = pretrained_names()
    assert {"ours", "sh", "sipr", "uniform"} <= set(names)
    assert names == [n for n in registry.list_estimators() if registry.estimator_info(n).pretrained_available]


def test_a_lookup_can_be_replaced(monkeypatch):
    monkeypatch.setattr(pretrained, "_lookup", None)
    assert pretrained_names() == []
    set_pretrained_lookup(lambda: ["a", "b"])
    assert pretrained_names() == ["a", "b"]


@pytest.mark.parametrize("module", [base, pretrained])
def test_no_cycle_with_the_registry(module):
    """Neither the contract nor the lookup imports the registry, at the top or in a function."""
    tree = ast.parse(Path(module.__file__).read_text())
    imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    assert "kornia_ilum.estimators.registry" not in imported and "kornia_ilum.estimators" not in imported
