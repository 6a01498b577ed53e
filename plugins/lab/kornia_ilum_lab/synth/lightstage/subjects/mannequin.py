r"""Synthetic subjects for the virtual light stage: diverse heads meshed from signed distance functions.

:func:`make_subject` turns a seed into a :class:`Subject`: a head with a face (forehead, brow ridge, cheeks and
cheekbones, nose with alae and nostrils, lips, jaw and chin), ears, neck and shoulders, eyes with a glossy
cornea, eyebrows, and for some subjects facial hair, head hair, a hat, glasses and earrings, over a shirt.
Every shape, expression and colour parameter is drawn from a generator seeded by the subject's seed, so a
seed always gives the same subject (to the bit), on any machine with the same numpy and scikit-image.

Construction:
    Each part is a signed distance function (:mod:`kornia_ilum_lab.synth.lightstage.sdf`: ellipsoids, capsules,
    warped ellipsoids, blended by polynomial smooth minima) meshed with :func:`skimage.measure.marching_cubes`
    on a narrow band of a regular grid: 2.5 mm for the head and neck, 1.5 mm for the ears (separate meshes
    that enter the head at their root), 1 mm for brows, glasses and teeth, 3 to 3.6 mm for hair and hats,
    2.3 to 2.7 mm for beards and necklines, 8 mm for the shirt's body. The eyes are surfaces of revolution
    (sclera, iris and pupil in one ball, following the gaze) under a closed cornea lens. The lips, the mouth's
    inside, stubble and buzz-cut hair are the triangles of the skin mesh inside their regions, so they share
    one surface. Hair, beards and eyebrows are shells (the scalp's or the skin's distance offset outwards by
    a thickness that tapers to their edges, intersected with a hairline, a beard outline or a brow band);
    hats are solids down to the scalp. Triangles buried inside another opaque part (the scalp under hair and
    hats, the insides of shells, the skin inside the shirt) are dropped (``cull_hidden``): every render is
    unchanged.

    Sampled per seed (:func:`subject_params`): head width, height and length, face length and width, jaw and
    chin width, chin projection, cheek fullness, cheekbones, brow ridge, forehead slope, nose length, width,
    projection, bridge height and tip lift, lip fullness, mouth width, eye spacing, size and canthal tilt,
    ear size and flare, neck and shoulder width, an overall scale; an expression (mouth opening, smile, brow
    raise, squint, gaze); skin tone, lip colour (sometimes lipstick), iris colour, hair style (bald, buzz,
    short, medium, long, afro, bun; fringe; receding hairline) and colour (black, browns, blonde, red, grey,
    white, dyed), eyebrow thickness, facial hair (stubble, moustache, goatee, beard, long beard), a beanie or
    a cap, glasses, earrings, and a crew, V-neck, turtleneck or collared shirt in a saturated or neutral
    colour. Styles and colours are drawn with plausible correlations (a ``masculinity`` shape axis drives the
    brow ridge, jaw, neck and facial-hair likelihood; ``age`` greys hair; iris and hair colours depend on the
    skin tone).

    Size: 140k triangles on average (100k to 190k); the build time is in docs/lightstage.rst, "Measured".

Skin tones (Monk Skin Tone scale):
    The skin's albedo follows the 10 tones of the Monk Skin Tone (MST) scale: :data:`SKIN_ALBEDO`, calibrated
    against measured facial skin colour (:mod:`~kornia_ilum_lab.synth.lightstage.subjects.skin`).

    A subject's tone is uniform over 1..10 (every tone equally often), and its albedo is the tone's, times a
    brightness factor ``exp(N(0, 0.08))`` (the normal draw clipped to +-0.12, so a subject stays
    within its tone's measured range) and a per-channel factor ``exp(N(0, 0.03))`` (clipped to 0.95).

Materials:
    :class:`Material` ``kind`` says how a renderer should shade a part:

    - ``"skin"``: diffuse ``albedo`` plus a dielectric specular lobe, GGX ``roughness`` (alpha) 0.35 to 0.5
      and principled ``specular`` 0.30 to 0.40 (F0 = 0.08 ``specular`` = 0.024 to 0.032, an index of refraction
      near 1.4, as measured for skin's oily layer, Weyrich et al. 2006). No subsurface scattering.
    - ``"diffuse"``: Lambertian (shirts, the mouth's inside, pupils).
    - ``"glossy"``: diffuse plus a specular lobe (plastic: glasses frames, caps, teeth, the moist sclera).
    - ``"hair"``: diffuse plus a broad specular lobe (a stand-in for a fibre BSDF).
    - ``"cornea"``: a smooth dielectric, index of refraction 1.376 (principled ``specular`` 0.313), clear
      (``albedo`` 1 is its transmittance): a closed lens over the iris, so the iris shows through and the
      light sources leave catch-lights. A renderer without dielectrics may shade it as a mirror-smooth coat.

Train / evaluation split:
    :func:`subject_split` is ``"eval"`` when the first 8 bytes of
    ``blake2b(f"kornia_ilum.lightstage.subject:{seed}")`` (little-endian) are 0 modulo 10, else ``"train"``:
    about 10% of seeds, fixed forever, disjoint by construction, and unrelated to the subject's appearance.

Convention:
    Metres, in the frame of docs/conventions.rst (+X right, +Y up, +Z toward the camera): the subject faces
    +Z, the eyes are at ``y = 0`` and ``z`` about 0.07, the top of the head is near ``y = 0.12`` and the
    shoulders near ``y = -0.22``. The subject's right eye is at ``-X`` (on the image's left).
"""

from __future__ import annotations

import math

import numpy as np

from kornia_ilum_lab.synth.lightstage.sdf import (
    bounded,
    capsule,
    edit_in_box,
    ellipsoid,
    mesh_sdf,
    smax,
    smin,
    sphere,
)
from kornia_ilum_lab.synth.lightstage.subjects.base import (
    FRAME_ALBEDO,
    GLASSES_FRAMES,
    SKIN_ALBEDO,
    Material,
    MeshPart,
    Subject,
    fabric_colour,
    frame_material,
    merge_meshes,
    pick,
    seed_digest,
    subject_split,
)

__all__ = ["MannequinSource", "make_subject", "subject_params"]

# --------------------------------------------------------------------------------------------------------
# Parameters
# --------------------------------------------------------------------------------------------------------

_HAIR_COLOURS = {  # linear RGB
    "black": (0.010, 0.009, 0.008),
    "dark_brown": (0.028, 0.017, 0.010),
    "brown": (0.070, 0.042, 0.021),
    "light_brown": (0.150, 0.095, 0.050),
    "blonde": (0.400, 0.290, 0.150),
    "platinum": (0.580, 0.530, 0.420),
    "auburn": (0.200, 0.055, 0.020),
    "ginger": (0.420, 0.140, 0.040),
    "grey": (0.300, 0.290, 0.280),
    "white": (0.580, 0.580, 0.560),
    "dyed_pink": (0.700, 0.100, 0.300),
    "dyed_blue": (0.030, 0.110, 0.550),
    "dyed_green": (0.040, 0.380, 0.120),
    "dyed_purple": (0.220, 0.040, 0.420),
    "dyed_red": (0.550, 0.020, 0.020),
}
_IRIS_COLOURS = {
    "dark_brown": (0.030, 0.014, 0.006),
    "brown": (0.080, 0.036, 0.012),
    "hazel": (0.120, 0.085, 0.030),
    "green": (0.070, 0.120, 0.055),
    "blue": (0.070, 0.130, 0.240),
    "grey": (0.140, 0.160, 0.180),
    "amber": (0.200, 0.100, 0.020),
}
def subject_params(seed: int) -> dict:
    """All the random choices of subject ``seed`` (shape, expression, appearance), without building meshes.

    This is :attr:`Subject.params` of ``make_subject(seed)``: cheap (well under a millisecond), for choosing
    subjects by skin tone, hair or accessories.

    Args:
        seed: the subject's seed (any int).

    Returns:
        A JSON-serialisable dict: ``skin_tone`` (1..10), shape multipliers (``head_width``, ``nose_length``,
        ...), expression (``mouth_open``, ``smile``, ``brow_raise``, ``squint``, gaze angles in radians),
        colours (linear RGB lists) and styles (``hair_style``, ``facial_hair``, ``hat``, ``glasses``, ...).

    Raises:
        TypeCheckError: ``seed`` is not an int.

    Examples:
        >>> p = subject_params(0)
        >>> p == subject_params(0), 1 <= p["skin_tone"] <= 10
        (True, True)
    """
    rng = np.random.default_rng(seed_digest(seed, "subject.params"))

    def n(mu: float, sigma: float, lo: float, hi: float) -> float:
        return float(np.clip(rng.normal(mu, sigma), lo, hi))

    def u(lo: float, hi: float) -> float:
        return float(rng.uniform(lo, hi))

    p: dict = {}
    tone = int(rng.integers(1, 11))
    masc = u(0.0, 1.0)  # a continuous shape axis: brow ridge, jaw, neck, facial-hair likelihood
    age = u(0.0, 1.0)  # 0 young adult .. 1 elderly: grey hair, receding hairline, fuller cheeks
    p.update(skin_tone=tone, masculinity=masc, age=age)
    # Shape (multipliers of the average head, or offsets in metres).
    p.update(
        scale=n(0.97 + 0.06 * masc, 0.03, 0.9, 1.1),
        head_width=n(1.0, 0.04, 0.9, 1.1),
        head_height=n(1.0, 0.035, 0.92, 1.08),
        head_length=n(1.0, 0.04, 0.9, 1.1),
        face_length=n(0.97, 0.045, 0.88, 1.1),
        face_width=n(1.0, 0.04, 0.9, 1.1),
        jaw_width=n(0.95 + 0.1 * masc, 0.05, 0.82, 1.15),
        chin_width=n(0.95 + 0.12 * masc, 0.1, 0.75, 1.25),
        chin_projection=n(0.0, 0.003, -0.007, 0.007),
        cheek_fat=u(0.0, 1.0) * (0.6 + 0.4 * age),
        cheekbones=u(0.0, 1.0),
        brow_ridge=float(np.clip(0.8 * masc + rng.normal(0.0, 0.2), 0.0, 1.0)),
        forehead_slope=u(-1.0, 1.0),
        nose_length=n(1.0, 0.08, 0.8, 1.25),
        nose_width=n(1.0, 0.12, 0.75, 1.35),
        nose_projection=n(1.0, 0.1, 0.75, 1.25),
        nose_bridge=n(1.0, 0.2, 0.5, 1.5),
        nose_tip_lift=n(0.0, 1.0, -2.0, 2.0),
        lip_fullness=n(1.0, 0.18, 0.65, 1.5),
        mouth_width=n(1.0, 0.07, 0.85, 1.18),
        eye_spacing=n(1.0, 0.04, 0.9, 1.1),
        eye_size=n(1.0, 0.06, 0.85, 1.15),
        eye_tilt=n(0.04, 0.05, -0.08, 0.15),
        ear_size=n(1.0, 0.07, 0.85, 1.2),
        ear_flare=u(0.1, 0.5),
        neck_width=n(0.95 + 0.1 * masc, 0.05, 0.85, 1.2),
        shoulder_width=n(0.95 + 0.1 * masc, 0.05, 0.85, 1.15),
    )
    # Expression.
    p.update(
        mouth_open=u(0.0, 1.0) if rng.random() < 0.3 else 0.0,
        smile=u(0.0, 1.0) if rng.random() < 0.5 else 0.0,
        brow_raise=n(0.0, 0.4, -0.6, 1.0),
        squint=u(0.0, 1.0) if rng.random() < 0.35 else 0.0,
        gaze_yaw=n(0.0, 0.1, -0.25, 0.25),
        gaze_pitch=n(0.0, 0.07, -0.2, 0.2),
    )
    # Skin and lips.
    base = np.array(SKIN_ALBEDO[tone - 1])
    skin = base * math.exp(float(np.clip(rng.normal(0.0, 0.08), -0.12, 0.12))) * np.exp(rng.normal(0.0, 0.03, 3))
    p["skin_albedo"] = [round(float(c), 4) for c in np.clip(skin, 0.003, 0.95)]
    p["skin_roughness"] = u(0.35, 0.5)
    p["skin_specular"] = u(0.30, 0.40)
    lip_tint = np.array([0.80, 0.55, 0.58]) if tone <= 6 else np.array([0.95, 0.75, 0.75])
    lips = skin * lip_tint * math.exp(rng.normal(0.0, 0.1))
    p["lipstick"] = bool(rng.random() < 0.1 * (1.0 - masc) + 0.02)
    if p["lipstick"]:
        lips = np.array(
            [(0.45, 0.02, 0.04), (0.50, 0.08, 0.20), (0.12, 0.01, 0.04), (0.30, 0.06, 0.05)][rng.integers(4)]
        )
    p["lip_albedo"] = [round(float(c), 4) for c in np.clip(lips, 0.003, 0.95)]
    # Eyes.
    dark = tone >= 6
    iris = pick(
        rng,
        {"dark_brown": 6, "brown": 3, "hazel": 1, "amber": 0.3}
        if dark
        else {"dark_brown": 2, "brown": 3, "hazel": 2, "green": 1.5, "blue": 2.5, "grey": 1, "amber": 0.3},
    )
    p["iris"] = iris
    # Hair.
    grey_p = max(0.0, age - 0.55) * 1.6
    if rng.random() < grey_p:
        colour = pick(rng, {"grey": 3, "white": 1})
    elif rng.random() < 0.08:
        colour = pick(rng, {k: 1.0 for k in _HAIR_COLOURS if k.startswith("dyed")} | {"platinum": 1.0})
    elif dark:
        colour = pick(rng, {"black": 6, "dark_brown": 3, "brown": 0.5, "blonde": 0.15})
    else:
        colour = pick(
            rng,
            {
                "black": 1.5,
                "dark_brown": 3,
                "brown": 3,
                "light_brown": 2,
                "blonde": 2,
                "auburn": 0.8,
                "ginger": 0.6,
            },
        )
    p["hair_colour"] = colour
    natural = (
        colour
        if not (colour.startswith("dyed") or colour == "platinum")
        else ("black" if dark else pick(rng, {"dark_brown": 1.0, "brown": 1.0}))
    )
    p["beard_colour"] = natural
    bald_p = 0.05 + 0.35 * masc * age
    p["hair_style"] = (
        "bald"
        if rng.random() < bald_p
        else pick(
            rng,
            {
                "buzz": 1.0 + masc,
                "short": 2.0 + 2 * masc,
                "medium": 2.0 - masc,
                "long": 3.0 * (1.0 - masc) + 0.3,
                "afro": 0.8 + 1.2 * (tone >= 7),
                "bun": 1.0 * (1.0 - masc) + 0.1,
            },
        )
    )
    p["hair_volume"] = u(0.0, 1.0)
    p["fringe"] = bool(p["hair_style"] in ("medium", "long") and rng.random() < 0.35)
    p["hair_recession"] = float(np.clip(masc * age * 1.5 * rng.random(), 0.0, 1.0))
    p["brow_thickness"] = n(1.0 - 0.2 * (1 - masc), 0.2, 0.5, 1.5)
    fh_p = 0.6 * masc**2
    p["facial_hair"] = (
        pick(rng, {"stubble": 1.0, "moustache": 0.5, "goatee": 0.6, "beard": 1.0, "long_beard": 0.3})
        if (rng.random() < fh_p)
        else "none"
    )
    p["beard_thickness"] = u(0.003, 0.011)
    # Accessories and clothes.
    p["hat"] = pick(rng, {"none": 8.0, "beanie": 1.0, "cap": 1.0})
    p["hat_colour"], p["hat_albedo"] = fabric_colour(rng, 0.6)
    if p["hat"] != "none" and p["hair_style"] in ("medium", "afro", "bun"):
        p["hair_style"] = "short"  # what shows of such hair under a hat
    p["glasses"] = bool(rng.random() < 0.2)
    frame = pick(rng, GLASSES_FRAMES)
    p["glasses_frame"] = frame
    p["glasses_albedo"] = FRAME_ALBEDO.get(frame) or fabric_colour(rng, 1.0)[1]
    p["earrings"] = bool(rng.random() < 0.2 * (1.0 - masc) + 0.03)
    p["earring_style"] = pick(rng, {"stud": 1.0, "hoop": 1.0})
    p["earring_albedo"] = [(0.75, 0.55, 0.22), (0.62, 0.62, 0.62), (0.55, 0.05, 0.08)][int(rng.integers(3))]
    p["shirt_style"] = pick(rng, {"crew": 3, "vneck": 2, "turtleneck": 1, "collar": 1.5})
    p["shirt_colour"], p["shirt_albedo"] = fabric_colour(rng, 0.5)
    return p


# --------------------------------------------------------------------------------------------------------
# Geometry
# --------------------------------------------------------------------------------------------------------


def _bounded_ellipsoid(x, y, z, *, c, r, margin: float):
    """An ellipsoid evaluated only near its bounding box (:func:`~kornia_ilum_lab.synth.lightstage.sdf.bounded`)."""
    lo = [c[i] - r[i] for i in range(3)]
    hi = [c[i] + r[i] for i in range(3)]
    return bounded(lambda a, b, cc: ellipsoid(a, b, cc, c=c, r=r), x, y, z, lo=lo, hi=hi, margin=margin)


def _warp_arch(x: np.ndarray, z: np.ndarray, radius: float) -> np.ndarray:
    """``z`` measured from a parabolic arch ``z = -x^2 / (2 radius)`` (the dental arch, a frame's wrap)."""
    return z + x * x / (2.0 * radius)


class _Head:
    """The signed distance functions of one head, in the unscaled frame (eyes at y = 0)."""

    def __init__(self, p: dict) -> None:
        self.p = p
        hw, hh, hl = p["head_width"], p["head_height"], p["head_length"]
        fl, fw, jw = p["face_length"], p["face_width"], p["jaw_width"]
        fat = p["cheek_fat"]
        self.d_open = 0.011 * p["mouth_open"]
        d = self.d_open
        sm = p["smile"]
        # Cranium and forehead.
        self.cranium = ((0.0, 0.028, -0.014), (0.073 * hw, 0.090 * hh, 0.099 * hl))
        fs = p["forehead_slope"]
        self.forehead = ((0.0, 0.040 + 0.004 * fs, 0.030 - 0.006 * fs), (0.062 * hw, 0.052, 0.056))
        # Eyes.
        self.eye_r = 0.012
        ex = 0.0315 * p["eye_spacing"]
        self.eyes = [(-ex, 0.0, 0.066), (ex, 0.0, 0.066)]
        self.lid_r = self.eye_r + 0.0018
        # Brow ridge.
        br = p["brow_ridge"]
        ry = 0.003 * p["brow_raise"]
        self.brows = [((s * 0.030, 0.017 + ry, 0.071 + 0.004 * br), (0.026, 0.0095, 0.016)) for s in (-1, 1)]
        self.glabella = ((0.0, 0.013 + ry, 0.077 + 0.004 * br), (0.013, 0.012, 0.012))
        # Cheeks and cheekbones.
        self.cheeks = [
            ((s * 0.036 * fw, -0.030 * fl + 0.005 * sm, 0.054 + 0.003 * sm),
             (0.030 + 0.008 * fat, 0.032, 0.032 + 0.006 * fat)) for s in (-1, 1)
        ]  # fmt: skip
        cb = p["cheekbones"]
        self.cheekbones = [
            ((s * (0.050 + 0.003 * cb) * fw, -0.006, 0.046), (0.022, 0.013, 0.024)) for s in (-1, 1)
        ]
        # Lower face, jaw and chin.
        self.lower_face = (
            (0.0, -0.050 * fl - d / 2, 0.025),
            (0.050 * jw + 0.004 * fat, 0.068 * fl + d / 2, 0.066),
        )
        self.muzzle = ((0.0, -0.066 * fl - d / 3, 0.060), (0.034, 0.032 * fl + d / 3, 0.034))
        cw = p["chin_width"]
        cz = 0.074 + p["chin_projection"]
        self.chin = ((0.0, -0.102 * fl - d, cz - 0.3 * d), (0.017 * cw, 0.016, 0.015))
        self.gonion = [(s * 0.046 * jw, -0.080 * fl - 0.5 * d, -0.010) for s in (-1, 1)]
        self.chin_side = [(s * 0.016 * cw, -0.106 * fl - d, cz - 0.008 - 0.3 * d) for s in (-1, 1)]
        self.ramus_top = [(s * 0.052 * jw, -0.030, -0.018) for s in (-1, 1)]
        # Nose.
        nl, nw, npj = p["nose_length"], p["nose_width"], p["nose_projection"]
        self.nasion = (0.0, 0.008, 0.081 + 0.003 * (p["nose_bridge"] - 1.0))
        tip_y = -0.031 * fl * nl + 0.002 * p["nose_tip_lift"]
        self.tip = (0.0, tip_y, 0.086 + 0.026 * npj)
        self.nose_w = nw
        # Mouth.
        self.sto_y = -0.068 * fl
        self.mouth_z = 0.095
        self.mouth_w = 0.050 * p["mouth_width"] * (1.0 + 0.12 * sm)
        self.lip_f = p["lip_fullness"]
        # Neck.
        self.neck_r = 0.054 * p["neck_width"]
        self.neck = ((0.0, -0.070, -0.024), (0.0, -0.36, -0.010))
        # Ears.
        self.ear_size = p["ear_size"]
        self.ear_root = [(s * 0.067 * hw, -0.006, -0.006) for s in (-1, 1)]
        self.shoulder_w = p["shoulder_width"]

    # ---- pieces --------------------------------------------------------------------------------------

    def cranium_sdf(self, x, y, z):
        c = ellipsoid(x, y, z, c=self.cranium[0], r=self.cranium[1])
        return smin(c, ellipsoid(x, y, z, c=self.forehead[0], r=self.forehead[1]), 0.02)

    def _eye_local(self, x, y, z, side: int):
        """Eye-centred angular coordinates: (radius, azimuth toward the temple, elevation)."""
        e = self.eyes[side]
        lx = (x - e[0]) * (1.0 if side == 1 else -1.0)
        ly, lz = y - e[1], z - e[2]
        rho = np.sqrt(lx * lx + ly * ly + lz * lz)
        az = np.arctan2(lx, lz)
        el = np.arctan2(ly, np.sqrt(lx * lx + lz * lz))
        return rho, az, el

    def aperture(self, x, y, z, side: int):
        """Negative inside the palpebral fissure's cone (an angular distance times the radius)."""
        p = self.p
        rho, az, el = self._eye_local(x, y, z, side)
        es = p["eye_size"]
        a_med, a_lat = -0.95 * es, 1.0 * es
        ac, half = 0.5 * (a_lat + a_med), 0.5 * (a_lat - a_med)
        t = (az - ac) / half
        tc = np.clip(t, -1.0, 1.0)
        centre = p["eye_tilt"] * tc - 0.02
        up = 0.37 * es * (1.0 - 0.35 * p["squint"] + 0.12 * p["brow_raise"])
        low = 0.25 * es * (1.0 - 0.45 * p["squint"] - 0.2 * p["smile"])
        w = 1.0 - tc * tc
        e_up = centre + up * w**0.6 * (1.0 - 0.15 * tc)
        e_lo = centre - low * w**0.8 * (1.0 + 0.2 * tc)
        g = np.maximum(np.maximum(el - e_up, e_lo - el), (np.abs(t) - 1.0) * half * 0.6)
        return g * np.maximum(rho, 0.005)

    def eyelids(self, x, y, z, face):
        """Carve the orbits and add the lids: a ball around each eye, open along the palpebral fissure."""
        for side in (0, 1):
            e = self.eyes[side]
            sg = -1.0 if side == 0 else 1.0

            def edit(d, x, y, z, *, e=e, sg=sg, side=side):
                socket = ellipsoid(
                    x, y, z, c=(e[0] + sg * 0.001, e[1] + 0.002, e[2] + 0.010), r=(0.019, 0.0155, 0.011)
                )
                d = smax(d, -socket, 0.006)
                ap = self.aperture(x, y, z, side)
                lid = smax(sphere(x, y, z, c=e, r=self.lid_r), -ap, 0.001)
                d = smin(d, lid, 0.003)
                return np.maximum(d, -np.maximum(ap, sphere(x, y, z, c=e, r=self.lid_r + 0.003)))

            lo = (e[0] - 0.032, e[1] - 0.03, e[2] - 0.02)
            hi = (e[0] + 0.032, e[1] + 0.032, e[2] + 0.04)
            face = edit_in_box(face, x, y, z, lo=lo, hi=hi, fn=edit)
        return face

    def nose(self, x, y, z):
        n, t, nw = self.nasion, self.tip, self.nose_w
        tip_back = (0.0, t[1] + 0.002, t[2] - 0.007)
        d = capsule(x, y, z, a=n, b=tip_back, ra=0.0052, rb=0.0068)
        side = ellipsoid(
            x,
            y,
            z,
            c=(0.0, 0.5 * (n[1] + t[1]) - 0.004, 0.5 * (n[2] + t[2]) - 0.006),
            r=(0.012 * nw, 0.5 * (n[1] - t[1]) + 0.004, 0.013),
        )
        d = smin(d, side, 0.006)
        d = smin(d, ellipsoid(x, y, z, c=(0.0, t[1], t[2] - 0.0085), r=(0.0095 * nw, 0.0085, 0.0088)), 0.004)
        for s in (-1, 1):
            ala = ellipsoid(
                x, y, z, c=(s * 0.0135 * nw, t[1] - 0.005, t[2] - 0.019), r=(0.0072, 0.0068, 0.0075)
            )
            d = smin(d, ala, 0.003)
        colum = ellipsoid(x, y, z, c=(0.0, t[1] - 0.009, t[2] - 0.012), r=(0.0055, 0.004, 0.010))
        return smin(d, colum, 0.003)

    def nostrils(self, d, x, y, z):
        t, nw = self.tip, self.nose_w
        for s in (-1, 1):
            hole = ellipsoid(
                x, y, z, c=(s * 0.0068 * nw, t[1] - 0.0115, t[2] - 0.0145), r=(0.0038 * nw, 0.0026, 0.0068)
            )
            d = smax(d, -hole, 0.0012)
        return d

    def _lip_frame(self, x, y, z):
        """Coordinates relative to the mouth, bent along the dental arch and by the smile."""
        w = self.mouth_w
        u = np.clip(2.0 * x / w, -1.5, 1.5)
        ly = y - self.sto_y - 0.005 * self.p["smile"] * u * u
        lz = _warp_arch(x, z - self.mouth_z, 0.040)
        return x, ly, lz

    def lips(self, x, y, z):
        lx, ly, lz = self._lip_frame(x, y, z)
        f, w, d = self.lip_f, self.mouth_w, self.d_open
        upper = ellipsoid(lx, ly, lz, c=(0.0, 0.0042 * f, -0.0030), r=(0.5 * w, 0.0050 * f, 0.0075 * f))
        lower = ellipsoid(
            lx, ly, lz, c=(0.0, -0.0055 * f - d, -0.0045 - 0.3 * d), r=(0.46 * w, 0.0058 * f, 0.0080 * f)
        )
        return np.minimum(upper, lower)

    def mouth_cut(self, x, y, z):
        """The slit between the lips and, when open, the mouth's cavity (negative inside)."""
        lx, ly, lz = self._lip_frame(x, y, z)
        w, d = self.mouth_w, self.d_open
        slit = ellipsoid(lx, ly, lz, c=(0.0, -0.5 * d, -0.006), r=(0.51 * w, 0.0007 + 0.5 * d, 0.013))
        cavity = ellipsoid(lx, ly, lz, c=(0.0, -0.5 * d, -0.026), r=(0.024, 0.003 + 0.6 * d, 0.022))
        return np.minimum(slit, cavity)

    def teeth(self, x, y, z):
        lx, ly, lz = self._lip_frame(x, y, z)
        lz = _warp_arch(x, z - self.mouth_z, 0.026)
        d = self.d_open
        up = ellipsoid(lx, ly, lz, c=(0.0, 0.004, -0.0085), r=(0.019, 0.0055, 0.0035))
        lo = ellipsoid(lx, ly, lz, c=(0.0, -0.004 - d, -0.0095 - 0.3 * d), r=(0.017, 0.0045, 0.0032))
        return np.minimum(up, lo)

    def ear_frame(self, side: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[float, float, float]]:
        """The ear's axes (up, forward, outward) and root point."""
        sg = -1.0 if side == 0 else 1.0
        flare, beta = self.p["ear_flare"], 0.26
        n = np.array([sg * math.cos(flare), 0.0, math.sin(flare)])
        v0 = np.array([-sg * math.sin(flare), 0.0, math.cos(flare)])
        u0 = np.array([0.0, 1.0, 0.0])
        u = math.cos(beta) * u0 - math.sin(beta) * v0
        v = math.sin(beta) * u0 + math.cos(beta) * v0
        return u, v, n, self.ear_root[side]

    def ear(self, x, y, z, side: int):
        """An ear: a cartilage plate with a helix rim, an antihelix ridge, a concha bowl, a lobe and a tragus."""
        u, v, n, r = self.ear_frame(side)
        px, py, pz = x - r[0], y - r[1], z - r[2]
        lu = px * u[0] + py * u[1] + pz * u[2]
        lv = px * v[0] + py * v[1] + pz * v[2]
        ln = px * n[0] + py * n[1] + pz * n[2]
        es = self.ear_size
        u0, v0 = 0.004 * es, -0.014 * es
        a = 0.029 * es
        b = 0.0165 * es * (1.0 + 0.18 * np.clip((lu - u0) / a, -1.0, 1.0))
        q = np.sqrt(((lu - u0) / a) ** 2 + ((lv - v0) / b) ** 2)
        e2 = (q - 1.0) * b
        plate = smax(e2, np.abs(ln - 0.0015) - 0.0022, 0.001)
        rim = np.sqrt((e2 + 0.0024) ** 2 + (ln - 0.0042) ** 2) - 0.0026
        rim = smax(rim, (lv - v0) - 0.35 * b + 0.4 * (lu - u0 + 0.6 * a) * 0.0, 0.003)
        a2, b2 = 0.018 * es, 0.0095 * es
        q2 = np.sqrt(((lu - u0 - 0.003 * es) / a2) ** 2 + ((lv - v0 + 0.0005) / b2) ** 2)
        anti = np.sqrt(((q2 - 1.0) * b2) ** 2 + (ln - 0.0032) ** 2) - 0.0017
        anti = smax(anti, -(lu - u0 + 0.004 * es), 0.003)
        d = smin(plate, rim, 0.0015)
        d = smin(d, anti, 0.0015)
        concha = ellipsoid(
            lu, lv, ln, c=(u0 - 0.005 * es, v0 + 0.004 * es, 0.0068), r=(0.0105 * es, 0.0085 * es, 0.006)
        )
        d = smax(d, -concha, 0.0015)
        lobe = ellipsoid(
            lu, lv, ln, c=(u0 - 0.021 * es, v0 + 0.002 * es, 0.0028), r=(0.0095 * es, 0.0085 * es, 0.0045)
        )
        d = smin(d, lobe, 0.003)
        tragus = ellipsoid(
            lu, lv, ln, c=(u0 - 0.008 * es, v0 + 0.0125 * es, 0.0045), r=(0.005, 0.003, 0.0035)
        )
        d = smin(d, tragus, 0.0015)
        # The root, reaching into the head.
        root = ellipsoid(
            lu, lv, ln, c=(u0 - 0.004, v0 + 0.010 * es, -0.004), r=(0.020 * es, 0.008 * es, 0.006)
        )
        return smin(d, root, 0.003)

    def face(self, x, y, z):
        """Cranium, face and jaw, before eyes, nose, lips, ears and neck."""
        d = self.cranium_sdf(x, y, z)
        f = ellipsoid(x, y, z, c=self.lower_face[0], r=self.lower_face[1])
        f = smin(f, _bounded_ellipsoid(x, y, z, c=self.muzzle[0], r=self.muzzle[1], margin=0.03), 0.012)
        for c, r in self.cheeks:
            f = smin(f, _bounded_ellipsoid(x, y, z, c=c, r=r, margin=0.035), 0.015)
        for c, r in self.cheekbones:
            f = smin(f, _bounded_ellipsoid(x, y, z, c=c, r=r, margin=0.03), 0.012)
        for g, c, rt in zip(self.gonion, self.chin_side, self.ramus_top):
            lo = np.minimum(np.minimum(g, c), rt) - 0.012
            hi = np.maximum(np.maximum(g, c), rt) + 0.012

            def jaw(x, y, z, *, g=g, c=c, rt=rt):
                return smin(
                    capsule(x, y, z, a=g, b=c, ra=0.011, rb=0.010),
                    capsule(x, y, z, a=rt, b=g, ra=0.012, rb=0.011),
                    0.012,
                )

            f = smin(f, bounded(jaw, x, y, z, lo=lo, hi=hi, margin=0.03), 0.014)
        f = smin(f, _bounded_ellipsoid(x, y, z, c=self.chin[0], r=self.chin[1], margin=0.02), 0.01)
        d = smin(d, f, 0.022)

        def brow(x, y, z):
            b = ellipsoid(x, y, z, c=self.glabella[0], r=self.glabella[1])
            for c, r in self.brows:
                b = smin(b, ellipsoid(x, y, z, c=c, r=r), 0.01)
            return b

        b = bounded(brow, x, y, z, lo=(-0.058, -0.002, 0.05), hi=(0.058, 0.035, 0.095), margin=0.025)
        return smin(d, b, 0.012)

    def skin(self, x, y, z):
        """The skin surface of the head, face and neck (the ears are separate meshes), negative inside."""
        d = self.face(x, y, z)
        d = self.eyelids(x, y, z, d)
        t = self.tip
        nose = bounded(
            self.nose, x, y, z, lo=(-0.03, t[1] - 0.02, 0.06), hi=(0.03, 0.02, t[2] + 0.01), margin=0.02
        )
        d = smin(d, nose, 0.006)
        d = edit_in_box(
            d, x, y, z, lo=(-0.02, t[1] - 0.025, t[2] - 0.03), hi=(0.02, t[1], t[2] + 0.005), fn=self.nostrils
        )
        lo = (-0.04, self.sto_y - 0.02 - self.d_open, 0.07)
        hi = (0.04, self.sto_y + 0.02, 0.11)
        d = smin(d, bounded(self.lips, x, y, z, lo=lo, hi=hi, margin=0.02), 0.0025)
        d = smax(d, -bounded(self.mouth_cut, x, y, z, lo=(-0.04, lo[1], 0.05), hi=hi, margin=0.01), 0.0015)
        d = smin(d, self.neck_sdf(x, y, z), 0.012)
        return d

    def neck_sdf(self, x, y, z):
        """The neck, down into the shirt (and the chest inside a V neck)."""
        d = capsule(x, y, z, a=self.neck[0], b=self.neck[1], ra=self.neck_r)
        if self.p["shirt_style"] == "vneck":
            chest = ellipsoid(x, y, z, c=(0.0, -0.35, -0.008), r=(0.16 * self.shoulder_w, 0.13, 0.105))
            vee = np.maximum(np.abs(x) - 0.5 * (y + 0.285) - 0.015, -0.295 - y)  # only what the V shows
            d = smin(d, np.maximum(chest, vee), 0.02)
        return d

    def body(self, x, y, z):
        """Neck, shoulders and chest (the shirt's inside)."""
        return smin(
            capsule(x, y, z, a=self.neck[0], b=self.neck[1], ra=self.neck_r), self.torso(x, y, z), 0.035
        )

    def torso(self, x, y, z):
        """Shoulders and chest, without the neck."""
        sw = 0.175 * self.shoulder_w
        shoulders = capsule(x, y, z, a=(-sw, -0.232, -0.022), b=(sw, -0.232, -0.022), ra=0.052)
        chest = ellipsoid(x, y, z, c=(0.0, -0.35, -0.008), r=(0.16 * self.shoulder_w, 0.13, 0.105))
        trap = capsule(x, y, z, a=(-0.10, -0.205, -0.035), b=(0.10, -0.205, -0.035), ra=0.04)
        return smin(smin(shoulders, chest, 0.06), trap, 0.05)


def _revolve(profile: list[tuple[float, float]], segments: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A closed surface of revolution about +Z from a profile of ``(radius, z)`` points, from pole to pole.

    Returns ``(vertices, faces, band)``: ``band[f]`` is the profile segment that face ``f`` comes from.
    Faces are counter-clockwise seen from outside when the profile runs from the ``+z`` pole to the ``-z`` one.
    """
    phi = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    starts, verts = [], []
    n = 0
    for rad, zz in profile:
        starts.append(n)
        if rad <= 1e-9:
            verts.append(np.array([[0.0, 0.0, zz]]))
            n += 1
        else:
            verts.append(np.stack([rad * np.cos(phi), rad * np.sin(phi), np.full_like(phi, zz)], axis=1))
            n += segments
    j = np.arange(segments)
    k = (j + 1) % segments
    faces, band = [], []
    for i in range(len(profile) - 1):
        a0, b0 = starts[i], starts[i + 1]
        pa, pb = profile[i][0] <= 1e-9, profile[i + 1][0] <= 1e-9
        if pa and pb:
            continue
        if pa:
            f = np.stack([np.full(segments, a0), b0 + j, b0 + k], axis=1)
        elif pb:
            f = np.stack([a0 + j, np.full(segments, b0), a0 + k], axis=1)
        else:
            f = np.concatenate([np.stack([a0 + j, b0 + j, a0 + k], 1), np.stack([a0 + k, b0 + j, b0 + k], 1)])
        faces.append(f)
        band.append(np.full(len(f), i))
    return (
        np.concatenate(verts).astype(np.float32),
        np.concatenate(faces).astype(np.int32),
        np.concatenate(band),
    )


def _rotation_to(g: np.ndarray) -> np.ndarray:
    """A rotation whose third column is the unit vector ``g`` and whose first column is horizontal."""
    xa = np.cross(np.array([0.0, 1.0, 0.0]), g)
    xa /= np.linalg.norm(xa)
    ya = np.cross(g, xa)
    return np.stack([xa, ya, g], axis=1)


def _submesh(verts: np.ndarray, faces: np.ndarray, keep: np.ndarray, normals: np.ndarray | None = None):
    """The faces ``keep`` (a mask) of a mesh, with only the vertices they use, re-indexed."""
    f = faces[keep]
    used, inv = np.unique(f.ravel(), return_inverse=True)
    nrm = None if normals is None else normals[used]
    return verts[used], inv.reshape(-1, 3).astype(np.int32), nrm


def _eye_meshes(head: _Head) -> dict[str, list[tuple[np.ndarray, np.ndarray]]]:
    """Both eyes: sclera, iris and pupil (one closed ball) and a closed cornea lens, following the gaze."""
    p = head.p
    r = head.eye_r
    rho_l = 0.0059  # limbus (iris) radius
    z_l = math.sqrt(r * r - rho_l * rho_l)
    z_p = z_l - 0.0004  # the iris is a shallow funnel toward the pupil
    rho_p = 0.0021 * (1.0 - 0.25 * p["squint"])
    profile = [(0.0, z_p), (rho_p, z_p)]
    profile += [(float(rr), float(z_p + (z_l - z_p) * (rr - rho_p) / (rho_l - rho_p)))
                for rr in np.linspace(rho_p, rho_l, 5)[1:]]  # fmt: skip
    n_iris = len(profile) - 1
    theta_l = math.asin(rho_l / r)
    profile[-1] = (rho_l, z_l - 0.0001)
    profile += [(r * math.sin(t), r * math.cos(t)) for t in np.linspace(theta_l, math.pi, 17)]
    ball_v, ball_f, band = _revolve(profile, 40)
    names = np.where(
        band == 0, 0, np.where(band <= n_iris, 1, 2)
    )  # pupil, iris (with the limbus step), sclera
    rc = 0.0078
    zc = z_l - math.sqrt(rc * rc - rho_l * rho_l)
    alpha_l = math.asin(rho_l / rc)
    lens = [(rc * math.sin(a), zc + rc * math.cos(a)) for a in np.linspace(0.0, alpha_l, 7)]
    lens += [(0.5 * rho_l, z_l), (0.0, z_l)]
    lens_v, lens_f, _ = _revolve(lens, 40)

    # Gaze: both eyes converge on a point 0.6 m away in the gaze direction.
    yaw, pitch = p["gaze_yaw"], p["gaze_pitch"]
    mid = np.array([0.0, 0.0, head.eyes[0][2]])
    target = mid + 0.6 * np.array(
        [math.sin(yaw) * math.cos(pitch), math.sin(pitch), math.cos(yaw) * math.cos(pitch)]
    )
    out: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {
        "pupil": [],
        "iris": [],
        "sclera": [],
        "cornea": [],
    }
    for e in head.eyes:
        centre = np.array(e)
        g = target - centre
        rot = _rotation_to(g / np.linalg.norm(g))
        bv = (ball_v @ rot.T + centre).astype(np.float32)
        for k, name in enumerate(("pupil", "iris", "sclera")):
            v, f, _ = _submesh(bv, ball_f, names == k)
            out[name].append((v, f))
        out["cornea"].append(((lens_v @ rot.T + centre).astype(np.float32), lens_f))
    return out


_SKIN_LO, _SKIN_HI = (-0.095, -0.27, -0.128), (0.095, 0.132, 0.132)
_SKIN_STEP = 0.0025


def _ear_meshes(head: _Head, step: float = 0.0015) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Both ears, meshed finer than the head on their own grids (they cross into the head at the root)."""
    out = []
    for side in (0, 1):
        u, v, n, r = head.ear_frame(side)
        es = head.ear_size
        corners = np.array([[a, b, c] for a in (-0.034 * es, 0.036 * es) for b in (-0.035 * es, 0.016 * es)
                            for c in (-0.010, 0.011)])  # fmt: skip
        world = corners @ np.stack([u, v, n]) + np.array(r)
        out.append(
            mesh_sdf(
                lambda a, b, c, side=side: head.ear(a, b, c, side),
                lo=world.min(0),
                hi=world.max(0),
                step=step,
            )
        )
    return out


def _skin_mesh(
    head: _Head, p: dict
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[tuple[str, Material]]]:
    """The skin (head, neck, ears) and a label per face: skin, lips, mouth, and stubble or buzz-cut hair."""
    lo = (_SKIN_LO[0], -0.27 if p["shirt_style"] == "vneck" else -0.215, _SKIN_LO[2])
    v, f, n = merge_meshes([mesh_sdf(head.skin, lo=lo, hi=_SKIN_HI, step=_SKIN_STEP), *_ear_meshes(head)])
    cen = v[f].mean(axis=1)
    cx, cy, cz = cen[:, 0], cen[:, 1], cen[:, 2]
    skin = np.array(p["skin_albedo"])
    hair = np.array(_HAIR_COLOURS[p["hair_colour"]])
    beard = np.array(_HAIR_COLOURS[p["beard_colour"]])
    table = [
        ("skin", Material("skin", tuple(p["skin_albedo"]), p["skin_roughness"], p["skin_specular"])),
        ("lips", Material("skin", tuple(p["lip_albedo"]), 0.3 if p["lipstick"] else p["skin_roughness"] * 0.8,
                          0.5 if p["lipstick"] else p["skin_specular"])),
        ("mouth", Material("diffuse", (0.10, 0.018, 0.018), 0.5, 0.3)),
        ("stubble", Material("skin", _rgb(0.75 * skin + 0.25 * np.minimum(beard, skin)), p["skin_roughness"], 0.3)),
        ("hair", Material("hair", _rgb(0.35 * skin + 0.65 * hair), 0.4, 0.35)),
    ]  # fmt: skip
    label = np.zeros(len(f), dtype=np.int8)
    if p["facial_hair"] == "stubble":
        label[_beard_region(head, p, cx, cy, cz) < 0.0] = 3
    if p["hair_style"] == "buzz":
        label[_hair_region(p, cx, cy, cz) < 0.0] = 4
    lo, hi = (-0.045, head.sto_y - 0.025 - head.d_open, 0.05), (0.045, head.sto_y + 0.02, 0.12)
    near = (cx > lo[0]) & (cx < hi[0]) & (cy > lo[1]) & (cy < hi[1]) & (cz > lo[2]) & (cz < hi[2])
    if near.any():
        lips = head.lips(cx[near], cy[near], cz[near])
        cut = head.mouth_cut(cx[near], cy[near], cz[near])
        lab = np.where(lips < 0.0008, 1, label[near])
        label[near] = np.where(cut < 0.0004, 2, lab)
    return v, f, n, label, table


def _rgb(c) -> tuple[float, float, float]:
    return (round(float(c[0]), 4), round(float(c[1]), 4), round(float(c[2]), 4))


# --------------------------------------------------------------------------------------------------------
# Hair, brows, beards, hats, glasses, earrings and the shirt
# --------------------------------------------------------------------------------------------------------

_HAIR_AXIS_Z = -0.015  # the vertical axis that hairlines are measured around


def _azimuth(x, z):
    """Azimuth about the head's vertical axis: 0 toward the face, +-pi/2 at the ears, +-pi at the back."""
    return np.arctan2(x, z - _HAIR_AXIS_Z)


def _hairline(p: dict) -> tuple[np.ndarray, np.ndarray]:
    """Knots ``(|azimuth|, height)`` of the lower edge of the hair."""
    rec = p["hair_recession"]
    front = 0.030 if p["fringe"] else 0.068 + 0.025 * rec
    az = [0.0, 0.5, 0.95, 1.12, 1.2, 1.3, 1.42, 2.05, 2.35, math.pi]
    y = [front, max(front, 0.060 + 0.035 * rec), 0.048, 0.030, -0.004, -0.004, 0.034, 0.030, -0.032, -0.052]
    if p["hair_style"] in ("medium", "long", "afro"):
        y = [front, max(front, 0.058 + 0.035 * rec), 0.045, 0.02, -0.03, -0.04, -0.05, -0.06, -0.065, -0.07]
    if p["fringe"]:  # straight across the forehead
        y[:3] = [front, front + 0.002, front + 0.01]
    return np.array(az), np.array(y)


def _hair_region(p: dict, x, y, z):
    """Negative above the hairline."""
    az, yy = _hairline(p)
    return np.interp(np.abs(_azimuth(x, z)), az, yy) - y


def _hair_sdf(head: _Head, p: dict, x, y, z):
    style, vol = p["hair_style"], p["hair_volume"]
    base = head.cranium_sdf(x, y, z)
    phi = _azimuth(x, z)
    up = np.clip((y - 0.02) / 0.08, 0.0, 1.0)
    front = np.clip(np.cos(phi), 0.0, 1.0) ** 2
    if style == "short":
        t_top, t_side = 0.008 + 0.012 * vol, 0.005
    elif style == "bun":
        t_top, t_side = 0.005, 0.0045
    elif style == "afro":
        t_top, t_side = 0.035 + 0.02 * vol, 0.030 + 0.015 * vol
    else:  # medium, long: over the ears (the base swells over them)
        t_top, t_side = 0.014 + 0.012 * vol, 0.009 + 0.006 * vol
        for side in (0, 1):
            r = head.ear_root[side]
            blob = ellipsoid(x, y, z, c=(r[0] * 1.12, r[1] + 0.002, r[2] - 0.016), r=(0.016, 0.036, 0.028))
            base = smin(base, blob, 0.02)
    t = t_side + (t_top - t_side) * up
    t = t * (1.0 - 0.35 * front * (1.0 - up))  # thinner over the forehead
    region = _hair_region(p, x, y, z)
    t = t * np.clip(-region / 0.02, 0.12, 1.0)  # tapering to the hairline
    if p["hat"] != "none":  # pressed flat under the hat's edge
        t = t * np.clip((_hat_edge(p, x, z) - y) / 0.06, 0.2, 1.0)
    grooves = 0.0006 * np.sin(45.0 * phi + 25.0 * y)
    if style == "afro":
        grooves = 0.0025 * np.sin(150.0 * x) * np.sin(150.0 * y + 1.0) * np.sin(150.0 * z + 2.0)
    d = smax(np.maximum(base - t + grooves, -(base + 0.006)), region, 0.002)
    if style == "bun":
        d = smin(d, sphere(x, y, z, c=(0.0, 0.075, -0.112), r=0.028 + 0.01 * vol), 0.012)
    if style == "long":
        # A curtain falling from the head: hugging it at the top, flaring a little toward the shoulders,
        # thinning and ending in a rounded, uneven edge; grooves run down its strands.
        length = 0.13 + 0.12 * vol
        drop = np.clip(-y / length, 0.0, 1.0)
        ax, az_ = 0.082 + t_side + 0.012 * drop, 0.100 + t_side + 0.01 * drop
        q = np.sqrt((x / ax) ** 2 + ((z - _HAIR_AXIS_Z) / az_) ** 2)
        cyl = (q - 1.0) * np.minimum(ax, az_) + 0.0012 * np.sin(60.0 * phi)
        bottom = -length + 0.07 * np.clip(np.cos(phi), 0.0, 1.0) + 0.008 * np.sin(9.0 * phi)
        curtain = smax(cyl, bottom - y, 0.015)
        curtain = np.maximum(np.maximum(curtain, y - 0.06), -(cyl + 0.012 - 0.005 * drop))
        d = smin(d, np.maximum(curtain, -(base + 0.006)), 0.01)
    if style in ("medium", "long", "afro"):
        # Keep the face clear: nothing in front of the cheeks below the hairline.
        ax_ = np.abs(x)
        zcut = -0.005 + 0.06 * np.clip((ax_ - 0.052) / 0.025, 0.0, 1.0) + 0.25 * np.clip(-0.03 - y, 0.0, 0.1)
        front_y = _hairline(p)[1][0]
        window = smax(zcut - z, y - front_y, 0.015)
        d = smax(d, -window, 0.01)
    return d


def _hat_edge(p: dict, x, z):
    phi = np.abs(_azimuth(x, z))
    if p["hat"] == "beanie":
        return np.interp(phi, [0.0, 1.0, 1.6, 2.4, math.pi], [0.052, 0.040, 0.030, 0.005, -0.01])
    return np.interp(phi, [0.0, 1.0, 1.6, 2.4, math.pi], [0.060, 0.050, 0.040, 0.025, 0.018])


def _hat_cover(p: dict, x, y, z):
    """Negative above the hat's lower edge: the hair there is pressed under the hat."""
    return _hat_edge(p, x, z) - 0.004 - y


def _hat_sdf(head: _Head, p: dict, x, y, z):
    """A beanie or a cap, as a solid down to the head (the scalp under it is inside it)."""
    base = head.cranium_sdf(x, y, z)
    edge = _hat_edge(p, x, z)
    if p["hat"] == "beanie":
        ribs = 0.0006 * np.sin(60.0 * _azimuth(x, z))
        cuff = 0.003 * np.clip((edge + 0.028 - y) / 0.003, 0.0, 1.0)
        d = np.maximum(base - 0.011 - cuff + ribs, edge - y)
        if p["hair_volume"] > 0.5:  # a pompom
            d = smin(d, sphere(x, y, z, c=(0.0, 0.132, -0.02), r=0.016), 0.006)
        return d
    # Cap: a dome and a brim.
    d = np.maximum(base - 0.008, edge - y)
    fz = 0.088
    brim_y = 0.058 - 0.15 * np.maximum(z - fz, 0.0)
    plate = np.abs(y - brim_y) - 0.0025
    outline = np.sqrt((x / 0.085) ** 2 + ((z - fz + 0.02) / 0.085) ** 2) - 1.0
    brim = np.maximum(plate, np.maximum(outline * 0.08, fz - 0.03 - z))
    d = smin(d, brim, 0.004)
    return smin(d, sphere(x, y, z, c=(0.0, 0.127, -0.015), r=0.006), 0.002)


def _brow_region(head: _Head, p: dict, x, y, z, *, side: int):
    sg = -1.0 if side == 0 else 1.0
    e = head.eyes[side]
    xl = sg * x
    x_m, x_l = 0.011, abs(e[0]) + 0.027
    t = np.clip((xl - x_m) / (x_l - x_m), 0.0, 1.0)
    yb = 0.016 + 0.004 * p["brow_raise"] + 0.0065 * np.sin(np.pi * t**0.8) - 0.003 * t
    h = np.maximum(0.0042 * p["brow_thickness"] * (1.0 - 0.6 * t), 0.0012)
    d = np.maximum(np.abs(y - yb) - h, np.maximum(x_m - xl, xl - x_l))
    return np.maximum(d, 0.05 - z)


def _brow_sdf(head: _Head, p: dict, x, y, z, *, side: int):
    """A thin shell over the skin inside the brow band, thickest in the middle of the band."""
    skin = head.skin(x, y, z)
    region = _brow_region(head, p, x, y, z, side=side)
    t = 0.0019 * np.clip(-region / 0.0015, 0.3, 1.0)
    return smax(np.maximum(skin - t, -(skin + 0.0008)), region, 0.0005)


def _beard_region(head: _Head, p: dict, x, y, z):
    """Negative where facial hair grows (by style), with a slightly irregular edge."""
    style = p["facial_hair"]
    sn_y = head.tip[1] - 0.013
    sto = head.sto_y
    ax = np.abs(x)
    w2 = 0.5 * head.mouth_w
    ragged = 0.0012 * np.sin(420.0 * x + 3.0) * np.sin(380.0 * y + 1.0)
    # Rounded patches (ellipses in x-y), so that the shells' tapered edges look soft.
    my, mh = 0.5 * (sn_y + sto) + 0.0015, 0.5 * (sn_y - sto) - 0.001
    moustache = (np.sqrt((x / (w2 + 0.005)) ** 2 + ((y - my) / mh) ** 4) - 1.0) * mh
    moustache = np.maximum(moustache, 0.07 - z)
    if style == "moustache":
        return moustache + ragged
    cy = 0.5 * (sto - 0.006 + head.chin[0][1] - head.chin[1][1] - 0.006)
    ch = 0.5 * (sto - 0.006 - (head.chin[0][1] - head.chin[1][1] - 0.006))
    chin = (np.sqrt((x / 0.022) ** 2 + ((y - cy) / ch) ** 2) - 1.0) * 0.02
    chin = np.maximum(chin, 0.05 - z)
    if style == "goatee":
        return np.minimum(moustache, chin) + ragged
    # Full beard and stubble: under a cheek line curving up from the mouth's corner to the sideburn, down to
    # the neck, in front of the ears.
    k = np.clip((ax - w2) / (0.064 - w2), 0.0, 1.0)
    y_top = sto + 0.006 + (0.0 - sto - 0.006) * k**2.2
    d = np.maximum(y - y_top, -0.15 - head.d_open - y)
    d = np.minimum(d, moustache)
    return np.maximum(d, -0.002 - z) + ragged


def _beard_sdf(head: _Head, p: dict, x, y, z):
    t = p["beard_thickness"] if p["facial_hair"] != "moustache" else 0.003 + 0.3 * p["beard_thickness"]
    skin = head.skin(x, y, z)
    region = _beard_region(head, p, x, y, z)
    lips = head.lips(x, y, z)
    region = np.maximum(region, -(lips - 0.0015))
    t = t * np.clip(-region / 0.015, 0.1, 1.0)
    texture = 0.0008 * np.sin(260.0 * x + 70.0 * y) * np.sin(210.0 * z + 40.0 * x)
    d = smax(np.maximum(skin - t + texture, -(skin + 0.0045)), region, 0.002)
    if p["facial_hair"] == "long_beard":
        hang = ellipsoid(x, y, z, c=(0.0, -0.132 - head.d_open, 0.06), r=(0.04, 0.04, 0.028))
        d = smin(d, np.maximum(hang, y - head.sto_y + 0.03), 0.012)
    return d


def _glasses_sdf(head: _Head, p: dict, x, y, z):
    ex = abs(head.eyes[0][0])
    zg = head.eyes[0][2] + 0.029
    zz = _warp_arch(x, z - zg, 0.16)
    d = None
    for sg in (-1.0, 1.0):
        cx, cy = sg * (ex + 0.002), 0.001
        qx, qy = np.abs(x - cx) - 0.0215, np.abs(y - cy) - 0.0135
        rect = (
            np.sqrt(np.maximum(qx, 0.0) ** 2 + np.maximum(qy, 0.0) ** 2)
            + np.minimum(np.maximum(qx, qy), 0.0)
            - 0.006
        )
        ring = np.sqrt(rect**2 + zz**2) - 0.0016
        temple = capsule(
            x, y, z, a=(sg * (ex + 0.029), 0.010, zg - 0.006), b=(sg * 0.074, 0.008, -0.005), ra=0.0013
        )
        part = np.minimum(ring, temple)
        d = part if d is None else np.minimum(d, part)
    bridge = capsule(
        x, y, z, a=(-ex + 0.024, 0.009, zg + 0.0005), b=(ex - 0.024, 0.009, zg + 0.0005), ra=0.0014
    )
    return np.minimum(d, bridge)


def _shirt_sdf(head: _Head, p: dict, x, y, z):
    """The shirt's body: the torso grown by 5 mm with soft folds, open around the neck (and in a V)."""
    body = head.body(x, y, z)
    folds = 0.002 * np.sin(18.0 * x + 11.0 * y) * np.sin(14.0 * y - 9.0 * z)
    d = body - 0.005 + folds
    if p["shirt_style"] == "turtleneck":
        return d
    hole = capsule(x, y, z, a=head.neck[0], b=head.neck[1], ra=head.neck_r) - 0.010
    if p["shirt_style"] == "vneck":
        vee = np.abs(x) - 0.5 * (y + 0.285)
        hole = np.minimum(hole, np.maximum(vee, -z))
    return smax(d, -hole, 0.008)


def _collar_sdf(head: _Head, p: dict, x, y, z):
    """The neckline's finish, meshed finer than the shirt: a rib (crew), a V rib, a standing collar or a
    turtleneck's rolled tube."""
    style = p["shirt_style"]
    neck = capsule(x, y, z, a=head.neck[0], b=head.neck[1], ra=head.neck_r)
    back = np.clip(-z / 0.05, 0.0, 1.0)
    if style == "turtleneck":  # solid down to the neck's axis: the skin inside it is hidden
        top = -0.135 + 0.03 * back
        return np.maximum(neck - 0.011 + 0.0008 * np.sin(70.0 * y), np.maximum(y - top, -0.235 - y))
    torso = np.abs(head.torso(x, y, z) + 0.002) - 0.0065
    rib = np.maximum(np.abs(neck - 0.0135) - 0.0045, torso)
    if style == "vneck":  # a rib along the V's edges in front, around the neck behind
        vee = np.maximum(0.894 * np.abs(np.abs(x) - 0.5 * (y + 0.285)) - 0.0055, np.maximum(-z, -0.292 - y))
        rib = np.maximum(np.minimum(np.maximum(rib, z), vee), torso)
        return rib
    if style == "collar":  # a standing band, open at the front
        band = np.maximum(np.abs(neck - 0.0135) - 0.002, np.maximum(y + 0.215, -0.178 + 0.012 * back - y))
        band = np.maximum(band, np.where(z > 0.0, 0.012 - np.abs(x), -1.0))
        rib = np.minimum(rib, band)
    return rib


_SHIRT_LO, _SHIRT_HI = (-0.25, -0.42, -0.16), (0.25, -0.11, 0.14)


def _landmarks(head: _Head, skin_v: np.ndarray) -> np.ndarray:
    """The face landmarks of :data:`LANDMARK_NAMES`, guessed from the model and snapped onto the skin."""
    p = head.p
    e0, e1 = head.eyes
    ry = 0.004 * p["brow_raise"]
    es = p["eye_size"]
    t, sto, w = head.tip, head.sto_y, head.mouth_w
    mz = head.mouth_z
    pts = [
        (e0[0] - 0.002, 0.030 + ry, 0.085), (e1[0] + 0.002, 0.030 + ry, 0.085), (0.0, 0.013 + ry, 0.09),
        (e0[0] - head.lid_r * math.sin(1.0 * es), 0.0, e0[2] + head.lid_r * math.cos(1.0 * es)),
        (e0[0] + head.lid_r * math.sin(0.95 * es), 0.0, e0[2] + head.lid_r * math.cos(0.95 * es)),
        (e1[0] - head.lid_r * math.sin(0.95 * es), 0.0, e1[2] + head.lid_r * math.cos(0.95 * es)),
        (e1[0] + head.lid_r * math.sin(1.0 * es), 0.0, e1[2] + head.lid_r * math.cos(1.0 * es)),
        (0.0, t[1], t[2] + 0.002), (0.0, t[1] - 0.013, t[2] - 0.02),
        (-0.5 * w, sto + 0.005 * p["smile"], mz - w * w / 0.32), (0.5 * w, sto + 0.005 * p["smile"], mz - w * w / 0.32),
        (0.0, sto + 0.007, mz + 0.004), (0.0, sto - 0.008 - head.d_open, mz + 0.002),
        (0.0, head.chin[0][1] - head.chin[1][1], head.chin[0][2]),
        head.gonion[0], head.gonion[1],
        (-0.070 * p["head_width"], -0.008, 0.035), (0.070 * p["head_width"], -0.008, 0.035),
    ]  # fmt: skip
    for side in (0, 1):
        u, v, n, r = head.ear_frame(side)
        es_ = head.ear_size
        local = np.array([0.004 * es_ - 0.008 * es_, -0.014 * es_ + 0.0125 * es_, 0.0045])
        pts.append(tuple(local @ np.stack([u, v, n]) + np.array(r)))
    pts_a = np.array(pts, dtype=np.float32)
    # Snap each guess onto the nearest skin vertex (within 2 cm).
    d2 = ((pts_a[:, None, :] - skin_v[None, ::3, :]) ** 2).sum(-1)
    j = d2.argmin(1)
    near = d2[np.arange(len(pts_a)), j] < 0.02**2
    pts_a[near] = skin_v[::3][j[near]]
    return pts_a


def _earring_sdf(head: _Head, p: dict, x, y, z):
    d = None
    for side in (0, 1):
        u, v, n, r = head.ear_frame(side)
        es = head.ear_size
        lobe = np.array([0.004 * es - 0.027 * es, -0.014 * es + 0.004 * es, 0.0025]) @ np.stack(
            [u, v, n]
        ) + np.array(r)
        if p["earring_style"] == "stud":
            e = sphere(x, y, z, c=lobe, r=0.0028)
        else:
            c = lobe - np.array([0.0, 0.011, 0.0])
            q = np.sqrt((y - c[1]) ** 2 + (z - c[2]) ** 2) - 0.010
            e = np.sqrt(q * q + (x - c[0]) ** 2) - 0.0011
        d = e if d is None else np.minimum(d, e)
    return d


def _clip_to_box(fn, lo, hi):
    """``fn`` intersected with the box ``[lo, hi]``."""

    def clipped(x, y, z):
        out = np.maximum(np.maximum(lo[0] - x, x - hi[0]), np.maximum(lo[1] - y, y - hi[1]))
        return np.maximum(np.maximum(out, np.maximum(lo[2] - z, z - hi[2])), fn(x, y, z))

    return clipped


def _cull_hidden(v: np.ndarray, f: np.ndarray, occluders: list) -> np.ndarray:
    """A mask of the faces to keep: those not entirely inside one of the opaque ``occluders``.

    ``occluders`` holds ``(sdf, step)``: a face is dropped when its three vertices are deeper than 1.5 grid
    steps inside the occluder's SDF, so that the occluder's mesh (which marching cubes places within a step of
    the SDF's zero set) surely covers it.
    """
    keep = np.ones(len(f), dtype=bool)
    for fn, step in occluders:
        inside = np.asarray(fn(v[:, 0], v[:, 1], v[:, 2])) < -1.5 * step
        keep &= ~(inside[f[:, 0]] & inside[f[:, 1]] & inside[f[:, 2]])
    return keep


def make_subject(seed: int, *, cull_hidden: bool = True) -> Subject:
    """The synthetic subject of ``seed``: meshes, materials, skin tone, face landmarks and parameters.

    Args:
        seed: any int; the same seed always gives the same subject.
        cull_hidden: drop the triangles buried inside another opaque part (the scalp under the hair, the inside
            of hair and beard shells, the neck inside the shirt): the union of the parts, and so every render,
            is unchanged, with about a third fewer triangles. Without it every part is a closed mesh.

    Returns:
        The :class:`Subject`, in metres in the frame of docs/conventions.rst, facing +Z.

    Raises:
        TypeCheckError: ``seed`` is not an int.

    Examples:
        >>> s = make_subject(7)
        >>> s.split, 1 <= s.skin_tone <= 10, s.face_landmarks.shape
        ('train', True, (20, 3))
        >>> sorted({"skin", "lips", "sclera", "iris", "cornea", "shirt"} - {p.name for p in s.parts})
        []
    """
    p = subject_params(seed)
    head = _Head(p)
    hair_mat = Material("hair", _HAIR_COLOURS[p["hair_colour"]], 0.3, 0.5)
    beard_mat = Material("hair", _HAIR_COLOURS[p["beard_colour"]], 0.3, 0.5)
    # (name, vertices, faces, normals, material, its SDF when it hides what is inside it)
    pieces: list[tuple[str, np.ndarray, np.ndarray, np.ndarray | None, Material, object]] = []

    def add(name, mesh, *, material, sdf=None, box=None):
        if len(mesh[1]):
            if sdf is not None:  # what the mesh holds: the SDF clipped to the meshed box, and its step
                sdf = (_clip_to_box(sdf, *box[:2]), box[2])
            pieces.append((name, mesh[0], mesh[1], mesh[2], material, sdf))

    def fn_of(f, **kwargs):
        return lambda x, y, z: f(head, p, x, y, z, **kwargs)

    # Eyebrows: a thin shell over the skin inside a band over each brow ridge.
    hair_rgb = np.array(_HAIR_COLOURS[p["beard_colour"]])
    # Brows: the facial-hair colour, darkened (keeping its hue) when light, except for grey and white.
    brow_rgb = (
        hair_rgb if p["beard_colour"] in ("grey", "white") else hair_rgb * min(0.85, 0.2 / hair_rgb.max())
    )
    brows = []
    for side in (0, 1):
        sg = -1.0 if side == 0 else 1.0
        lo, hi = (min(sg * 0.006, sg * 0.064), 0.002, 0.05), (max(sg * 0.006, sg * 0.064), 0.036, 0.1)
        brows.append(mesh_sdf(fn_of(_brow_sdf, side=side), lo=lo, hi=hi, step=0.001))
    add("brows", merge_meshes(brows), material=Material("hair", _rgb(brow_rgb), 0.35, 0.4))
    if p["facial_hair"] not in ("none", "stubble"):
        box = ((-0.085, -0.2, -0.03), (0.085, 0.0, 0.135))
        beard = mesh_sdf(fn_of(_beard_sdf), lo=box[0], hi=box[1], step=0.0026)
        add("beard", beard, material=beard_mat, sdf=fn_of(_beard_sdf), box=(*box, 0.0026))
    if p["hair_style"] not in ("bald", "buzz"):
        hair_fn = fn_of(_hair_sdf)
        if p["hat"] != "none":
            hair_fn = lambda x, y, z: np.maximum(_hair_sdf(head, p, x, y, z), -_hat_cover(p, x, y, z))
        step = 0.0036 if p["hair_style"] in ("afro", "long") else 0.003
        box = ((-0.16, -0.30, -0.20), (0.16, 0.19, 0.14))
        hair = mesh_sdf(hair_fn, lo=box[0], hi=box[1], step=step)
        add("hair", hair, material=hair_mat, sdf=hair_fn, box=(*box, step))
    if p["hat"] != "none":
        hat_fn = fn_of(_hat_sdf)
        kind = "diffuse" if p["hat"] == "beanie" else "glossy"
        box = ((-0.12, -0.03, -0.14), (0.12, 0.16, 0.20))
        hat = mesh_sdf(hat_fn, lo=box[0], hi=box[1], step=0.0028)
        add(
            "hat",
            hat,
            material=Material(kind, tuple(p["hat_albedo"]), 0.45, 0.4),
            sdf=hat_fn,
            box=(*box, 0.0028),
        )
    if p["glasses"]:
        glasses = mesh_sdf(fn_of(_glasses_sdf), lo=(-0.08, -0.02, -0.01), hi=(0.08, 0.024, 0.1), step=0.001)
        add("glasses", glasses, material=frame_material(p["glasses_frame"], p["glasses_albedo"], 0.15))
    if p["earrings"]:
        earrings = mesh_sdf(
            fn_of(_earring_sdf), lo=(-0.11, -0.075, -0.06), hi=(0.11, -0.005, 0.03), step=0.0007
        )
        add("earrings", earrings, material=Material("glossy", tuple(p["earring_albedo"]), 0.08, 0.5))
    if p["mouth_open"] > 0.1:
        lo = (-0.03, head.sto_y - 0.015 - head.d_open, head.mouth_z - 0.03)
        hi = (0.03, head.sto_y + 0.012, head.mouth_z + 0.005)
        add("teeth", mesh_sdf(lambda x, y, z: head.teeth(x, y, z), lo=lo, hi=hi, step=0.001),
            material=Material("glossy", (0.62, 0.57, 0.47), 0.25, 0.5))  # fmt: skip
    shirt_mat = Material("diffuse", tuple(p["shirt_albedo"]), 0.6, 0.3)
    turtle = p["shirt_style"] == "turtleneck"
    box = (
        (-0.085, -0.30 if p["shirt_style"] == "vneck" else -0.24, -0.09),
        (0.085, -0.10 if turtle else -0.15, 0.085),
    )
    step = 0.0035 if turtle else 0.0027
    collar = mesh_sdf(fn_of(_collar_sdf), lo=box[0], hi=box[1], step=step)
    shirt = mesh_sdf(fn_of(_shirt_sdf), lo=_SHIRT_LO, hi=_SHIRT_HI, step=0.008)
    collar_sdf = fn_of(_collar_sdf) if turtle else None
    add("shirt", merge_meshes([shirt, collar]), material=shirt_mat, sdf=collar_sdf, box=(*box, step))
    # The shirt's body is smooth and thick: its mesh follows its SDF closely, so it hides skin 4 mm inside it.
    occluders_extra = [(_clip_to_box(fn_of(_shirt_sdf), _SHIRT_LO, _SHIRT_HI), 0.004 / 1.5)]

    # The skin, with its labelled regions.
    sv, sf, sn, label, table = _skin_mesh(head, p)
    occluders = [pc[5] for pc in pieces if pc[5] is not None] + occluders_extra
    parts: list[MeshPart] = []
    if cull_hidden:
        keep = _cull_hidden(sv, sf, occluders)
        sf, label = sf[keep], label[keep]
    for k, (name, mat) in enumerate(table):
        sel = label == k
        if sel.any():
            v, f, n = _submesh(sv, sf, sel, sn)
            parts.append(MeshPart(name, v, f, mat, n))
    eyes = _eye_meshes(head)
    mats = {
        "sclera": Material("glossy", (0.60, 0.56, 0.52), 0.08, 0.5),
        "iris": Material("diffuse", _IRIS_COLOURS[p["iris"]], 0.5, 0.5),
        "pupil": Material("diffuse", (0.004, 0.004, 0.004), 0.5, 0.5),
        "cornea": Material("cornea", (1.0, 1.0, 1.0), 0.0, 0.313),
    }
    for name in ("sclera", "iris", "pupil", "cornea"):
        v, f, _ = merge_meshes(eyes[name])
        parts.append(MeshPart(name, v, f, mats[name]))
    for name, v, f, n, mat, sdf in pieces:
        if cull_hidden and name not in ("glasses", "earrings", "teeth"):
            others = [(head.skin, _SKIN_STEP)] + [o for o in occluders if o is not sdf]
            keep = _cull_hidden(v, f, others)
            v, f, n = _submesh(v, f, keep, n)
        if len(f):
            parts.append(MeshPart(name, v, f, mat, n))
    landmarks = _landmarks(head, sv)
    s = p["scale"]
    for part in parts:
        part.vertices = (part.vertices * s).astype(np.float32)
    return Subject(
        seed=seed,
        split=subject_split(seed),
        parts=parts,
        skin_tone=p["skin_tone"],
        face_landmarks=(landmarks * s).astype(np.float32),
        params=p,
        face_albedo=(float(p["skin_albedo"][0]), float(p["skin_albedo"][1]), float(p["skin_albedo"][2])),
    )


class MannequinSource:
    """The signed-distance mannequins as a :class:`~kornia_ilum_lab.synth.lightstage.subjects.SubjectSource`.

    They need no assets: the fallback for machines without the MakeHuman data.

    Examples:
        >>> MannequinSource().sample(7).source
        'mannequin'
    """

    name = "mannequin"

    def sample(self, seed: int) -> Subject:
        """:func:`make_subject` of ``seed``."""
        return make_subject(seed)

    def __repr__(self) -> str:
        return "MannequinSource()"
