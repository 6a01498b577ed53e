"""Subjects of the virtual light stage: MakeHuman heads (photoreal, from CC0 assets) and SDF mannequins.

:func:`subject_source` picks a source by name; both give :class:`Subject` objects that every renderer takes.
"""

from typing import Any

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
from kornia_ilum_lab.synth.lightstage.subjects.makehuman import (
    MakeHumanAssetsNotFoundError,
    MakeHumanSource,
    find_makehuman_root,
)
from kornia_ilum_lab.synth.lightstage.subjects.mannequin import MannequinSource, make_subject, subject_params


def subject_source(name: str, assets: str | None = None, **options: Any) -> SubjectSource:
    """The subject source called ``name``: ``"makehuman"`` (photoreal, needs the assets) or ``"mannequin"``.

    Args:
        name: ``"makehuman"`` or ``"mannequin"``.
        assets: the MakeHuman data root for ``"makehuman"`` (default: ``$KORNIA_ILUM_MAKEHUMAN``, else
            ``$KORNIA_ILUM_SHARED_DATA/makehuman``); unused by ``"mannequin"``.
        options: :class:`MakeHumanSource`'s options (``clothes``, ``cut_below_chin``); ``"mannequin"`` takes none.

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
        if options:
            raise ValueCheckError(f"the mannequins take no options, got {sorted(options)}")
        return MannequinSource()
    if name == "makehuman":
        return MakeHumanSource(find_makehuman_root(assets), **options)
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
