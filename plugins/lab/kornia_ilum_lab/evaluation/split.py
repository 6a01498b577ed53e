r"""The held-out evaluation split: unseen subjects, held-out real maps, held-out procedural seeds.

Nothing here is trained on, as long as training keeps to the train side of each of the three splits:

- **Subjects**: the light-stage subjects of split ``"eval"``
  (:func:`~kornia_ilum_lab.synth.lightstage.subjects.base.subject_split`, about one seed in ten), read from one or
  more caches with :func:`~kornia_ilum_lab.synth.lightstage.portraits.load_fields` ``(cache, split="eval")``
  (the training cache and, for more subjects, an eval-only cache rendered with
  ``kornia-ilum synth subjects --split eval --seeds ...``).
- **Real maps**: the maps of split ``"eval"`` of :func:`~kornia_ilum_lab.synth.environments.real.hdri_split`
  (about one file name in four, by a stable hash; training must use
  ``HDRFolderSource(folder, split="train")``). :func:`heldout_maps` lists them per folder.
- **Procedural environments**: skies, rooms and portrait lights drawn by an
  :class:`~kornia_ilum_lab.synth.environments.EnvironmentSampler` with the seed :data:`EVAL_SEED`. A sampler draws
  environment ``index`` from ``blake2b(f"kornia_ilum.synth:{seed}:{index}")``, so a seed's stream shares no
  draw with another seed's; training uses the small seeds ``0..N`` (one per run), far from :data:`EVAL_SEED`.

The portraits themselves (field, crop, flip, exposure, camera effects) are drawn by
:class:`~kornia_ilum_lab.synth.lightstage.portraits.PortraitDataset` with the seed :data:`EVAL_SEED` too, so the eval
set is the same every run (:func:`kornia_ilum_lab.evaluation.build_eval_set`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from kornia_ilum.core.errors import TypeCheckError, ValueCheckError
from kornia_ilum_lab.synth.environments.indoor import IndoorSource
from kornia_ilum_lab.synth.environments.portrait import PortraitLightSource
from kornia_ilum_lab.synth.environments.real import HDRFolderSource, folder_splits, guess_label
from kornia_ilum_lab.synth.environments.sky import SkySource
from kornia_ilum_lab.synth.lightstage.portraits import load_fields

__all__ = ["EVAL_SEED", "eval_environment_sources", "eval_fields", "heldout_maps"]

#: The seed of the eval set's environment sampler and portraits. Training seeds are small (0..N); this one is
#: not used for training anywhere in the project.
EVAL_SEED = 1_000_003


def heldout_maps(folders: Sequence[str | os.PathLike[str]]) -> dict[str, dict[str, Any]]:
    r"""The real maps of each folder, by split, with their labels: what a model card should list.

    Args:
        folders: folders of lat-long maps.

    Returns:
        ``{folder: {"eval": {name: label}, "train": {name: label}}}``, names sorted
        (:func:`~kornia_ilum_lab.synth.environments.real.folder_splits`,
        :func:`~kornia_ilum_lab.synth.environments.real.guess_label`).

    Raises:
        HDRIOError: a folder does not exist.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     for name in ("studio.exr", "meadow.exr"):
        ...         Path(tmp, name).touch()  # only the names count: the maps are not read
        ...     heldout_maps([tmp])[tmp]
        {'eval': {'studio.exr': 'indoor'}, 'train': {'meadow.exr': 'outdoor'}}
    """
    out: dict[str, dict[str, Any]] = {}
    for folder in folders:
        splits = folder_splits(folder)
        out[str(folder)] = {
            split: {n: guess_label(n) for n, s in splits.items() if s == split} for split in ("eval", "train")
        }
    return out


def eval_environment_sources(hdri: Sequence[str | os.PathLike[str]] = (), height: int = 128) -> list:
    r"""The eval set's environment sources: procedural skies, rooms and portrait lights, plus the eval maps of
    ``hdri``.

    The procedural sources are those of training
    (:func:`~kornia_ilum_lab.synth.environments.default_sources`), drawn with another seed.

    Args:
        hdri: folders of real maps; each gives ``HDRFolderSource(folder, height, split="eval")``.
        height: the working height of the lat-long maps.

    Returns:
        ``[SkySource, IndoorSource, PortraitLightSource, HDRFolderSource(...), ...]`` (sample them with
        :data:`EVAL_SEED`; the default weights give the portrait lights a quarter of the draws).

    Raises:
        HDRIOError: a folder does not exist or holds no map of split ``"eval"``.

    Examples:
        >>> [type(s).__name__ for s in eval_environment_sources()]
        ['SkySource', 'IndoorSource', 'PortraitLightSource']
    """
    procedural = [SkySource(height=height), IndoorSource(height=height), PortraitLightSource(height=height)]
    return procedural + [
        HDRFolderSource(folder, height=height, split="eval") for folder in hdri
    ]


def eval_fields(caches: Sequence[str | os.PathLike[str]] = (), fields: Sequence[Any] = ()) -> list:
    r"""The reflectance fields of the eval subjects of ``caches``, then the eval fields among ``fields``.

    Args:
        caches: light-stage cache folders (:func:`~kornia_ilum_lab.synth.lightstage.build_cache`); each gives
            ``load_fields(cache, split="eval")`` (a cache without eval subjects gives none).
        fields: :class:`~kornia_ilum_lab.synth.lightstage.ReflectanceField` objects; those with
            ``meta["split"] == "eval"`` are kept.

    Returns:
        the fields, caches first (in the order given, each sorted by seed and view).

    Raises:
        ValueCheckError: no eval field at all, the same subject seed in two caches, or a lighting size other
            than 32 (the estimators' and the metrics' size).
        TypeCheckError: ``caches`` is one folder, not a sequence of them.

    Examples:
        >>> eval_fields([])
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: no eval subject in the caches [] (or fields)
        >>> fields = eval_fields(["lightstage/"])  # a cache built by kornia-ilum synth  # doctest: +SKIP
    """
    if isinstance(caches, (str, os.PathLike)):
        raise TypeCheckError("caches must be a sequence of folders, not one folder")
    out: list = []
    seen: dict[int, str] = {}
    for cache in caches:
        try:
            loaded = load_fields(cache, split="eval")
        except ValueCheckError as e:
            if "no reflectance field" not in str(e):
                raise
            loaded = []
        for seed in {f.subject_seed for f in loaded}:
            if seed in seen:
                raise ValueCheckError(f"subject seed {seed} is in both {seen[seed]} and {cache}")
            seen[seed] = str(cache)
        out.extend(loaded)
    out.extend(f for f in fields if f.meta.get("split") == "eval")
    if not out:
        raise ValueCheckError(f"no eval subject in the caches {[str(Path(c)) for c in caches]} (or fields)")
    sizes = {f.lighting_size for f in out}
    if sizes != {32}:
        raise ValueCheckError(f"the eval fields must have lighting size 32, got {sorted(sizes)}")
    return out
