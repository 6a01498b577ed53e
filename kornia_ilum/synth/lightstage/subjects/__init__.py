"""Subjects of the virtual light stage: MakeHuman heads (photoreal, from CC0 assets) and SDF mannequins.

:func:`subject_source` picks a source by name; both give :class:`Subject` objects that every renderer takes.
"""

from kornia_ilum.synth.lightstage.subjects.base import (
    LANDMARK_NAMES,
    MONK_SKIN_TONES_SRGB,
    SKIN_ALBEDO,
    SKIN_ALBEDO_SCALE,
    Material,
    MeshPart,
    Subject,
    SubjectSource,
    subject_split,
)
from kornia_ilum.synth.lightstage.subjects.mannequin import MannequinSource, make_subject, subject_params

__all__ = [
    "LANDMARK_NAMES",
    "MONK_SKIN_TONES_SRGB",
    "SKIN_ALBEDO",
    "SKIN_ALBEDO_SCALE",
    "MannequinSource",
    "Material",
    "MeshPart",
    "Subject",
    "SubjectSource",
    "make_subject",
    "subject_params",
    "subject_split",
]
