"""Mitsuba set-up shared by the renderers (kornia_ilum_lab.synth.lightstage.materials): variants and BSDFs."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum_lab.synth.lightstage.materials import (
    MITSUBA_VARIANTS,
    VARIANT_ENV,
    fresnel_ior,
    material_bsdf,
    select_mitsuba_variant,
)
from tests.lab.synth.lightstage.spheres import material

class TestMaterialBsdf:
    @pytest.mark.slow
    @pytest.mark.parametrize("kind", ["skin", "diffuse", "glossy", "metal", "cornea", "hair"])
    def test_smoke(self, kind: str, variant: str) -> None:
        import mitsuba as mi  # lazy: Mitsuba is slow to import, and only the slow tests need it

        select_mitsuba_variant(variant)
        assert mi.load_dict(material_bsdf(material(kind))) is not None

    def test_roughness_is_ggx_alpha(self) -> None:
        bsdf = material_bsdf(material("skin", roughness=0.16, specular=0.35))
        assert bsdf["bsdf"]["roughness"] == pytest.approx(0.4)
        assert bsdf["bsdf"]["specular"] == 0.35

    def test_metal_is_all_specular(self) -> None:
        """A metal (a titanium glasses frame) is the principled lobe tinted by F0, with no diffuse part: its
        diffuse twin is black, so the one-pass renderer puts all of its light in the specular part."""
        from kornia_ilum_lab.synth.lightstage.materials import diffuse_twin_bsdf
        from kornia_ilum_lab.synth.lightstage.subjects.base import FRAME_ALBEDO, frame_material

        frame = frame_material("metal", FRAME_ALBEDO["metal"], 0.12)
        bsdf = material_bsdf(frame)["bsdf"]
        assert bsdf["metallic"] == 1.0 and bsdf["base_color"]["value"] == pytest.approx(FRAME_ALBEDO["metal"])
        assert diffuse_twin_bsdf(frame)["bsdf"] == {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0] * 3}}
        plastic = material_bsdf(frame_material("black", FRAME_ALBEDO["black"], 0.12))["bsdf"]
        assert plastic["metallic"] == 0.0 and diffuse_twin_bsdf(material("glossy"))["bsdf"]["specular"] == 0.0

    def test_cornea_ior(self) -> None:
        """F0 = 0.08 specular: specular 0.3125 is the real cornea's F0 = 0.025, IOR 1.376."""
        bsdf = material_bsdf(material("cornea", specular=0.3125))
        assert bsdf["mirror"]["eta"] == pytest.approx(1.376, abs=2e-3)
        assert fresnel_ior(0.025) == pytest.approx(bsdf["mirror"]["eta"])

    @pytest.mark.parametrize(
        ("mat", "match"),
        [
            (SimpleNamespace(kind="velvet", albedo=(0.5, 0.5, 0.5)), "kind must be one of"),
            (SimpleNamespace(kind="skin", albedo=(1.5, 0.5, 0.5)), r"albedo must be 3 linear RGB values in \[0, 1\]"),
            (SimpleNamespace(kind="skin", albedo=(0.5, 0.5, 0.5), roughness=2.0), "roughness must be in"),
            (SimpleNamespace(kind="glossy", albedo=(0.5, 0.5, 0.5), specular=-1.0), "specular must be in"),
        ],
    )
    def test_exception(self, mat: SimpleNamespace, match: str) -> None:
        with pytest.raises(ValueCheckError, match=match):
            material_bsdf(mat)

@pytest.mark.slow  # the first call probes the variants in a child process
class TestSelectMitsubaVariant:
    def test_smoke(self) -> None:
        import mitsuba as mi  # lazy: Mitsuba is slow to import, and only the slow tests need it

        assert select_mitsuba_variant() in MITSUBA_VARIANTS
        assert mi.variant() in MITSUBA_VARIANTS

    def test_environment_variable(self, monkeypatch: pytest.MonkeyPatch) -> None:
        import mitsuba as mi  # lazy: Mitsuba is slow to import, and only the slow tests need it

        monkeypatch.setenv(VARIANT_ENV, "scalar_rgb")
        assert select_mitsuba_variant() == "scalar_rgb" == mi.variant()

    def test_exception(self) -> None:
        with pytest.raises(ValueCheckError, match="variant must be one of"):
            select_mitsuba_variant("scalar_xyz")
