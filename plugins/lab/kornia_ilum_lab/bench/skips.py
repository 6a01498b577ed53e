r"""What each skip saves against what it costs, on the held-out split: the ``skips`` section of ``kornia-ilum bench``.

With ``--cache``, ``kornia-ilum bench`` takes the first eval subject-view of the caches and the held-out real maps
(``hdri_split`` "eval") of ``--hdri``, and measures, each against its own baseline in the same process:

- **video** (:class:`~kornia_ilum.video.LightingTracker`): a clip of the subject under a held-out map turning by
  2.8 degrees a frame, then a cut to another held-out map (:func:`video_clip`); per-frame estimation against
  the tracker's defaults (and the ``auto`` runtime): ms per frame, and as error the median
  ``|log(E_est / E_true)|``, the flicker over the truth's own (:func:`flicker`) and the lag after the cut
  (:func:`lag`);
- **sparse relighting** (:func:`~kornia_ilum.render.relight_sparse`): the subject relit by each held-out map
  at 16 yaws, dense against sparse (:data:`RELIGHT_SETTINGS`): ms per batch, and as error the paper's
  ``L_rec`` applied to the portrait (:func:`lrec_like`), over all the maps, the sun-dominated ones and the
  sun-dominated outdoor ones.

The measurements are :mod:`~kornia_ilum_lab.bench.video` and :mod:`~kornia_ilum_lab.bench.relight`, on the
clips of :mod:`~kornia_ilum_lab.bench.maps`; this module runs both on a cache (:func:`skip_rows`). Detection at a
reduced side, the other skip of the estimate, is the end-to-end section of the bench.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum_lab.bench.maps import held_out_maps
from kornia_ilum_lab.bench.relight import relight_skips
from kornia_ilum_lab.bench.video import video_skips
from kornia_ilum_lab.evaluation.split import eval_fields

__all__ = ["skip_rows"]


def skip_rows(caches: Sequence[str | os.PathLike[str]], hdri: Sequence[str | os.PathLike[str]],
              quick: bool = False) -> tuple[list[dict[str, Any]], str]:
    """Every skip's rows, and one line saying what they were measured on (or why nothing was).

    Args:
        caches: light-stage caches; the first of their eval subject-views is relit.
        hdri: folders of real maps; their held-out maps light it (two at least).
        quick: the short form of each skip (CI).

    Returns:
        ``(rows, what)``: the rows of :func:`video_skips` then :func:`relight_skips`, and the line; no rows
        without an eval subject or two held-out maps.

    Examples:
        >>> skip_rows([], [])
        ([], 'skips: not measured (needs an eval subject in --cache and two held-out maps in --hdri)')
    """
    try:
        fields = eval_fields(caches)
    except ValueCheckError:
        fields = []
    maps = held_out_maps(hdri)
    if not fields or len(maps) < 2:
        return [], "skips: not measured (needs an eval subject in --cache and two held-out maps in --hdri)"
    field = fields[0]
    what = (f"eval subject {field.subject_seed} (view {field.meta.get('view_index', 0)}) under the held-out maps "
            f"{', '.join(p.name for p in maps)}")
    return video_skips(field, maps, quick=quick) + relight_skips(field, maps, quick=quick), what
