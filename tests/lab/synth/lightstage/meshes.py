"""Checks of triangle meshes shared by the subject and SDF tests."""

from __future__ import annotations

import numpy as np


def edge_counts(faces: np.ndarray) -> np.ndarray:
    """How many faces share each undirected edge (2 everywhere on a closed manifold mesh)."""
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    return np.unique(e, axis=0, return_counts=True)[1]


def signed_volume(v: np.ndarray, f: np.ndarray) -> float:
    """The signed volume of a closed mesh: positive when its faces wind outward."""
    a, b, c = (v[f[:, i]].astype(np.float64) for i in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)
