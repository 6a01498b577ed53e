"""The virtual light stage: synthetic subjects, their OLAT reflectance fields, and portraits relit from them."""

from kornia_ilum_lab.synth.lightstage.cache import (
    DEFAULT_VIEWS,
    FixedViews,
    SampledViews,
    Workers,
    build_cache,
    cache_summary,
    read_field,
    read_manifest,
    write_field,
)
from kornia_ilum_lab.synth.lightstage.field import ReflectanceField
from kornia_ilum_lab.synth.lightstage.materials import select_mitsuba_variant
from kornia_ilum_lab.synth.lightstage.olat import render_olat
from kornia_ilum_lab.synth.lightstage.portraits import PortraitDataset, load_fields, relight_portraits
from kornia_ilum_lab.synth.lightstage.reference import render_lighting, render_olat_reference
from kornia_ilum_lab.synth.lightstage.scene import Camera, sample_views
from kornia_ilum_lab.synth.lightstage.settings import Auto, OnePass, Reference
from kornia_ilum_lab.synth.lightstage.sparse import read_sparse, write_sparse, write_sparse_cache
from kornia_ilum_lab.synth.lightstage.subjects import (
    LANDMARK_NAMES,
    SKIN_ALBEDO,
    Material,
    MeshPart,
    Subject,
    make_subject,
    subject_params,
    subject_split,
)

__all__ = [
    "DEFAULT_VIEWS",
    "LANDMARK_NAMES",
    "SKIN_ALBEDO",
    "Auto",
    "Camera",
    "FixedViews",
    "Material",
    "MeshPart",
    "OnePass",
    "PortraitDataset",
    "Reference",
    "ReflectanceField",
    "SampledViews",
    "Subject",
    "Workers",
    "build_cache",
    "cache_summary",
    "load_fields",
    "make_subject",
    "read_field",
    "read_manifest",
    "read_sparse",
    "relight_portraits",
    "render_lighting",
    "render_olat_reference",
    "render_olat",
    "sample_views",
    "select_mitsuba_variant",
    "subject_params",
    "subject_split",
    "write_field",
    "write_sparse",
    "write_sparse_cache",
]
