r"""Readers for the MakeHuman 1.1 asset formats (hm08 base mesh, ``.target``, ``.mhclo``, ``.mhmat``, textures).

The formats are those of the shared data root's ``README.md`` (``$KORNIA_ILUM_SHARED_DATA/makehuman``):

- ``.obj``: ``v``, ``vt`` and ``f v/vt ...`` lines (quads or triangles), ``g`` groups.
- ``.target``: ``i dx dy dz`` lines, applied additively (``V = V_base + sum_t w_t D_t``).
- ``.mhclo``: a proxy bound to the base mesh: ``P = wi V[i] + wj V[j] + wk V[k] + diag(s) (dx, dy, dz)``, where
  ``s_axis = |V[a]_axis - V[b]_axis| / den`` from the ``{x,y,z}_scale a b den`` header lines; a line with a
  single index ``i`` is an exact copy of ``V[i]``.
- ``.mhmat``: ``key value`` lines; texture paths are relative to the ``.mhmat``'s folder.

Three mesh helpers sit beside them: :func:`vertex_normals`, :func:`raster_uv_mask` (UV triangles drawn into
a texture's rows) and :func:`opaque_faces` (which faces of an alpha-tested card cover an opaque texel).

Everything here is plain numpy, in the assets' own units (decimetres, +Y up, the face along +Z).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kornia_ilum.core.errors import IlumError

__all__ = [
    "ETHNICITIES",
    "MakeHumanAssetsNotFoundError",
    "ObjMesh",
    "Proxy",
    "age_to_macro",
    "bind_proxy",
    "load_texture",
    "macro_target_weights",
    "opaque_faces",
    "raster_uv_mask",
    "read_mhclo",
    "read_mhmat",
    "read_modifier_pairs",
    "read_obj",
    "read_target",
    "srgb_to_linear_np",
    "vertex_normals",
    "years_to_age",
]


class MakeHumanAssetsNotFoundError(IlumError, FileNotFoundError):
    """The MakeHuman data root is missing (point ``$KORNIA_ILUM_MAKEHUMAN`` or ``$KORNIA_ILUM_SHARED_DATA`` at it).

    Both an :class:`~kornia_ilum.core.errors.IlumError` and a :class:`FileNotFoundError`.

    Examples:
        >>> try:
        ...     raise MakeHumanAssetsNotFoundError("no MakeHuman assets in /nowhere")
        ... except FileNotFoundError as exc:
        ...     isinstance(exc, IlumError), str(exc)
        (True, 'no MakeHuman assets in /nowhere')
    """


@dataclass
class ObjMesh:
    """A Wavefront OBJ mesh, fan-triangulated.

    Args:
        vertices: ``(V, 3)`` float64 positions.
        uvs: ``(T, 2)`` float64 texture coordinates (``v`` up).
        tri_v: ``(F, 3)`` int64 vertex indices of the triangles.
        tri_t: ``(F, 3)`` int64 uv indices of the triangles.
        tri_group: ``(F,)`` int64 index into ``groups`` of each triangle's ``g`` group.
        groups: the group names.
        quad_v: ``(Q, 4)`` int64 vertex indices of the quads (the faces with 4 corners), for the base mesh.
        quad_group: ``(Q,)`` int64 group of each quad.

    Examples:
        >>> tri = np.array([[0, 1, 2], [0, 2, 3]])
        >>> mesh = ObjMesh(np.zeros((5, 3)), np.zeros((0, 2)), tri, -np.ones_like(tri), np.array([1, 2]),
        ...                ["default", "eyes", "body"])
        >>> mesh.group_vertices("body").tolist()
        [0, 2, 3]
    """

    vertices: np.ndarray
    uvs: np.ndarray
    tri_v: np.ndarray
    tri_t: np.ndarray
    tri_group: np.ndarray
    groups: list[str]
    quad_v: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), np.int64))
    quad_group: np.ndarray = field(default_factory=lambda: np.zeros((0,), np.int64))

    def group_vertices(self, name: str) -> np.ndarray:
        """The sorted vertex indices used by the faces of group ``name``."""
        g = self.groups.index(name)
        return np.unique(self.tri_v[self.tri_group == g])


def read_obj(path: str | Path) -> ObjMesh:
    """Read an OBJ file (``v``, ``vt``, ``f v/vt``, ``g``); polygons are fan-triangulated in their order.

    Args:
        path: the ``.obj`` file.

    Returns:
        The :class:`ObjMesh` (0-based indices).

    Examples:
        >>> import tempfile
        >>> obj = "v 0 0 0\\nv 1 0 0\\nv 1 1 0\\nv 0 1 0\\ng body\\nf 1 2 3 4\\n"  # one quad, no uvs
        >>> with tempfile.TemporaryDirectory() as d:
        ...     _ = (Path(d) / "quad.obj").write_text(obj)
        ...     mesh = read_obj(Path(d) / "quad.obj")
        >>> mesh.tri_v.tolist(), mesh.groups, mesh.quad_v.shape
        ([[0, 1, 2], [0, 2, 3]], ['default', 'body'], (1, 4))
    """
    verts: list[str] = []
    uvs: list[str] = []
    tv: list[list[int]] = []
    tt: list[list[int]] = []
    tg: list[int] = []
    qv: list[list[int]] = []
    qg: list[int] = []
    groups: list[str] = ["default"]
    cur = 0
    with open(path, encoding="utf-8", errors="replace") as fh:
        for line in fh:
            if line.startswith("v "):
                verts.append(line[2:])
            elif line.startswith("vt "):
                uvs.append(line[3:])
            elif line.startswith("g "):
                name = line.split(maxsplit=1)[1].strip()
                if name not in groups:
                    groups.append(name)
                cur = groups.index(name)
            elif line.startswith("f "):
                corners = [c.split("/") for c in line.split()[1:]]
                iv = [int(c[0]) - 1 for c in corners]
                it = [int(c[1]) - 1 if len(c) > 1 and c[1] else -1 for c in corners]
                for k in range(1, len(iv) - 1):
                    tv.append([iv[0], iv[k], iv[k + 1]])
                    tt.append([it[0], it[k], it[k + 1]])
                    tg.append(cur)
                if len(iv) == 4:
                    qv.append(iv)
                    qg.append(cur)
    vertices = np.array(" ".join(v.split("#")[0] for v in verts).split(), dtype=np.float64).reshape(-1, 3)
    uv = np.array([u.split()[:2] for u in uvs], dtype=np.float64).reshape(-1, 2)
    return ObjMesh(
        vertices,
        uv,
        np.array(tv, np.int64).reshape(-1, 3),
        np.array(tt, np.int64).reshape(-1, 3),
        np.array(tg, np.int64),
        groups,
        np.array(qv, np.int64).reshape(-1, 4),
        np.array(qg, np.int64),
    )


def read_target(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a ``.target``: the moved vertices and their offsets.

    Args:
        path: the ``.target`` file.

    Returns:
        ``(indices, deltas)``: ``(N,)`` int32 and ``(N, 3)`` float32 (decimetres).

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as d:
        ...     _ = (Path(d) / "a.target").write_text("# a comment\\n3 0.5 0 0\\n7 0 -0.25 0\\n")
        ...     indices, deltas = read_target(Path(d) / "a.target")
        >>> indices.tolist(), deltas.tolist()
        ([3, 7], [[0.5, 0.0, 0.0], [0.0, -0.25, 0.0]])
    """
    with open(path, encoding="utf-8", errors="replace") as fh:
        body = "".join(line for line in fh if line.strip() and not line.lstrip().startswith("#"))
    a = np.array(body.split(), dtype=np.float64).reshape(-1, 4)
    return a[:, 0].astype(np.int32), a[:, 1:].astype(np.float32)


@dataclass
class Proxy:
    """A parsed ``.mhclo`` proxy with its mesh.

    Args:
        name: the proxy's ``name``.
        folder: the folder of the ``.mhclo`` (the ``obj_file`` and ``material`` are relative to it).
        mesh: the proxy's :class:`ObjMesh` (its own vertex positions are unused once bound).
        refs: ``(N, 3)`` int64 base-mesh vertices of each proxy vertex.
        weights: ``(N, 3)`` float64 barycentric weights.
        offsets: ``(N, 3)`` float64 offsets, scaled per axis by ``scales``.
        scales: ``{"x": (a, b, den), "y": ..., "z": ...}``.
        material: the ``material`` path relative to ``folder`` (``""`` when absent).
        delete_verts: base-mesh vertices the proxy hides (``delete_verts``), sorted.
        header: the other header keys, raw.

    Examples:
        >>> mesh = ObjMesh(np.zeros((1, 3)), np.zeros((0, 2)), np.zeros((0, 3), np.int64), np.zeros((0, 3), np.int64),
        ...                np.zeros(0, np.int64), ["default"])
        >>> proxy = Proxy("dot", Path("."), mesh, refs=np.array([[0, 1, 2]]), weights=np.array([[0.5, 0.5, 0.0]]),
        ...               offsets=np.zeros((1, 3)), scales={})  # one vertex halfway between base vertices 0 and 1
        >>> proxy.material, proxy.delete_verts.tolist()
        ('', [])
    """

    name: str
    folder: Path
    mesh: ObjMesh
    refs: np.ndarray
    weights: np.ndarray
    offsets: np.ndarray
    scales: dict[str, tuple[int, int, float]]
    material: str = ""
    delete_verts: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    header: dict[str, str] = field(default_factory=dict)


def _parse_delete_verts(tokens: list[str]) -> list[int]:
    """The vertex indices of a ``delete_verts`` line: single ``i`` and inclusive ranges ``i - j`` (MakeHuman writes
    both; also ``i-j`` without spaces).

    Examples:
        >>> _parse_delete_verts(["3", "7", "-", "9", "12-13"])
        [3, 7, 8, 9, 12, 13]
    """
    words = " ".join(tokens).replace("-", " - ").split()
    out: list[int] = []
    i = 0
    while i < len(words):
        if i + 2 < len(words) and words[i + 1] == "-":
            out.extend(range(int(words[i]), int(words[i + 2]) + 1))
            i += 3
        else:
            out.append(int(words[i]))
            i += 1
    return out


def read_mhclo(path: str | Path) -> Proxy:
    """Read a ``.mhclo`` proxy and its ``obj_file``.

    Args:
        path: the ``.mhclo`` file.

    Returns:
        The :class:`Proxy`.

    Raises:
        ValueError: the number of bound vertices differs from the ``obj_file``'s.

    Examples:
        >>> import tempfile
        >>> mhclo = "name dot\\nobj_file dot.obj\\nx_scale 0 1 2.0\\nverts 0\\n0 1 2 0.5 0.5 0.0 0.1 0.0 0.0\\n"
        >>> with tempfile.TemporaryDirectory() as d:
        ...     _ = (Path(d) / "dot.obj").write_text("v 0 0 0\\n")
        ...     _ = (Path(d) / "dot.mhclo").write_text(mhclo)
        ...     proxy = read_mhclo(Path(d) / "dot.mhclo")
        >>> proxy.name, proxy.refs.tolist(), proxy.weights.tolist(), proxy.scales
        ('dot', [[0, 1, 2]], [[0.5, 0.5, 0.0]], {'x': (0, 1, 2.0)})
    """
    path = Path(path)
    header: dict[str, str] = {}
    scales: dict[str, tuple[int, int, float]] = {}
    refs: list[list[int]] = []
    weights: list[list[float]] = []
    offsets: list[list[float]] = []
    delete: list[int] = []
    section = "header"
    with open(path, encoding="utf-8", errors="replace") as fh:
        for raw in fh:
            line = raw.split("#")[0].strip()
            if not line:
                continue
            tok = line.split()
            head = tok[0]
            if head[0].isdigit() or head[0] == "-":
                if section == "verts":
                    if len(tok) == 1:
                        refs.append([int(tok[0])] * 3)
                        weights.append([1.0, 0.0, 0.0])
                        offsets.append([0.0, 0.0, 0.0])
                    else:
                        refs.append([int(t) for t in tok[:3]])
                        weights.append([float(t) for t in tok[3:6]])
                        offsets.append([float(t) for t in tok[6:9]] if len(tok) >= 9 else [0.0, 0.0, 0.0])
                elif section == "delete_verts":
                    delete.extend(_parse_delete_verts(tok))
                continue
            if head == "verts":
                section = "verts"
            elif head == "delete_verts":
                section = "delete_verts"
                delete.extend(_parse_delete_verts(tok[1:]))
            elif head in ("x_scale", "y_scale", "z_scale"):
                scales[head[0]] = (int(tok[1]), int(tok[2]), float(tok[3]))
            elif head != "tag":
                header.setdefault(head, " ".join(tok[1:]))
    mesh = read_obj(path.parent / header["obj_file"])
    if len(refs) != len(mesh.vertices):
        raise ValueError(f"{path}: {len(refs)} bound vertices for {len(mesh.vertices)} obj vertices")
    return Proxy(
        name=header.get("name", path.stem),
        folder=path.parent,
        mesh=mesh,
        refs=np.array(refs, np.int64),
        weights=np.array(weights, np.float64),
        offsets=np.array(offsets, np.float64),
        scales=scales,
        material=header.get("material", ""),
        delete_verts=np.unique(np.array(delete, np.int64)),
        header=header,
    )


def bind_proxy(proxy: Proxy, base_vertices: np.ndarray) -> np.ndarray:
    """The proxy's vertices on a (morphed) base mesh: ``P = sum_k w_k V[r_k] + diag(s) offset``.

    Args:
        proxy: the :class:`Proxy`.
        base_vertices: ``(V, 3)`` the morphed base mesh, helpers included.

    Returns:
        ``(N, 3)`` float64 proxy vertices.

    Examples:
        >>> mesh = ObjMesh(np.zeros((1, 3)), np.zeros((0, 2)), np.zeros((0, 3), np.int64), np.zeros((0, 3), np.int64),
        ...                np.zeros(0, np.int64), ["default"])
        >>> proxy = Proxy("dot", Path("."), mesh, refs=np.array([[0, 1, 2]]), weights=np.array([[0.5, 0.5, 0.0]]),
        ...               offsets=np.array([[0.1, 0.0, 0.0]]), scales={"x": (0, 1, 2.0)})
        >>> base = np.array([[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0]])
        >>> bind_proxy(proxy, base).tolist()  # halfway, plus 0.1 scaled by |4 - 0| / 2
        [[2.2, 0.0, 0.0]]
    """
    v = np.asarray(base_vertices, dtype=np.float64)
    p = np.einsum("nk,nkc->nc", proxy.weights, v[proxy.refs])
    s = np.ones(3)
    for axis, (a, b, den) in proxy.scales.items():
        c = "xyz".index(axis)
        s[c] = abs(v[a, c] - v[b, c]) / den
    return p + proxy.offsets * s


def read_mhmat(path: str | Path) -> dict[str, str]:
    """Read a ``.mhmat``: ``key value`` lines (``//`` and ``#`` comments skipped), first occurrence wins.

    Args:
        path: the ``.mhmat`` file.

    Returns:
        ``{key: value}``, the values as raw text (``""`` for a key without one).

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as d:
        ...     _ = (Path(d) / "skin.mhmat").write_text("// skin\\nname young\\ndiffuseTexture skin.png\\nname old\\n")
        ...     read_mhmat(Path(d) / "skin.mhmat")
        {'name': 'young', 'diffuseTexture': 'skin.png'}
    """
    out: dict[str, str] = {}
    with open(path, encoding="utf-8", errors="replace") as fh:
        for raw in fh:
            line = raw.strip()
            if not line or line.startswith(("#", "//")):
                continue
            tok = line.split(maxsplit=1)
            out.setdefault(tok[0], tok[1].strip() if len(tok) > 1 else "")
    return out


def srgb_to_linear_np(x: np.ndarray) -> np.ndarray:
    """The sRGB decoding curve (IEC 61966-2-1) on a float array in ``[0, 1]``.

    Args:
        x: sRGB-encoded values in ``[0, 1]``, any shape.

    Returns:
        the linear values, float32, in the shape of ``x``.

    Examples:
        >>> [round(float(v), 4) for v in srgb_to_linear_np(np.array([0.0, 0.5, 1.0]))]
        [0.0, 0.214, 1.0]
    """
    x = np.asarray(x, dtype=np.float32)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4).astype(np.float32)


def load_texture(path: str | Path) -> tuple[np.ndarray, np.ndarray | None]:
    """Load a PNG: linear RGB and its alpha.

    Args:
        path: the image file.

    Returns:
        ``(rgb, alpha)``: ``(H, W, 3)`` float32 linear RGB (sRGB-decoded) and ``(H, W)`` float32 alpha in
        ``[0, 1]``, or ``None`` when the image has none.

    Examples:
        >>> import tempfile
        >>> from PIL import Image
        >>> with tempfile.TemporaryDirectory() as d:
        ...     Image.new("RGBA", (4, 2), (255, 128, 0, 255)).save(Path(d) / "t.png")
        ...     rgb, alpha = load_texture(Path(d) / "t.png")
        >>> rgb.shape, [round(float(c), 3) for c in rgb[0, 0]], float(alpha.min())
        ((2, 4, 3), [1.0, 0.216, 0.0], 1.0)
    """
    from PIL import Image  # lazy: Pillow is an optional dependency (the dev extra)

    with Image.open(path) as im:
        has_alpha = im.mode in ("RGBA", "LA") or (im.mode == "P" and "transparency" in im.info)
        a = np.asarray(im.convert("RGBA" if has_alpha else "RGB"), dtype=np.float32) / 255.0
    rgb = srgb_to_linear_np(a[..., :3])
    return np.ascontiguousarray(rgb), (np.ascontiguousarray(a[..., 3]) if has_alpha else None)


# --------------------------------------------------------------------------------------------------------
# Macro targets
# --------------------------------------------------------------------------------------------------------

ETHNICITIES = ("african", "asian", "caucasian")


def years_to_age(years: float) -> float:
    """MakeHuman's age slider for an age in years: 1 y = 0, 25 y = 0.5, 90 y = 1 (linear in between).

    Args:
        years: the age in years.

    Returns:
        the slider value in ``[0, 1]`` (clipped outside 1 to 90 years).

    Examples:
        >>> years_to_age(1.0), years_to_age(25.0), years_to_age(90.0), round(years_to_age(40.0), 4)
        (0.0, 0.5, 1.0, 0.6154)
    """
    if years < 25.0:
        return max(0.0, (years - 1.0) / 48.0)
    return min(1.0, 0.5 + (years - 25.0) / 130.0)


def age_to_macro(age: float) -> dict[str, float]:
    """The child/young/old weights of the age slider (README formula).

    Args:
        age: the age slider in ``[0, 1]`` (:func:`years_to_age`).

    Returns:
        ``{"child": w, "young": w, "old": w}``, the weights of the macro targets of each age.

    Examples:
        >>> {k: round(v, 3) for k, v in age_to_macro(0.75).items()}
        {'child': 0.0, 'young': 0.5, 'old': 0.5}
    """
    if age < 0.5:
        young = max(0.0, (age - 0.1875) * 3.2)
        return {"child": min(1.0, 5.333 * age) - young, "young": young, "old": 0.0}
    old = 2.0 * age - 1.0
    return {"child": 0.0, "young": 1.0 - old, "old": old}


def _min_avg_max(x: float) -> dict[str, float]:
    lo, hi = max(0.0, 1.0 - 2.0 * x), max(0.0, 2.0 * x - 1.0)
    return {"min": lo, "average": 1.0 - lo - hi, "max": hi}


def macro_target_weights(
    ethnic: tuple[float, float, float], *, gender: float, age: float, muscle: float = 0.5, weight: float = 0.5
) -> dict[str, float]:
    """The weights of the macro targets (``targets/macrodetails``) for the macro sliders.

    Args:
        ethnic: (african, asian, caucasian) proportions (normalised to sum to 1 here).
        gender: 0 female ... 1 male.
        age: the age slider in ``[0, 1]`` (:func:`years_to_age`).
        muscle: the muscle slider in ``[0, 1]`` (0.5 average).
        weight: the weight slider in ``[0, 1]`` (0.5 average).

    Returns:
        ``{target stem: weight}`` for the nonzero weights, e.g. ``"caucasian-male-young"`` and
        ``"universal-male-young-averagemuscle-averageweight"``.

    Examples:
        >>> w = macro_target_weights((0.0, 0.0, 1.0), gender=1.0, age=0.5)
        >>> w["caucasian-male-young"], w["universal-male-young-averagemuscle-averageweight"]
        (1.0, 1.0)
    """
    e = np.asarray(ethnic, dtype=np.float64)
    e = e / e.sum()
    g = {"female": 1.0 - gender, "male": gender}
    a = age_to_macro(age)
    m, w = _min_avg_max(muscle), _min_avg_max(weight)
    out: dict[str, float] = {}
    for ei, en in enumerate(ETHNICITIES):
        for gn, gw in g.items():
            for an, aw in a.items():
                x = float(e[ei] * gw * aw)
                if x > 1e-9:
                    out[f"{en}-{gn}-{an}"] = x
    for gn, gw in g.items():
        for an, aw in a.items():
            for mn, mw in m.items():
                for wn, ww in w.items():
                    x = gw * aw * mw * ww
                    if x > 1e-9:
                        out[f"universal-{gn}-{an}-{mn}muscle-{wn}weight"] = x
    return out


def read_modifier_pairs(path: str | Path, groups: tuple[str, ...]) -> list[tuple[str, str, str | None, str | None]]:
    """The detail sliders of ``modeling_modifiers.json`` in ``groups``: ``(group, target, min, max)``.

    ``min``/``max`` are ``None`` for one-sided sliders (``{target}.target`` with a weight in ``[0, 1]``).

    Args:
        path: ``modeling_modifiers.json`` of the MakeHuman data.
        groups: the modifier groups to keep (``"nose"``, ``"mouth"``, ...).

    Returns:
        ``(group, target, min, max)`` for each modifier with a ``target`` in those groups, in the file's order.

    Examples:
        >>> import json, tempfile
        >>> spec = [{"group": "nose", "modifiers": [{"target": "nose-width", "min": "decr", "max": "incr"}]},
        ...         {"group": "ears", "modifiers": [{"target": "ears-size"}]}]
        >>> with tempfile.TemporaryDirectory() as d:
        ...     _ = (Path(d) / "modifiers.json").write_text(json.dumps(spec))
        ...     read_modifier_pairs(Path(d) / "modifiers.json", ("nose",))
        [('nose', 'nose-width', 'decr', 'incr')]
    """
    with open(path, encoding="utf-8") as fh:
        spec = json.load(fh)
    out = []
    for g in spec:
        if g["group"] not in groups:
            continue
        for m in g["modifiers"]:
            if "target" in m:
                out.append((g["group"], m["target"], m.get("min"), m.get("max")))
    return out


def vertex_normals(v: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Area-weighted smooth unit vertex normals of a triangle mesh (``(0, 0, 1)`` where they vanish).

    Args:
        v: ``(V, 3)`` vertex positions.
        tri: ``(F, 3)`` vertex indices of the triangles, counter-clockwise seen from outside.

    Returns:
        ``(V, 3)`` unit normals (``(0, 0, 1)`` for vertices of no or degenerate triangles).

    Examples:
        >>> v = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [5.0, 5.0, 5.0]])
        >>> vertex_normals(v, np.array([[0, 1, 2]])).tolist()  # a triangle facing +Z; vertex 3 is in none
        [[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]
    """
    fn = np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, tri[:, k], fn)
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    bad = ln[:, 0] < 1e-20
    n = n / np.maximum(ln, 1e-20)
    n[bad] = (0.0, 0.0, 1.0)
    return n


def raster_uv_mask(uv_tris: np.ndarray, size: int) -> np.ndarray:
    """``(size, size)`` bool mask of the UV triangles (``(F, 3, 2)``, v up) drawn into image rows (v down).

    Args:
        uv_tris: ``(F, 3, 2)`` texture coordinates of each triangle's corners, ``v`` up.
        size: the mask's side in texels.

    Returns:
        the mask ``(size, size)``, bool, row 0 at ``v = 1``.

    Examples:
        >>> raster_uv_mask(np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]]), 4).astype(int).tolist()
        [[1, 0, 0, 0], [1, 1, 0, 0], [1, 1, 1, 0], [1, 1, 1, 1]]
    """
    import cv2  # lazy: OpenCV is slow to import, and few steps need it

    img = np.zeros((size, size), np.uint8)
    px = np.stack([uv_tris[..., 0] * size, (1.0 - uv_tris[..., 1]) * size], -1)
    pts = np.round(px * 16).astype(np.int32)
    cv2.fillPoly(img, list(pts), 1, lineType=cv2.LINE_8, shift=4)
    return img.astype(bool)


def opaque_faces(uv_tris: np.ndarray, opacity: np.ndarray) -> np.ndarray:
    """Which UV triangles cover at least one opaque texel (``opacity >= 0.5``) of an alpha-tested map.

    Hair styles such as ``short02`` stack several cards over the forehead whose texels there are all clear. Every
    such face still stops a ray once (it is tested texel by texel), so a camera or shadow ray that crosses more
    of them than the renderer's layer budget is counted as blocked, and the skin under them renders black in
    blotches. A face that covers no opaque texel changes nothing but that, so it is dropped.

    Args:
        uv_tris: ``(F, 3, 2)`` texture coordinates (``v`` up) of each face's corners.
        opacity: ``(H, W)`` alpha map (rows: ``v`` down).

    Returns:
        ``(F,)`` bool: the face covers an opaque texel (its outline and interior, nearest texels).

    Examples:
        >>> op = np.zeros((8, 8), np.float32); op[0, 0] = 1.0  # only the top-left texel is opaque
        >>> tris = np.array([[[0.0, 1.0], [0.2, 1.0], [0.0, 0.8]], [[0.5, 0.5], [0.9, 0.5], [0.5, 0.1]]])
        >>> opaque_faces(tris, op).tolist()
        [True, False]
    """
    import cv2  # lazy: OpenCV is slow to import, and few steps need it

    h, w = opacity.shape
    solid = opacity >= 0.5
    px = np.stack([uv_tris[..., 0] * w - 0.5, (1.0 - uv_tris[..., 1]) * h - 0.5], -1)  # texel centres at integers
    lo = np.clip(np.floor(px.min(1)).astype(int), 0, [w - 1, h - 1])
    hi = np.clip(np.ceil(px.max(1)).astype(int), 0, [w - 1, h - 1])
    out = np.zeros(len(px), bool)
    for i in range(len(px)):
        (x0, y0), (x1, y1) = lo[i], hi[i]
        crop = solid[y0 : y1 + 1, x0 : x1 + 1]
        if not crop.any():
            continue
        m = np.zeros(crop.shape, np.uint8)
        pts = np.round((px[i] - (x0, y0)) * 16).astype(np.int32)[None]
        cv2.fillPoly(m, pts, 1, lineType=cv2.LINE_8, shift=4)
        cv2.polylines(m, pts, True, 1, lineType=cv2.LINE_8, shift=4)
        out[i] = bool(crop[m.astype(bool)].any())
    return out
