"""Skin calibrated against measured facial skin colour (kornia_ilum_lab.synth.lightstage.subjects.skin)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from kornia_ilum_lab.synth.lightstage.subjects.skin import (
    MEASURED_SKIN_LAB,
    SKIN_ALBEDO,
    SKIN_SPECULAR_ALBEDO,
    SKIN_TOTAL_REFLECTANCE,
    lab_to_linear_rgb,
    measured_skin_range,
)


def _luminance(rgb):
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]


class TestMeasuredColours:
    def test_span_of_measured_faces(self):
        """L* from 70 (very light, ITA > 55 deg) to 29 (the darkest faces measured), evenly spaced."""
        lightness = [lab[0] for lab in MEASURED_SKIN_LAB]
        assert lightness[0] == 70.0 and lightness[-1] == 29.0
        np.testing.assert_allclose(np.diff(lightness), -41.0 / 9, atol=0.01)

    def test_individual_typology_angle_runs_through_the_classes(self):
        """ITA = atan((L* - 50) / b*): very light (> 55) for tone 1, dark (< -30) for tones 8 to 10."""
        ita = [np.degrees(np.arctan2(lab[0] - 50.0, lab[2])) for lab in MEASURED_SKIN_LAB]
        assert ita[0] > 55 and all(a > b for a, b in itertools.pairwise(ita)) and max(ita[7:]) < -30

    def test_lab_conversion(self):
        """D65 white is (1, 1, 1); a measured light face (L* 63.5, a* 7.2, b* 9.7) reads about (0.42, 0.30, 0.25)."""
        np.testing.assert_allclose(lab_to_linear_rgb((100.0, 0.0, 0.0)), (1.0, 1.0, 1.0), atol=1e-3)
        np.testing.assert_allclose(lab_to_linear_rgb((63.5, 7.2, 9.7)), (0.42, 0.30, 0.25), atol=0.01)


class TestAlbedo:
    def test_total_is_albedo_plus_specular(self):
        for albedo, total in zip(SKIN_ALBEDO, SKIN_TOTAL_REFLECTANCE, strict=True):
            np.testing.assert_allclose(np.asarray(albedo) + SKIN_SPECULAR_ALBEDO, total, atol=1e-3)

    def test_ordered_and_within_measured_skin(self):
        """Darker with every tone; red > green > blue; the lightest no brighter than measured skin."""
        lum = [_luminance(t) for t in SKIN_TOTAL_REFLECTANCE]
        assert all(a > b for a, b in itertools.pairwise(lum))
        assert lum[0] < 0.45 and lum[-1] > 0.04  # L* 70 is Y 0.41; L* 29 is Y 0.06
        assert all(r > g > b > 0 for r, g, b in SKIN_ALBEDO)

    @pytest.mark.parametrize("tone", range(1, 11))
    def test_range_holds_the_tone(self, tone):
        low, high = measured_skin_range(tone)
        assert all(lo < t < hi for lo, t, hi in zip(low, SKIN_TOTAL_REFLECTANCE[tone - 1], high, strict=True))
        # the brightness jitter of the sources (exp(+-0.12)) keeps a subject inside its tone's range
        for factor in (np.exp(-0.12), np.exp(0.12)):
            total = np.asarray(SKIN_ALBEDO[tone - 1]) * factor + SKIN_SPECULAR_ALBEDO
            assert np.all(total > np.asarray(low)) and np.all(total < np.asarray(high))

    def test_range_rejects_a_bad_tone(self):
        with pytest.raises(ValueError, match="MST tone"):
            measured_skin_range(11)


@pytest.mark.slow
def test_specular_albedo_is_the_renderers():
    """A flat patch of the light stage's skin BSDF under uniform white radiance 1, seen head-on, reads its base
    colour plus SKIN_SPECULAR_ALBEDO (Mitsuba principled, F0 0.03, alpha 0.4: the middle of the sources' ranges)."""
    mi = pytest.importorskip("mitsuba")
    from types import SimpleNamespace

    from kornia_ilum_lab.synth.lightstage.materials import material_bsdf, select_mitsuba_variant

    select_mitsuba_variant("scalar_rgb")
    for base in (0.05, 0.3):
        material = SimpleNamespace(kind="skin", albedo=(base,) * 3, roughness=0.4, specular=0.03 / 0.08)
        scene = mi.load_dict({
            "type": "scene", "integrator": {"type": "path", "max_depth": 2},
            "sensor": {"type": "perspective", "fov": 10,
                       "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]),
                       "film": {"type": "hdrfilm", "width": 8, "height": 8, "rfilter": {"type": "box"}},
                       "sampler": {"type": "independent", "sample_count": 1024}},
            "env": {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}},
            "ball": {"type": "sphere", "center": [0, 0, 0], "radius": 1, "bsdf": material_bsdf(material)},
        })  # fmt: skip
        centre = float(np.asarray(mi.render(scene, seed=1))[3:5, 3:5].mean())
        assert abs(centre - base - SKIN_SPECULAR_ALBEDO) < 0.004, (base, centre)
