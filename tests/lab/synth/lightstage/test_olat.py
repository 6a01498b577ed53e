"""OLAT reflectance fields rendered with Mitsuba 3 (kornia_ilum_lab.synth.lightstage.olat.render_olat).

All renders are tiny (32 x 32 pixels, an 8 x 8 mirror ball = 52 lights, 16 spp) and use hand-built sphere
subjects (tests/synth/lightstage/spheres.py), so that the file runs in seconds and does not depend on the
subject generator. Every test renders with Mitsuba: the file is slow.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import direction_to_mirror_ball, mirror_ball_pixel_index, mirror_ball_valid
from kornia_ilum.render import relight
from kornia_ilum_lab.synth.lightstage.field import ReflectanceField
from kornia_ilum_lab.synth.lightstage.olat import render_olat
from kornia_ilum_lab.synth.lightstage.reference import render_lighting
from kornia_ilum_lab.synth.lightstage.scene import Camera
from kornia_ilum_lab.synth.lightstage.settings import Auto, OnePass, Reference
from kornia_ilum_lab.synth.lightstage.subjects.base import icosphere
from tests.lab.synth.lightstage.spheres import ALBEDO, CAM, S, material, sphere_subject

pytestmark = pytest.mark.slow

@pytest.fixture(scope="module")
def white_sphere(variant: str) -> ReflectanceField:
    return render_olat(sphere_subject(), CAM, settings=Reference(lighting_size=S, spp=16), variant=variant,
                       threads=1)

def covered(rf: ReflectanceField) -> torch.Tensor:
    """Pixels fully covered by the subject, ``(P,)`` bool."""
    return rf.alpha.flatten() == 1.0

def sphere_normals(camera: Camera, centre=(0.0, 0.0, -4.0), radius: float = 1.0) -> np.ndarray:
    """Unit normals ``(P, 3)`` where pixel-centre rays hit the sphere (NaN elsewhere)."""
    s, t = camera.size, math.tan(math.radians(camera.fov_deg) / 2)
    j, i = np.meshgrid(np.arange(s), np.arange(s))
    ray = np.stack([((j + 0.5) / s * 2 - 1) * t, (1 - (i + 0.5) / s * 2) * t, -np.ones((s, s))], -1)
    ray /= np.linalg.norm(ray, axis=-1, keepdims=True)
    c = np.asarray(centre)
    b = ray @ c
    disc = b**2 - (c @ c - radius**2)
    hit = ray * (b - np.sqrt(np.where(disc > 0, disc, np.nan)))[..., None]
    return ((hit - c) / radius).reshape(-1, 3)

def fibonacci_sphere(m: int) -> np.ndarray:
    k = np.arange(m) + 0.5
    z = 1 - 2 * k / m
    phi = math.pi * (1 + 5**0.5) * k
    r = np.sqrt(1 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)

class TestRenderOlat:
    def test_cardinality(self, white_sphere: ReflectanceField) -> None:
        rf = white_sphere
        assert rf.field.shape == (3, 32 * 32, S * S) and rf.field.dtype == torch.bfloat16
        assert rf.alpha.shape == (1, 32, 32) and rf.alpha.dtype == torch.float32
        assert rf.face_box.shape == (4,) and rf.size == 32 and rf.lighting_size == S
        invalid = ~mirror_ball_valid(S).flatten()
        assert rf.field[:, :, invalid].abs().max() == 0
        assert rf.field.min() >= 0 and 0 <= rf.alpha.min() and rf.alpha.max() == 1
        assert (rf.field.float().sum((0, 2)) > 0).reshape(32, 32).equal(rf.alpha[0] > 0)
        assert rf.meta["lights_rendered"] == 52 and rf.meta["integrator"] == "path"
        assert rf.meta["split"] == "eval" and rf.meta["skin_tone"] == 4 and rf.subject_seed == 11

    def test_white_environment_equals_sum(self, white_sphere: ReflectanceField, variant: str) -> None:
        """Relighting with a white environment equals a render under a uniform white environment."""
        white, alpha = render_lighting(sphere_subject(), CAM, lighting=torch.ones(3, S, S), spp=16,
                                       variant=variant,
                                       threads=1)
        torch.testing.assert_close(alpha, white_sphere.alpha)  # same seed: same sub-pixel positions
        summed = relight(white_sphere.field, torch.ones(1, S * S, 3))[0].flatten(1)
        fg = white_sphere.alpha.flatten() > 0
        assert summed[:, fg].mean() == pytest.approx(white.flatten(1)[:, fg].mean().item(), rel=0.01)
        assert (summed - white.flatten(1))[:, fg].pow(2).mean().sqrt() < 0.05 * ALBEDO  # measured 0.036

    def test_uniform_environment_analytic(self, white_sphere: ReflectanceField) -> None:
        """A Lambertian sphere of albedo a under a uniform unit environment reads a (no occlusion)."""
        summed = white_sphere.field.float().sum(-1)[:, covered(white_sphere)]
        assert summed.mean() == pytest.approx(ALBEDO, rel=0.01)  # measured 0.1 %
        assert (summed - ALBEDO).abs().max() < 0.12 * ALBEDO  # measured 6 % (16 spp)

    def test_single_light_analytic(self, white_sphere: ReflectanceField) -> None:
        """R[p, n] = a / pi * integral of max(0, N_p . w) over light n's solid angle, per light."""
        fg = covered(white_sphere).numpy()
        normals = sphere_normals(CAM)[fg]
        w = fibonacci_sphere(60000)
        owner = mirror_ball_pixel_index(direction_to_mirror_ball(torch.from_numpy(w)), S).numpy()
        cosine = np.maximum(normals @ w.T, 0.0).sum(0)  # summed over the covered pixels, per direction
        expected = ALBEDO / math.pi * np.bincount(owner, cosine * 4 * math.pi / len(w), minlength=S * S)
        measured = white_sphere.field[0][torch.from_numpy(fg)].float().sum(0).numpy()
        lit = expected > 0.05 * expected.max()
        assert lit.sum() > 25
        np.testing.assert_allclose(measured[lit], expected[lit], rtol=0.05)  # measured within 2.5 %
        assert measured.sum() == pytest.approx(expected.sum(), rel=0.01)

    @pytest.mark.parametrize(
        ("direction", "where"),
        [((0.0, 1.0, 0.3), "top"), ((0.0, -1.0, 0.3), "bottom"), ((1.0, 0.0, 0.3), "right"),
         ((-1.0, 0.0, 0.3), "left"), ((0.0, 0.0, 1.0), "centre"), ((0.0, 0.0, -1.0), "dark")],
    )
    def test_orientation(self, white_sphere: ReflectanceField, direction: tuple, where: str) -> None:
        """The camera frame of docs/conventions.rst: +Y lights the top, +X the right as seen by the camera, +Z
        the front."""
        n = int(mirror_ball_pixel_index(direction_to_mirror_ball(torch.tensor([direction])), S))
        img = white_sphere.field[0, :, n].float().reshape(32, 32)
        halves = {"top": (img[:16], img[16:]), "bottom": (img[16:], img[:16]), "right": (img[:, 16:], img[:, :16]),
                  "left": (img[:, :16], img[:, 16:]), "centre": (img[12:20, 12:20], img[:4])}
        if where == "dark":  # -Z belongs to the bottom rim pixel, from (0.12, -0.82, -0.56) at S = 8
            assert img[:14].max() == 0 and img[16:].sum() > 0
        else:
            lit, unlit = halves[where]
            assert lit.mean() > 4 * unlit.mean() + 1e-3

    def test_linearity(self, white_sphere: ReflectanceField, variant: str) -> None:
        """Relighting with any lighting matches a direct render under that lighting (light transport is linear)."""
        gen = torch.Generator().manual_seed(0)
        lighting = torch.rand(3, S, S, generator=gen) * mirror_ball_valid(S)
        lighting[:, 2, 3] += 20.0  # a bright light
        direct, _ = render_lighting(sphere_subject(), CAM, lighting=lighting, spp=16, variant=variant,
                                    threads=1)
        relit = relight(white_sphere.field, lighting.flatten(1).T[None])[0].flatten(1)
        fg = white_sphere.alpha.flatten() > 0
        assert relit[:, fg].mean() == pytest.approx(direct.flatten(1)[:, fg].mean().item(), rel=0.03)
        err = (relit - direct.flatten(1))[:, fg].pow(2).mean().sqrt() / direct.flatten(1)[:, fg].mean()
        assert err < 0.15  # measured 0.08 (16 spp, a bright light)

    def test_seed_reproducible(self, variant: str) -> None:
        subject = sphere_subject(subdivisions=2)
        cam = Camera(40.0, 4.0, 0.0, 0.0, size=16)
        a, b, c = (render_olat(subject, cam, variant=variant,
                               settings=Reference(lighting_size=4, spp=4, seed=s, lights=[5, 6]))
                   for s in (0, 0, 1))
        assert torch.equal(a.field, b.field) and torch.equal(a.alpha, b.alpha)
        assert not torch.equal(a.field, c.field)
        others = torch.ones(16, dtype=torch.bool)
        others[[5, 6]] = False
        assert a.field[:, :, others].abs().max() == 0 and a.meta["lights_rendered"] == 2

    def test_cornea(self, variant: str) -> None:
        """A clear cornea over a diffuse ball: the ball stays lit through it (shadow rays pass), and a black
        ball under it shows only small catch-lights of about F0."""
        cam = Camera(40.0, 4.0, 0.0, 0.0, size=32)
        cornea = SimpleNamespace(name="cornea", vertices=1.1 * icosphere(3)[0], faces=icosphere(3)[1],
                                 material=material("cornea", albedo=1.0, roughness=0.0, specular=0.3125))
        lights = [27, 21]  # near +Z, and from the upper right
        settings = Reference(lighting_size=S, spp=16, lights=lights)
        bare = render_olat(sphere_subject(subdivisions=3), cam, settings=settings, variant=variant)
        capped = render_olat(sphere_subject(subdivisions=3, extra=[cornea]), cam, settings=settings,
                             variant=variant)
        black = render_olat(sphere_subject(subdivisions=3, mat=material(albedo=0.0), extra=[cornea]), cam,
                            settings=settings, variant=variant)
        assert capped.meta["integrator"] == "volpath"
        ratio = capped.field[0, :, lights].float().sum(0) / bare.field[0, :, lights].float().sum(0)
        assert ((ratio > 0.93) & (ratio < 1.0)).all()  # (1 - F0)^2 = 0.95, plus catch-lights; measured 0.977
        glints = black.field[0, :, lights].float()
        assert (glints.amax(0) > 0.015).all() and glints.amax() < 0.05
        assert ((glints > 0.01).sum(0) < 30).all()

    def test_given_normals_shade(self, variant: str) -> None:
        """A part's own vertex normals are used: a ball whose normals all face the camera shades flat."""
        flat = sphere_subject(subdivisions=3)
        flat.parts[0].normals = np.tile(np.float32([0.0, 0.0, 1.0]), (len(flat.parts[0].vertices), 1))
        kw = {"settings": Reference(lighting_size=S, spp=16, lights=[27]), "variant": variant}  # 27: near +Z
        shaded = render_olat(sphere_subject(subdivisions=3), CAM, **kw).field[0, :, 27].float().reshape(32, 32)
        flat_img = render_olat(flat, CAM, **kw).field[0, :, 27].float().reshape(32, 32)
        rim, centre = (slice(15, 17), slice(24, 26)), (slice(15, 17), slice(15, 17))  # light 27 is upper left
        assert shaded[rim].mean() < 0.6 * shaded[centre].mean()
        assert flat_img[rim].mean() == pytest.approx(flat_img[centre].mean().item(), rel=0.1)

    def test_exception(self, variant: str) -> None:
        subject = sphere_subject(subdivisions=1)
        with pytest.raises(TypeCheckError, match="camera must be a Camera"):
            render_olat(subject, (30.0, 1.0, 0.0, 0.0), variant=variant)
        bad = sphere_subject(subdivisions=1)
        bad.parts[0].faces = bad.parts[0].faces + 1000
        with pytest.raises(ValueCheckError, match=r"faces must index its"):
            render_olat(bad, CAM, variant=variant)
        bad.parts[0].vertices = np.zeros((4, 2))
        with pytest.raises(ShapeError, match=r"vertices must have shape \(V, 3\)"):
            render_olat(bad, CAM, variant=variant)
        bad = sphere_subject(subdivisions=1)
        bad.parts[0].normals = np.zeros((3, 3))
        with pytest.raises(ShapeError, match="normals must be None or finite with the shape of its vertices"):
            render_olat(bad, CAM, variant=variant)
        with pytest.raises(ValueCheckError, match="parts must be a non-empty list"):
            render_olat(SimpleNamespace(seed=0, parts=[], face_landmarks=np.zeros((1, 3))), CAM, variant=variant)
        with pytest.raises(ValueCheckError, match="kind must be one of"):
            render_olat(sphere_subject(mat=SimpleNamespace(kind="chrome", albedo=(1, 1, 1))), CAM, variant=variant)
        with pytest.raises(ValueCheckError, match="lights must be valid light indices"):
            render_olat(subject, CAM, settings=Reference(lighting_size=4, lights=[0]), variant=variant)
        with pytest.raises(ValueCheckError, match="spp must be positive"):
            render_olat(subject, CAM, settings=Auto(spp=0), variant=variant)
        with pytest.raises(ValueCheckError, match="variant must be one of"):
            render_olat(subject, CAM, settings=Auto(lighting_size=2), variant="cpu_fast_rgb")
        with pytest.raises(TypeCheckError, match="settings must be OnePass, Reference or Auto"):
            render_olat(subject, CAM, settings={"spp": 4}, variant=variant)
        with pytest.raises(ValueCheckError, match="lighting must be non-negative"):
            render_lighting(subject, CAM, lighting=-torch.ones(3, 4, 4), variant=variant)
        with pytest.raises(ShapeError, match=r"lighting must have shape \(3, S, S\)"):
            render_lighting(subject, CAM, lighting=torch.ones(3, 4, 5), variant=variant)

class TestDispatch:
    def test_auto_picks_the_renderer_of_the_variant(self, variant: str) -> None:
        """Auto renders what OnePass (vectorised variant) or Reference (scalar) renders, bit for bit."""
        subject, cam = sphere_subject(subdivisions=2), Camera(40.0, 4.0, 0.0, 0.0, size=8)
        auto = render_olat(subject, cam, settings=Auto(lighting_size=4, spp=4), variant=variant, threads=1)
        resolved = Auto(lighting_size=4, spp=4).resolve(variant)
        direct = render_olat(subject, cam, settings=resolved, variant=variant, threads=1)
        assert torch.equal(auto.field, direct.field) and torch.equal(auto.alpha, direct.alpha)
        method = "onepass" if isinstance(resolved, OnePass) else "reference"
        assert auto.meta.get("method", "reference") == method
        scalar = render_olat(subject, cam, settings=Auto(lighting_size=4, spp=4), variant="scalar_rgb")
        assert "method" not in scalar.meta and scalar.meta["integrator"] == "path"  # the reference

    def test_onepass_needs_a_vectorised_variant(self) -> None:
        with pytest.raises(ValueCheckError, match="vectorised Mitsuba variant"):
            render_olat(sphere_subject(subdivisions=1), CAM, settings=OnePass(lighting_size=2),
                        variant="scalar_rgb")
