r"""The bench's error part: every timed estimator and the two oracles scored on the held-out eval split (or on
the shipped probe's check part), and the skips measured on a light-stage clip.

``kornia-ilum bench`` (:mod:`kornia_ilum.bench`, the library) times the estimators; where the lab is installed, it
finds :class:`BenchError` through the ``kornia_ilum.bench`` entry point ``error`` and adds its columns: ``L_rec``
per sphere, indoor and outdoor, the relative radiance, the diffuse ``L_rec`` per skin tone, and the skips'
section. The error is measured by :func:`~kornia_ilum_lab.evaluation.evaluate`'s scores, as ``kornia-ilum
evaluate`` measures it.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from typing import Any

from kornia_ilum.estimators.probe import CHECK
from kornia_ilum_lab.bench.skips import skip_rows
from kornia_ilum_lab.evaluation import (
    ORACLES,
    EvalSet,
    build_eval_set,
    oracle_predictions,
    predict,
    probe_eval_set,
    score,
    summarize,
)

__all__ = ["BenchError"]


class BenchError:
    r"""What the bench's error columns are measured on, and how (the ``kornia_ilum.bench`` entry point ``error``).

    Args:
        cache: light-stage caches: score on their held-out eval split (``samples`` portraits, ``kornia-ilum
            evaluate``'s set) and measure the skips there; empty: the shipped probe's check part (light-stage
            training portraits, labelled as such).
        hdri: the real maps' folders, with ``cache``.
        samples: eval portraits with ``cache``.
        quick: the first 32 portraits of the probe's check part, and the skips' short form (CI).

    Examples:
        >>> error = BenchError(quick=True)  # the probe's check part, 32 portraits
        >>> error.what.startswith("the shipped probe's check part (32 light-stage TRAINING portraits")
        True
    """

    def __init__(self, cache: Sequence[str | os.PathLike[str]] = (), hdri: Sequence[str | os.PathLike[str]] = (),
                 *, samples: int = 1024, quick: bool = False) -> None:
        self.cache, self.hdri, self.quick = list(cache), list(hdri), quick
        if self.cache:
            self.eval_set: EvalSet = build_eval_set(self.cache, self.hdri, samples=samples)
            self.what = (f"the held-out eval split ({len(self.eval_set)} portraits of "
                         f"{len(self.eval_set.description['subjects'])} eval subjects, kornia-ilum evaluate's set)")
        else:
            part = slice(CHECK.start, CHECK.start + 32) if quick else CHECK
            self.eval_set = probe_eval_set(part)
            self.what = (f"the shipped probe's check part ({len(self.eval_set)} light-stage TRAINING portraits: not "
                         "the held-out split, no evidence of accuracy; pass --cache for that)")

    def score(self, models: dict[str, Any], rows: list[dict[str, Any]]) -> dict[str, Any]:
        """Score every timed model (by its row's label) and the oracles; add their error to ``rows`` in place.

        Args:
            models: row label -> the model as timed.
            rows: the bench's rows; the oracles' rows are appended, and every scored row gets ``l_rec``,
                ``l_rec_groups`` and ``relative_radiance``.

        Returns:
            a dict: ``per_tone`` (label -> tone -> diffuse ``L_rec``), ``error`` (``what``, ``short``,
            ``eval_set``), ``methods`` (how many were scored) and ``seconds``.
        """
        t0 = time.perf_counter()
        methods = {}
        for label, model in models.items():
            t = time.perf_counter()
            methods[label] = {"scores": score(predict(model, self.eval_set.images), self.eval_set.mirror_ball),
                              "seconds": round(time.perf_counter() - t, 2)}
        for label, pred in oracle_predictions(self.eval_set.mirror_ball).items():
            methods[label] = {"scores": score(pred, self.eval_set.mirror_ball), "seconds": 0.0}
        summary = summarize({"methods": methods, "skipped": {}}, self.eval_set, reference="__none__")
        rows += [{"label": o, "estimator": o, "runtime": "oracle"} for o in ORACLES]
        for r in rows:
            t1 = summary["table1_l_rec"].get(r["label"])
            if t1 is not None:
                r["l_rec"] = t1["all"]
                r["l_rec_groups"] = {g: t1[g] for g in ("indoor", "outdoor")}
                r["relative_radiance"] = summary["table2_relative_radiance"][r["label"]]["all"]["mean"]
        per_tone = {label: {t: v["diffuse"] for t, v in per.items()}
                    for label, per in summary["per_skin_tone"].items()}
        return {"per_tone": per_tone, "methods": len(methods), "seconds": time.perf_counter() - t0,
                "error": {"what": self.what, "short": self.eval_set.description.get("source", "eval split"),
                          "eval_set": self.eval_set.description}}

    def skips(self) -> tuple[list[dict[str, Any]], str] | None:
        """The skips' rows and what they were measured on (:func:`~kornia_ilum_lab.bench.skips.skip_rows`), with
        a cache; ``None`` without one."""
        return skip_rows(self.cache, self.hdri, quick=self.quick) if self.cache else None
