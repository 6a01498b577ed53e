"""OLAT reflectance fields rendered with Mitsuba 3 (kornia_ilum.synth.lightstage.olat).

All renders are tiny (32 x 32 pixels, an 8 x 8 mirror ball = 52 lights, 16 spp) and use hand-built sphere
subjects, so that the file runs in seconds and does not depend on the subject generator.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import mitsuba as mi
import numpy as np
import pytest
import torch

from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import (
    direction_to_mirror_ball,
    mirror_ball_directions,
    mirror_ball_pixel_index,
    mirror_ball_solid_angles,
    mirror_ball_valid,
)
from kornia_ilum.render import relight
from kornia_ilum.synth.lightstage.scene import PIVOT_RAISE, Camera, camera_transform, project_points
from kornia_ilum.synth.lightstage.materials import MITSUBA_VARIANTS, VARIANT_ENV, material_bsdf, select_mitsuba_variant
from kornia_ilum.synth.lightstage.olat import ReflectanceField, _icosphere, render_olat
from kornia_ilum.synth.lightstage.reference import _session, olat_envmap_basis, render_lighting

S = 8  # lighting size of the tests: 52 valid lights
ALBEDO = 0.7
CAM = Camera(fov_deg=40.0, distance=4.0, yaw_deg=0.0, pitch_deg=0.0, size=32)


def material(kind: str = "diffuse", albedo: float = ALBEDO, **kw: float) -> SimpleNamespace:
    return SimpleNamespace(kind=kind, albedo=(albedo, albedo, albedo), roughness=kw.get("roughness", 0.3),
                           specular=kw.get("specular", 0.5))


def sphere_subject(radius: float = 1.0, centre=(0.0, 0.0, 0.0), mat: SimpleNamespace | None = None,
                   landmarks: np.ndarray | None = None, subdivisions: int = 4, extra=()) -> SimpleNamespace:
    """A hand-built Subject: a sphere mesh (plus ``extra`` parts) with the subjects module's attributes."""
    v, f = _icosphere(subdivisions)
    v = v * radius + np.asarray(centre, dtype=np.float32)
    ball = SimpleNamespace(name="ball", vertices=v, faces=f, material=mat or material())
    if landmarks is None:  # the sphere's vertices, lowered so that the camera's pivot is the sphere's centre
        landmarks = v - np.array([0.0, PIVOT_RAISE * 2 * radius, 0.0], dtype=np.float32)
    return SimpleNamespace(seed=11, split="eval", skin_tone=4, parts=[ball, *extra], face_landmarks=landmarks,
                           params={})


@pytest.fixture(scope="module")
def variant() -> str:
    return select_mitsuba_variant()


def variants() -> list[str]:
    """The default variant and the scalar fallback (once if they are the same)."""
    return sorted({select_mitsuba_variant(), "scalar_rgb"})


@pytest.fixture(scope="module")
def white_sphere(variant: str) -> ReflectanceField:
    return render_olat(sphere_subject(), CAM, lighting_size=S, spp=16, variant=variant, threads=1, method="reference")


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


class TestCamera:
    def test_smoke(self) -> None:
        cam = Camera(30.0, 0.5, 10.0, -5.0, size=64)
        assert Camera(**cam.to_dict()) == cam

    @pytest.mark.parametrize(
        ("kwargs", "error", "match"),
        [
            ({"fov_deg": 0.0}, ValueCheckError, "fov_deg must be in"),
            ({"fov_deg": 180.0}, ValueCheckError, "fov_deg must be in"),
            ({"distance": -1.0}, ValueCheckError, "distance must be positive"),
            ({"yaw_deg": float("nan")}, ValueCheckError, "yaw_deg must be finite"),
            ({"pitch_deg": "up"}, TypeCheckError, "pitch_deg must be a number"),
            ({"size": 0}, ValueCheckError, "Camera.size must be positive"),
            ({"size": 2.5}, TypeCheckError, "Camera.size must be an int"),
        ],
    )
    def test_exception(self, kwargs: dict, error: type, match: str) -> None:
        args = {"fov_deg": 30.0, "distance": 1.0, "yaw_deg": 0.0, "pitch_deg": 0.0, **kwargs}
        with pytest.raises(error, match=match):
            Camera(**args)


class TestCameraTransform:
    def test_frontal(self) -> None:
        t = camera_transform(Camera(30.0, 2.0, 0.0, 0.0), (0.1, 0.2, 0.3))
        np.testing.assert_allclose(t[:3, :3], np.eye(3), atol=1e-12)
        np.testing.assert_allclose(t[:3, :3] @ [0.1, 0.2, 0.3] + t[:3, 3], [0.0, 0.0, -2.0], atol=1e-12)

    @pytest.mark.parametrize(
        ("yaw", "pitch", "toward_camera"),
        [(90.0, 0.0, (1.0, 0.0, 0.0)), (-90.0, 0.0, (-1.0, 0.0, 0.0)), (0.0, 90.0, (0.0, 1.0, 0.0))],
    )
    def test_orbit(self, yaw: float, pitch: float, toward_camera: tuple) -> None:
        """The subject point on the camera's side comes nearest: yaw toward +X, pitch from above."""
        t = camera_transform(Camera(30.0, 2.0, yaw, pitch), (0.0, 0.0, 0.0))
        np.testing.assert_allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(t[:3, :3] @ toward_camera + t[:3, 3], [0.0, 0.0, -1.0], atol=1e-12)

    def test_yaw_turns_face_left(self) -> None:
        """Positive yaw: the subject's nose (+Z) turns toward the image's left (-X)."""
        t = camera_transform(Camera(30.0, 2.0, 30.0, 0.0), (0.0, 0.0, 0.0))
        assert (t[:3, :3] @ [0.0, 0.0, 1.0])[0] < -0.4


class TestProjectPoints:
    def test_smoke(self) -> None:
        cam = Camera(90.0, 1.0, 0.0, 0.0, size=100)
        xy = project_points(np.array([[0.0, 0.0, 0.0], [0.5, 0.5, 0.0], [-1.0, -1.0, 0.0]]), cam,
                            camera_transform(cam, (0.0, 0.0, 0.0)))
        torch.testing.assert_close(xy, torch.tensor([[50.0, 50.0], [75.0, 25.0], [0.0, 100.0]]))

    def test_exception(self) -> None:
        cam = Camera(60.0, 1.0, 0.0, 0.0)
        t = camera_transform(cam, (0.0, 0.0, 0.0))
        with pytest.raises(ValueCheckError, match="in front of the camera"):
            project_points(np.array([[0.0, 0.0, 2.0]]), cam, t)
        with pytest.raises(ShapeError, match=r"points must have shape \(K, 3\)"):
            project_points(np.zeros((4, 2)), cam, t)

    def test_matches_render(self, variant: str) -> None:
        """A small ball off the pivot, seen from an orbit, lands where project_points puts its centre."""
        pivot_marks = 0.2 * _icosphere(1)[0]  # landmarks around the origin; not rendered
        centre = (0.3, 0.25, 0.1)
        subject = sphere_subject(radius=0.03, centre=centre, landmarks=pivot_marks, subdivisions=2)
        cam = Camera(40.0, 2.0, 30.0, 15.0, size=64)
        rf = render_olat(subject, cam, lighting_size=2, spp=16, variant=variant, threads=1)
        alpha = rf.alpha[0]
        yy, xx = torch.meshgrid(torch.arange(64.0) + 0.5, torch.arange(64.0) + 0.5, indexing="ij")
        centroid = torch.stack([(alpha * xx).sum(), (alpha * yy).sum()]) / alpha.sum()
        pivot = (0.0, PIVOT_RAISE * 0.4, 0.0)  # the landmark box is 0.4 high, centred at the origin
        expected = project_points(np.array([centre]), cam, camera_transform(cam, pivot))[0]
        assert torch.dist(centroid, expected) < 0.3
        box = project_points(pivot_marks, cam, camera_transform(cam, pivot))
        torch.testing.assert_close(rf.face_box, torch.cat([box.min(0).values, box.max(0).values]))
        torch.testing.assert_close(torch.tensor(rf.meta["landmarks"]), box, atol=1e-3, rtol=0)


class TestOlatEnvmapBasis:
    def test_cardinality(self) -> None:
        basis, valid = olat_envmap_basis(S, 4 * S)
        assert basis.shape == (4 * S * 8 * S, S * S)
        np.testing.assert_array_equal(valid, np.flatnonzero(mirror_ball_valid(S).flatten().numpy()))

    def test_partition_of_unity(self) -> None:
        """Every texel is shared out among the lights: the lights sum to a uniform white environment."""
        basis, valid = olat_envmap_basis(S, 4 * S)
        np.testing.assert_allclose(np.asarray(basis.sum(axis=1)).ravel(), 1.0, atol=1e-12)
        invalid = np.setdiff1d(np.arange(S * S), valid)
        assert basis[:, invalid].nnz == 0
        assert basis.min() >= 0.0

    @pytest.mark.parametrize("height", [4 * S, 8 * S])
    def test_solid_angles(self, height: int) -> None:
        """Each light emits from its mirror-ball pixel's exact solid angle (bilinear texel tents, closed form)."""
        basis, valid = olat_envmap_basis(S, height)
        d = math.pi / (height - 1)
        theta = np.arange(height) * d
        tent = np.sin(theta) * 2 * (1 - math.cos(d)) / d  # int (1 - |t| / d) sin(theta + t) dt
        tent[[0, -1]] = 1 - math.sin(d) / d
        texel = np.repeat(tent * (2 * math.pi / (2 * height)), 2 * height)
        emitted = basis.T @ texel
        omega = mirror_ball_solid_angles(S, dtype=torch.float64).flatten().numpy()
        np.testing.assert_allclose(emitted[valid], omega[valid], rtol=1e-2)  # measured 0.53 % (0.35 % at S = 32)

    def test_exception(self) -> None:
        with pytest.raises(ValueCheckError, match="height must be at least 3"):
            olat_envmap_basis(S, 2)
        with pytest.raises(ValueCheckError, match="lighting_size must be positive"):
            olat_envmap_basis(0, 16)


def emitter_values(session, dirs: np.ndarray) -> np.ndarray:
    """Radiance of the session's envmap arriving from camera-frame directions ``(M, 3)`` (red channel)."""
    env = session.scene.environment()
    if session.variant.startswith("scalar"):
        out = []
        for d in dirs:
            si = mi.SurfaceInteraction3f()
            si.wi = mi.Vector3f(*(-d))
            out.append(np.asarray(env.eval(si))[0])
        return np.asarray(out)
    import drjit as dr

    si = dr.zeros(mi.SurfaceInteraction3f, len(dirs))
    si.wi = mi.Vector3f(*(-dirs.T))
    return np.asarray(env.eval(si))[0]  # (3, M): the red channel


class TestEnvmapFrame:
    @pytest.mark.parametrize("name", variants())
    def test_each_light_in_its_direction(self, name: str) -> None:
        """Mitsuba's envmap for light n is 1 at light n's direction (camera frame) and 0 at the others'."""
        session = _session(sphere_subject(subdivisions=1), CAM, S, 1, name, 4, 0, None, 1)
        d, valid = mirror_ball_directions(S, dtype=torch.float64)
        dirs = d.reshape(-1, 3)[valid.flatten()].numpy()
        rng = np.random.default_rng(0)
        rand = rng.normal(size=(64, 3))
        rand /= np.linalg.norm(rand, axis=1, keepdims=True)
        table, total = [], np.zeros(len(rand))
        for n in session.valid:
            session.set_texels(session.basis[:, n].toarray())
            table.append(emitter_values(session, dirs))
            total += emitter_values(session, rand)
        table = np.asarray(table)
        assert table.diagonal().min() > 0.98
        assert (table - np.diag(table.diagonal())).max() < 0.02
        np.testing.assert_allclose(total, 1.0, atol=1e-5)


class TestMaterialBsdf:
    @pytest.mark.parametrize("kind", ["skin", "diffuse", "glossy", "cornea", "hair"])
    def test_smoke(self, kind: str, variant: str) -> None:
        select_mitsuba_variant(variant)
        assert mi.load_dict(material_bsdf(material(kind))) is not None

    def test_roughness_is_ggx_alpha(self) -> None:
        bsdf = material_bsdf(material("skin", roughness=0.16, specular=0.35))
        assert bsdf["bsdf"]["roughness"] == pytest.approx(0.4)
        assert bsdf["bsdf"]["specular"] == 0.35

    def test_cornea_ior(self) -> None:
        """F0 = 0.08 specular: specular 0.3125 is the real cornea's F0 = 0.025, IOR 1.376."""
        bsdf = material_bsdf(material("cornea", specular=0.3125))
        assert bsdf["mirror"]["eta"] == pytest.approx(1.376, abs=2e-3)

    @pytest.mark.parametrize(
        ("mat", "match"),
        [
            (SimpleNamespace(kind="metal", albedo=(0.5, 0.5, 0.5)), "kind must be one of"),
            (SimpleNamespace(kind="skin", albedo=(1.5, 0.5, 0.5)), r"albedo must be 3 linear RGB values in \[0, 1\]"),
            (SimpleNamespace(kind="skin", albedo=(0.5, 0.5, 0.5), roughness=2.0), "roughness must be in"),
            (SimpleNamespace(kind="glossy", albedo=(0.5, 0.5, 0.5), specular=-1.0), "specular must be in"),
        ],
    )
    def test_exception(self, mat: SimpleNamespace, match: str) -> None:
        with pytest.raises(ValueCheckError, match=match):
            material_bsdf(mat)


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
        white, alpha = render_lighting(sphere_subject(), CAM, torch.ones(3, S, S), spp=16, variant=variant,
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
        """SPEC camera frame: +Y lights the top, +X the right as seen by the camera, +Z the front."""
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
        direct, _ = render_lighting(sphere_subject(), CAM, lighting, spp=16, variant=variant, threads=1)
        relit = relight(white_sphere.field, lighting.flatten(1).T[None])[0].flatten(1)
        fg = white_sphere.alpha.flatten() > 0
        assert relit[:, fg].mean() == pytest.approx(direct.flatten(1)[:, fg].mean().item(), rel=0.03)
        err = (relit - direct.flatten(1))[:, fg].pow(2).mean().sqrt() / direct.flatten(1)[:, fg].mean()
        assert err < 0.15  # measured 0.08 (16 spp, a bright light)

    def test_seed_reproducible(self, variant: str) -> None:
        subject = sphere_subject(subdivisions=2)
        cam = Camera(40.0, 4.0, 0.0, 0.0, size=16)
        a, b, c = (render_olat(subject, cam, lighting_size=4, spp=4, variant=variant, seed=s, lights=[5, 6])
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
        cornea = SimpleNamespace(name="cornea", vertices=1.1 * _icosphere(3)[0], faces=_icosphere(3)[1],
                                 material=material("cornea", albedo=1.0, roughness=0.0, specular=0.3125))
        lights = [27, 21]  # near +Z, and from the upper right
        bare = render_olat(sphere_subject(subdivisions=3), cam, lighting_size=S, spp=16, variant=variant,
                           lights=lights)
        capped = render_olat(sphere_subject(subdivisions=3, extra=[cornea]), cam, lighting_size=S, spp=16,
                             variant=variant, lights=lights)
        black = render_olat(sphere_subject(subdivisions=3, mat=material(albedo=0.0), extra=[cornea]), cam,
                            lighting_size=S, spp=16, variant=variant, lights=lights)
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
        kw = {"lighting_size": S, "spp": 16, "variant": variant, "lights": [27]}  # 27: near +Z
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
            render_olat(subject, CAM, lighting_size=4, lights=[0], variant=variant)
        with pytest.raises(ValueCheckError, match="spp must be positive"):
            render_olat(subject, CAM, spp=0, variant=variant)
        with pytest.raises(ValueCheckError, match="variant must be one of"):
            render_olat(subject, CAM, lighting_size=2, variant="cpu_fast_rgb")
        with pytest.raises(ValueCheckError, match="lighting must be non-negative"):
            render_lighting(subject, CAM, -torch.ones(3, 4, 4), variant=variant)
        with pytest.raises(ShapeError, match=r"lighting must have shape \(3, S, S\)"):
            render_lighting(subject, CAM, torch.ones(3, 4, 5), variant=variant)


class TestSelectMitsubaVariant:
    def test_smoke(self) -> None:
        assert select_mitsuba_variant() in MITSUBA_VARIANTS
        assert mi.variant() in MITSUBA_VARIANTS

    def test_environment_variable(self, monkeypatch: pytest.MonkeyPatch) -> None:
        monkeypatch.setenv(VARIANT_ENV, "scalar_rgb")
        assert select_mitsuba_variant() == "scalar_rgb" == mi.variant()

    def test_exception(self) -> None:
        with pytest.raises(ValueCheckError, match="variant must be one of"):
            select_mitsuba_variant("scalar_xyz")
