r"""Signed distance functions on numpy grids, and a narrow-band marching-cubes mesher.

The synthetic subjects (:mod:`kornia_ilum_lab.synth.lightstage.subjects`) are built from these primitives, blended
with polynomial smooth minima, and meshed with :func:`skimage.measure.marching_cubes`.

Convention:
    Every primitive takes the coordinates ``x, y, z`` as broadcastable float32 arrays (metres, the frame of
    docs/conventions.rst) and returns the signed distance, negative inside. Most are *bounds* or close
    approximations of the true distance (the ellipsoid is Inigo Quilez's first-order bound, a warped domain
    stretches distances by its Jacobian): good enough for meshing, which only needs the zero set and the sign.

References:
    Inigo Quilez, "distance functions" and "smooth minimum" (iquilezles.org/articles), for the primitive
    and blending formulas.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from skimage.measure import marching_cubes

__all__ = [
    "bounded",
    "capsule",
    "edit_in_box",
    "ellipsoid",
    "mesh_sdf",
    "smax",
    "smin",
    "sphere",
]

Array = np.ndarray
SDF = Callable[[Array, Array, Array], Array]
_EPS = np.float32(1e-9)


def smin(a: Array, b: Array, k: float) -> Array:
    """Polynomial smooth minimum (union) of two distances, blending over a width ``k`` (metres).

    ``h = clip(1/2 + (b - a) / (2 k), 0, 1)``, ``smin = b + (a - b) h - k h (1 - h)``: the plain minimum where
    ``|a - b| >= k``, at most ``k / 4`` below it in between.

    Args:
        a: a signed distance (array or number).
        b: another, broadcastable with ``a``.
        k: the blend width (metres); ``k <= 0`` gives ``np.minimum(a, b)``.

    Returns:
        the blended distance, broadcast from ``a`` and ``b``.

    Examples:
        >>> round(float(smin(np.float32(0.0), np.float32(0.0), 0.1)), 4)  # where both meet: k / 4 below
        -0.025
        >>> float(smin(np.float32(0.0), np.float32(1.0), 0.1))  # far apart: the minimum
        0.0
    """
    if k <= 0.0:
        return np.minimum(a, b)
    h = np.clip(0.5 + 0.5 * (b - a) / k, 0.0, 1.0)
    return b + (a - b) * h - k * h * (1.0 - h)


def smax(a: Array, b: Array, k: float) -> Array:
    """Polynomial smooth maximum (intersection; ``smax(a, -b)`` subtracts ``b``).

    Args:
        a: a signed distance (array or number).
        b: another, broadcastable with ``a``.
        k: the blend width (metres); ``k <= 0`` gives ``np.maximum(a, b)``.

    Returns:
        ``-smin(-a, -b, k)``.

    Examples:
        >>> round(float(smax(np.float32(0.0), np.float32(0.0), 0.1)), 4)
        0.025
    """
    return -smin(-a, -b, k)


def sphere(x: Array, y: Array, z: Array, *, c: Sequence[float], r: float) -> Array:
    """Exact distance to a sphere of centre ``c`` and radius ``r``.

    Args:
        x: the points' x coordinates (metres).
        y: their y coordinates, broadcastable with ``x``.
        z: their z coordinates, broadcastable with ``x``.
        c: the centre ``(x, y, z)``.
        r: the radius.

    Returns:
        the signed distance, negative inside, broadcast from ``x``, ``y`` and ``z``.

    Examples:
        >>> x = np.array([0.0, 0.3], np.float32); o = np.zeros(2, np.float32)
        >>> [round(float(v), 4) for v in sphere(x, o, o, c=(0.0, 0.0, 0.0), r=0.1)]
        [-0.1, 0.2]
    """
    return np.sqrt((x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2) - r


def ellipsoid(x: Array, y: Array, z: Array, *, c: Sequence[float], r: Sequence[float]) -> Array:
    """Axis-aligned ellipsoid of centre ``c`` and semi-axes ``r`` (Quilez's bound ``k0 (k0 - 1) / k1``).

    Args:
        x: the points' x coordinates (metres).
        y: their y coordinates, broadcastable with ``x``.
        z: their z coordinates, broadcastable with ``x``.
        c: the centre ``(x, y, z)``.
        r: the semi-axes along x, y and z, positive.

    Returns:
        the signed distance bound, negative inside, zero on the surface.

    Examples:
        >>> x = np.array([0.2, 0.4], np.float32); o = np.zeros(2, np.float32)
        >>> [round(float(v), 4) for v in ellipsoid(x, o, o, c=(0.0, 0.0, 0.0), r=(0.2, 0.1, 0.1))]  # x axis
        [0.0, 0.2]
    """
    px, py, pz = (x - c[0]) / r[0], (y - c[1]) / r[1], (z - c[2]) / r[2]
    k0 = np.sqrt(px * px + py * py + pz * pz)
    k1 = np.sqrt((px / r[0]) ** 2 + (py / r[1]) ** 2 + (pz / r[2]) ** 2) + _EPS
    return k0 * (k0 - 1.0) / k1


def capsule(
    x: Array,
    y: Array,
    z: Array,
    *,
    a: Sequence[float],
    b: Sequence[float],
    ra: float,
    rb: float | None = None,
) -> Array:
    """Segment ``a``-``b`` swept by a sphere whose radius goes linearly from ``ra`` to ``rb`` (a bound).

    Args:
        x: the points' x coordinates (metres).
        y: their y coordinates, broadcastable with ``x``.
        z: their z coordinates, broadcastable with ``x``.
        a: one end of the segment ``(x, y, z)``.
        b: the other end, different from ``a``.
        ra: the radius at ``a``.
        rb: the radius at ``b`` (``None``: ``ra``, a plain capsule).

    Returns:
        the signed distance (a bound when ``ra != rb``), negative inside.

    Examples:
        >>> p = [np.float32(0.1), np.float32(0.05), np.float32(0.0)]  # beside the middle of the segment
        >>> segment = {"a": (0.0, 0.0, 0.0), "b": (0.0, 0.1, 0.0)}
        >>> round(float(capsule(*p, **segment, ra=0.05)), 4)
        0.05
        >>> round(float(capsule(*p, **segment, ra=0.05, rb=0.01)), 4)  # radius 0.03 there
        0.07
    """
    rb = ra if rb is None else rb
    bx, by, bz = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    px, py, pz = x - a[0], y - a[1], z - a[2]
    h = np.clip((px * bx + py * by + pz * bz) / (bx * bx + by * by + bz * bz), 0.0, 1.0)
    d = np.sqrt((px - bx * h) ** 2 + (py - by * h) ** 2 + (pz - bz * h) ** 2)
    return d - (ra + (rb - ra) * h)


def mesh_sdf(
    fn: SDF,
    *,
    lo: Sequence[float],
    hi: Sequence[float],
    step: float,
    coarse: int = 4,
    band: float = 2.0,
) -> tuple[Array, Array, Array]:
    r"""Mesh the zero set of ``fn`` inside the box ``[lo, hi]`` with marching cubes, sampling a narrow band.

    ``fn`` is first evaluated on a grid ``coarse`` times coarser; only the coarse cells with a corner closer to
    the surface than ``band`` coarse-cell diagonals are refined (``fn`` evaluated at every fine node in them),
    the rest of the fine grid is filled by trilinear interpolation of the coarse values, whose sign is right
    away from the surface. The grid's outer layer is forced outside, so the meshes are closed.

    Args:
        fn: the signed distance, ``fn(x, y, z)`` on flat float32 arrays, negative inside.
        lo: the box's lower corner (metres).
        hi: the box's upper corner (metres).
        step: the fine grid's spacing (metres).
        coarse: the coarse-to-fine ratio.
        band: the refined band's half-width, in coarse-cell diagonals.

    Returns:
        ``(vertices, faces, normals)``: ``(V, 3)`` float32 metres, ``(F, 3)`` int32 counter-clockwise seen from
        outside, ``(V, 3)`` float32 unit outward normals (the gradient of ``fn``). Empty arrays when the zero
        set misses the box.

    Examples:
        >>> ball = lambda x, y, z: sphere(x, y, z, c=(0, 0, 0), r=0.1)
        >>> v, f, n = mesh_sdf(ball, lo=(-0.12,) * 3, hi=(0.12,) * 3, step=0.01)
        >>> bool(np.allclose(np.linalg.norm(v, axis=1), 0.1, atol=2e-3)), f.dtype
        (True, dtype('int32'))
    """
    lo_a = np.asarray(lo, dtype=np.float64)
    cells = np.maximum(np.ceil((np.asarray(hi, dtype=np.float64) - lo_a) / (step * coarse)).astype(int), 1)
    shape_c = cells + 1
    axes_c = [(lo_a[i] + np.arange(shape_c[i]) * step * coarse).astype(np.float32) for i in range(3)]
    xc, yc, zc = np.meshgrid(*axes_c, indexing="ij")
    dc = np.asarray(fn(xc.ravel(), yc.ravel(), zc.ravel()), dtype=np.float32).reshape(tuple(shape_c))

    # Coarse cells that may hold the surface: any corner within `band` diagonals.
    near = np.abs(dc) < band * math.sqrt(3.0) * step * coarse
    cell_near = np.zeros(tuple(cells), dtype=bool)
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                cell_near |= near[dx : dx + cells[0], dy : dy + cells[1], dz : dz + cells[2]]
    shape_f = cells * coarse + 1
    # Trilinear upsampling of the coarse values (exact at the coarse nodes), one axis at a time.
    vol = dc
    for axis in range(3):
        f = np.arange(shape_f[axis])
        i0 = np.minimum(f // coarse, cells[axis] - 1)
        w = ((f - i0 * coarse) / coarse).astype(np.float32)
        w = w.reshape([-1 if i == axis else 1 for i in range(3)])
        vol = np.take(vol, i0, axis=axis) * (1.0 - w) + np.take(vol, i0 + 1, axis=axis) * w
    vol = np.ascontiguousarray(vol, dtype=np.float32)

    # Fine nodes of the near cells, evaluated exactly.
    if not cell_near.any():
        return _empty()
    up = np.repeat(np.repeat(np.repeat(cell_near, coarse, 0), coarse, 1), coarse, 2)
    mask = np.zeros(tuple(shape_f), dtype=bool)
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                mask[dx : dx + up.shape[0], dy : dy + up.shape[1], dz : dz + up.shape[2]] |= up
    idx = np.nonzero(mask)
    pts = [(lo_a[i] + np.arange(shape_f[i]) * step).astype(np.float32)[idx[i]] for i in range(3)]
    vol[idx] = np.asarray(fn(*pts), dtype=np.float32)
    # Closed meshes: the outer layer of the grid is outside.
    for axis in range(3):
        for end in (0, -1):
            sl = tuple(end if i == axis else slice(None) for i in range(3))
            vol[sl] = np.maximum(vol[sl], np.float32(step))
    if vol.min() >= 0.0:
        return _empty()
    verts, faces, normals, _ = marching_cubes(vol, level=0.0, spacing=(step, step, step), mask=mask)
    verts = (verts + lo_a).astype(np.float32)
    # skimage's normals follow the descent of `vol`, i.e. point inside: flip them outward.
    return verts, faces.astype(np.int32), (-normals).astype(np.float32)


def _empty() -> tuple[Array, Array, Array]:
    return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32), np.zeros((0, 3), np.float32)


def bounded(
    fn: SDF, x: Array, y: Array, z: Array, *, lo: Sequence[float], hi: Sequence[float], margin: float
) -> Array:
    r"""Evaluate a primitive only near its bounding box, and a cheap lower bound of its distance elsewhere.

    ``fn`` must be negative only inside ``[lo, hi]``. Points within ``margin`` of the box get ``fn``; the others
    get their Chebyshev distance to the expanded box plus ``margin``, which never exceeds their distance to the
    primitive. With ``margin`` at least twice a smooth-minimum width, blending with it stays exact near other
    surfaces.

    Args:
        fn: the primitive's signed distance on flat arrays.
        x: flat coordinates (the same shape for ``x``, ``y`` and ``z``).
        y: flat coordinates.
        z: flat coordinates.
        lo: the primitive's lower bound.
        hi: the primitive's upper bound.
        margin: the exactly-evaluated margin around the box (metres).

    Returns:
        The distance, shaped like ``x``.

    Examples:
        >>> x = np.array([0.0, 1.0], np.float32); o = np.zeros(2, np.float32)
        >>> ball = lambda x, y, z: sphere(x, y, z, c=(0, 0, 0), r=0.1)
        >>> d = bounded(ball, x, o, o, lo=(-0.1,) * 3, hi=(0.1,) * 3, margin=0.05)
        >>> [round(float(v), 3) for v in d]  # exact inside the margin, a lower bound outside
        [-0.1, 0.9]
    """
    lo_m = [v - margin for v in lo]
    hi_m = [v + margin for v in hi]
    d = np.maximum(np.maximum(lo_m[0] - x, x - hi_m[0]), 0.0)
    d = np.maximum(d, np.maximum(lo_m[1] - y, y - hi_m[1]))
    d = np.maximum(d, np.maximum(lo_m[2] - z, z - hi_m[2]))
    out = (d + margin).astype(np.float32)
    inside = d <= 0.0
    if inside.any():
        out[inside] = fn(x[inside], y[inside], z[inside])
    return out


def edit_in_box(
    d: Array,
    x: Array,
    y: Array,
    z: Array,
    *,
    lo: Sequence[float],
    hi: Sequence[float],
    fn: Callable[[Array, Array, Array, Array], Array],
) -> Array:
    r"""Apply a local edit ``d <- fn(d, x, y, z)`` only at the points inside the box ``[lo, hi]``.

    For carvings and blends whose effect (blend width included) stays inside the box: the points outside keep
    ``d``, and ``fn`` runs on the points inside only.

    Args:
        d: the distance so far, on flat arrays like ``x``.
        x: flat coordinates.
        y: flat coordinates.
        z: flat coordinates.
        lo: the box's lower corner.
        hi: the box's upper corner.
        fn: the edit, ``fn(d, x, y, z)`` on the points inside.

    Returns:
        The edited distance (a new array).

    Examples:
        >>> x = np.array([0.0, 1.0], np.float32); o = np.zeros(2, np.float32)
        >>> edit = lambda d, x, y, z: d - 1.0
        >>> edit_in_box(x - 0.5, x, o, o, lo=(-0.1,) * 3, hi=(0.1,) * 3, fn=edit).tolist()
        [-1.5, 0.5]
    """
    m = (x >= lo[0]) & (x <= hi[0]) & (y >= lo[1]) & (y <= hi[1]) & (z >= lo[2]) & (z <= hi[2])
    out = np.array(d, dtype=np.float32, copy=True)
    if m.any():
        out[m] = fn(out[m], x[m], y[m], z[m])
    return out
