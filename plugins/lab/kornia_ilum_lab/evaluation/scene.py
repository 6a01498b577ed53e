r"""The strength of the light from the whole photograph, scored per skin tone: the face alone, the scene branch
alone, and the two fused by their spreads (:mod:`kornia_ilum.estimators.scene`).

On an eval set built with its frames (:func:`~kornia_ilum_lab.evaluation.build_eval_set` with
``portraits={"frame": 128}``), for every portrait: ``E_face`` (the face estimator's lighting, its energy by
:func:`~kornia_ilum.metrics.lighting_energy`), ``E_scene`` (the scene branch's, the mean of its
three channels' energies) and ``E_fused`` (:func:`~kornia_ilum.estimators.scene.fuse_strength`), each over the
truth's. Per Monk tone: the median ratio with its 95 % interval over subjects, the largest over the smallest
per-tone median (the tone spread) with its interval, and how often the truth's log energy lies within one spread
of each estimate (nominal :math:`1 - 1/e = 0.632` for a Laplace spread): an honest spread is what a user needs
where the photo cannot settle the strength.
"""

from __future__ import annotations

import math
from typing import Any

import torch
from torch import nn

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.estimators.scene import fuse_strength, scene_input
from kornia_ilum.metrics import lighting_energy
from kornia_ilum_lab.evaluation.bootstrap import ratio_interval, subject_interval
from kornia_ilum_lab.evaluation.evaluate import EvalSet
from kornia_ilum_lab.evaluation.measures import as_floats, median_of

__all__ = ["NOMINAL_COVERAGE", "scene_check"]

#: The share of true log energies within one Laplace spread of the estimate, for an honest spread.
NOMINAL_COVERAGE = 1.0 - math.exp(-1.0)


def scene_check(estimator: nn.Module, scene: nn.Module, eval_set: EvalSet, *, batch_size: int = 32
                ) -> dict[str, Any]:
    r"""The face's, the scene's and the fused strength on ``eval_set`` (module docstring).

    Args:
        estimator: a face estimator whose estimates carry ``log_energy_spread`` (``ours`` with its spread head).
        scene: a :class:`~kornia_ilum.estimators.scene.SceneStrength`.
        eval_set: an eval set with ``frames``.
        batch_size: portraits per pass.

    Returns:
        a dict: ``table`` (per group, ``all`` and each tone, and per estimate, ``face``, ``scene`` and
        ``fused``: the median ``ratio``, its interval ``ratio_ci`` and the ``coverage``; and the group's
        ``count``), ``tone_spread`` (per estimate, :func:`~kornia_ilum_lab.evaluation.bootstrap.ratio_interval`'s
        result), ``count``, and ``samples``: per estimate, each portrait's ``ratio`` (estimated over true energy)
        and ``spread``, in the set's order.

    Raises:
        ValueCheckError: the set has no frames, or the estimator gives no spread.
    """
    if eval_set.frames is None or eval_set.frame_boxes is None:
        raise ValueCheckError("scene_check needs the eval set's frames: build_eval_set(portraits={'frame': 128})")
    energy: dict[str, list[torch.Tensor]] = {"face": [], "scene": [], "fused": []}
    spread: dict[str, list[torch.Tensor]] = {"face": [], "scene": [], "fused": []}
    with torch.no_grad():
        for i in range(0, len(eval_set), batch_size):
            crops = as_floats(eval_set.images[i : i + batch_size])
            frames = eval_set.frames[i : i + batch_size].float() / 255.0
            x = scene_input(frames, eval_set.frame_boxes[i : i + batch_size].float(), torch.arange(len(frames)),
                            size=frames.shape[-1])
            face = estimator(crops)
            if face.log_energy_spread is None:
                raise ValueCheckError("scene_check needs a face estimator with a spread (ours with spread_head)")
            log_energy, b = scene(x)
            fused = fuse_strength(face, log_energy, b)
            for kind, value, width in (("face", lighting_energy(face.mirror_ball.double()), face.log_energy_spread),
                                       ("scene", torch.exp(log_energy.double()).mean(1), b),
                                       ("fused", lighting_energy(fused.mirror_ball.double()),
                                        fused.log_energy_spread)):
                energy[kind].append(value)
                spread[kind].append(width.double())
    truth = lighting_energy(eval_set.mirror_ball.double())
    subjects = torch.tensor(list(eval_set.subject_seed))
    tones = torch.tensor(list(eval_set.skin_tone))
    groups = {"all": torch.ones(len(tones), dtype=torch.bool)} | {
        str(t): tones == t for t in sorted(set(tones.tolist())) if t > 0}
    ratios = {k: torch.cat(v) / truth for k, v in energy.items()}
    inside = {k: (torch.log(ratios[k]).abs() <= torch.cat(spread[k])).double() for k in ratios}
    table = {g: {k: {"ratio": median_of(r[m]), "ratio_ci": subject_interval(r[m], subjects[m]),
                     "coverage": float(inside[k][m].mean())} for k, r in ratios.items()}
             for g, m in groups.items()}
    for g, m in groups.items():
        table[g]["count"] = int(m.sum())
    tone_spread = {k: ratio_interval({g: (r[m], subjects[m]) for g, m in groups.items() if g != "all"})
                   for k, r in ratios.items()}
    samples = {k: {"ratio": ratios[k], "spread": torch.cat(spread[k])} for k in ratios}
    return {"table": table, "tone_spread": tone_spread, "count": len(eval_set), "samples": samples}
