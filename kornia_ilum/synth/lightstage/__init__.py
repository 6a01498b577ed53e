"""The virtual light stage: synthetic subjects, their OLAT reflectance fields, and portraits relit from them."""

from kornia_ilum.synth.lightstage.cache import (
    DEFAULT_VIEWS,
    build_cache,
    read_field,
    read_manifest,
    write_field,
)
from kornia_ilum.synth.lightstage.olat import (
    ReflectanceField,
    render_lighting,
    render_olat,
    select_mitsuba_variant,
)
from kornia_ilum.synth.lightstage.scene import Camera
from kornia_ilum.synth.lightstage.portraits import PortraitDataset, load_fields, relight_portraits
from kornia_ilum.synth.lightstage.subjects import (
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
    "Camera",
    "Material",
    "MeshPart",
    "PortraitDataset",
    "ReflectanceField",
    "Subject",
    "build_cache",
    "load_fields",
    "make_subject",
    "read_field",
    "read_manifest",
    "relight_portraits",
    "render_lighting",
    "render_olat",
    "select_mitsuba_variant",
    "subject_params",
    "subject_split",
    "write_field",
]
