"""The virtual light stage: synthetic subjects (and their reflectance fields)."""

from kornia_ilum.synth.lightstage.cache import (
    DEFAULT_VIEWS,
    build_cache,
    read_field,
    read_manifest,
    write_field,
)
from kornia_ilum.synth.lightstage.olat import Camera, ReflectanceField, render_lighting, render_olat
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
    "ReflectanceField",
    "Subject",
    "build_cache",
    "make_subject",
    "read_field",
    "read_manifest",
    "render_lighting",
    "render_olat",
    "subject_params",
    "subject_split",
    "write_field",
]
