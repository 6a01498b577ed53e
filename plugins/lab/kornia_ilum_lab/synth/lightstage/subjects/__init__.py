"""Subjects of the virtual light stage: MakeHuman heads (photoreal, from CC0 assets) and SDF mannequins.

:func:`subject_source` picks a source by name; both give :class:`Subject` objects that every renderer takes.
"""

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum_lab.synth.lightstage.subjects.base import (
    LANDMARK_NAMES,
    MONK_SKIN_TONES_SRGB,
    SKIN_ALBEDO,
    Material,
    MeshPart,
    Subject,
    SubjectSource,
    subject_split,
)
from kornia_ilum_lab.synth.lightstage.subjects.makehuman import MakeHumanAssetsNotFoundError, MakeHumanSource
from kornia_ilum_lab.synth.lightstage.subjects.mannequin import MannequinSource, make_subject, subject_params


def subject_source(name: str, assets: str | None = None) -> SubjectSource:
    """The subject source called ``name``: ``"makehuman"`` (photoreal, needs the assets) or ``"mannequin"``.

    Args:
        name: ``"makehuman"`` or ``"mannequin"``.
        assets: the MakeHuman data root for ``"makehuman"`` (default: ``$KORNIA_ILUM_MAKEHUMAN``, else
            ``$KORNIA_ILUM_SHARED_DATA/makehuman``); unused by ``"mannequin"``.

    Returns:
        The source (parsing is deferred to its first ``sample``).

    Raises:
        ValueCheckError: unknown ``name``.
        MakeHumanAssetsNotFoundError: ``"makehuman"`` without the assets.

    Examples:
        >>> subject_source("mannequin").name
        'mannequin'
    """
    if name == "mannequin":
        return MannequinSource()
    if name == "makehuman":
        return MakeHumanSource.from_assets(assets)
    raise ValueCheckError(f"unknown subject source {name!r}; expected 'makehuman' or 'mannequin'")


__all__ = [
    "LANDMARK_NAMES",
    "MONK_SKIN_TONES_SRGB",
    "SKIN_ALBEDO",
    "MakeHumanAssetsNotFoundError",
    "MakeHumanSource",
    "MannequinSource",
    "Material",
    "MeshPart",
    "Subject",
    "SubjectSource",
    "make_subject",
    "subject_params",
    "subject_source",
    "subject_split",
]
