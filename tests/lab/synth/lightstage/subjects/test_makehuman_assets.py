"""The MakeHuman asset readers (kornia_ilum_lab.synth.lightstage.subjects.makehuman_assets) against the files."""

from __future__ import annotations

import numpy as np
import pytest

from kornia_ilum_lab.synth.lightstage.subjects.makehuman_assets import (
    bind_proxy,
    macro_target_weights,
    read_mhclo,
    read_target,
)

def _base_vertices_from_text(path) -> np.ndarray:
    rows = [line.split()[1:4] for line in open(path) if line.startswith("v ")]
    return np.array(rows, dtype=np.float64)

def test_target_application_matches_file_text(mh):
    a = mh.assets
    path = a.target_files["nose-trans-up"]
    lines = [ln.split() for ln in open(path) if ln.strip() and not ln.startswith("#")]
    picks = [lines[0], lines[len(lines) // 2], lines[-1]]
    idx, d = read_target(path)
    w = 0.37
    v = a.base.vertices.copy()
    v[idx] += w * d
    base = _base_vertices_from_text(a.root / "3dobjs" / "base.obj")
    for tok in picks:
        i = int(tok[0])
        expected = base[i] + w * np.array([float(t) for t in tok[1:4]])
        np.testing.assert_allclose(v[i], expected, atol=1e-6)
    untouched = np.setdiff1d(np.arange(len(base)), idx)[:50]
    np.testing.assert_array_equal(v[untouched], base[untouched])

def test_macro_weight_formula():
    # age 0.5 (25 y): young only; female 0.3 of gender 0.7; ethnic normalised.
    w = macro_target_weights((1.0, 1.0, 2.0), gender=0.7, age=0.5, muscle=0.5, weight=0.5)
    assert w["caucasian-male-young"] == pytest.approx(0.5 * 0.7)
    assert w["african-female-young"] == pytest.approx(0.25 * 0.3)
    assert not any(k.endswith("-old") or k.endswith("-child") for k in w if not k.startswith("universal"))
    assert w["universal-male-young-averagemuscle-averageweight"] == pytest.approx(0.7)
    # age 0.75 (57.5 y): old = 0.5, young = 0.5; muscle 0.75 -> average 0.5, max 0.5; weight 0.2 -> min 0.6.
    w = macro_target_weights((0.0, 1.0, 0.0), gender=1.0, age=0.75, muscle=0.75, weight=0.2)
    assert w["asian-male-old"] == pytest.approx(0.5) and w["asian-male-young"] == pytest.approx(0.5)
    assert w["universal-male-old-maxmuscle-minweight"] == pytest.approx(0.5 * 0.5 * 0.6)
    assert w["universal-male-young-averagemuscle-averageweight"] == pytest.approx(0.5 * 0.5 * 0.4)
    # age 0.3 (below 25 y): young = (0.3 - 0.1875) * 3.2 = 0.36, child = min(1, 1.6) - 0.36 = 0.64.
    w = macro_target_weights((0.0, 0.0, 1.0), gender=0.0, age=0.3)
    assert w["caucasian-female-young"] == pytest.approx(0.36)
    assert w["caucasian-female-child"] == pytest.approx(0.64)

def test_proxy_binding_formula(mh):
    a = mh.assets
    path = a.root / "eyebrows" / "eyebrow001" / "eyebrow001.mhclo"
    px = read_mhclo(path)
    v = a.base.vertices
    bound = bind_proxy(px, v)
    text = open(path).read().splitlines()
    sc = {ln.split()[0][0]: ln.split()[1:] for ln in text if ln.startswith(("x_scale", "y_scale", "z_scale"))}
    rows = text[[i for i, ln in enumerate(text) if ln.startswith("verts")][0] + 1 :]
    tok = rows[7].split()
    i, j, k = (int(t) for t in tok[:3])
    wi, wj, wk, dx, dy, dz = (float(t) for t in tok[3:9])
    s = [abs(v[int(sc[ax][0]), c] - v[int(sc[ax][1]), c]) / float(sc[ax][2]) for c, ax in enumerate("xyz")]
    expected = wi * v[i] + wj * v[j] + wk * v[k] + np.array([s[0] * dx, s[1] * dy, s[2] * dz])
    np.testing.assert_allclose(bound[7], expected, atol=1e-9)
    # An exact-copy line "i" gives V[i].
    px.refs[3] = 1234
    px.weights[3] = (1.0, 0.0, 0.0)
    px.offsets[3] = 0.0
    np.testing.assert_allclose(bind_proxy(px, v)[3], v[1234])

def test_exact_copy_line_parsed(tmp_path, mh):
    src = mh.root / "eyebrows" / "eyebrow001"
    lines = open(src / "eyebrow001.mhclo").read().splitlines()
    k = [i for i, ln in enumerate(lines) if ln.startswith("verts")][0] + 1
    lines[k] = "  4321"
    (tmp_path / "eyebrow001.mhclo").write_text("\n".join(lines))
    (tmp_path / "eyebrow001.obj").write_text((src / "eyebrow001.obj").read_text())
    px = read_mhclo(tmp_path / "eyebrow001.mhclo")
    np.testing.assert_allclose(bind_proxy(px, mh.assets.base.vertices)[0], mh.assets.base.vertices[4321])
