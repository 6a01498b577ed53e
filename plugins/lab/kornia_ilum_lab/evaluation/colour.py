r"""The colour check: the same portraits through the colour looks users apply, and how far the main light moves.

Where the light comes from is written in the shading, not in the colours: an estimator that reads the light's
direction from the shading gives the same main light for a photo and for its black-and-white, warmer, cooler,
desaturated or graded copy. :func:`colour_check` applies each look of
:data:`~kornia_ilum_lab.synth.colour_looks.LOOKS` to the portraits (sRGB crops) and reports, per look, the angle
between the dominant direction of the estimate of the look and that of the original
(:func:`~kornia_ilum_lab.evaluation.measures.dominant_direction`), in degrees, and the ratio of their energies
(``E(look) / E(original)``). It needs no label, so it runs on the eval split and on real photos alike.

The energy's ratio is not expected to be 1 for every look: a white balance keeps the luminance but moves the
channels, and the energy is the mean of R, G and B; a grade changes the photo's units. The greyscale look's
ratio says how much of the light the estimator attributes to the colours it no longer sees.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import torch

from kornia_ilum.core.check import check_positive_int
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.metrics import lighting_energy
from kornia_ilum_lab.evaluation.bootstrap import subject_interval
from kornia_ilum_lab.evaluation.measures import (
    Estimator,
    angle_degrees,
    as_floats,
    dominant_direction,
    estimates,
    quantiles,
)
from kornia_ilum_lab.synth.colour_looks import LOOKS, Look, apply_look

__all__ = ["COLOUR_LOOKS", "colour_check", "colour_markdown"]

#: The looks the check applies, in its tables' order.
COLOUR_LOOKS: tuple[str, ...] = ("greyscale", "desaturated", "warm", "cool", "teal_orange", "faded", "sepia")


def colour_check(estimator: Estimator, images: torch.Tensor, *, subjects: Sequence[int] | None = None,
                 looks: Sequence[str] = COLOUR_LOOKS, prediction: torch.Tensor | None = None,
                 batch_size: int = 32) -> dict[str, Any]:
    r"""How far each colour look turns the estimated main light, and how it changes its strength.

    Args:
        estimator: the estimator (:mod:`~kornia_ilum_lab.evaluation.measures`).
        images: ``(N, 3, H, W)`` sRGB crops, ``uint8`` codes or floats in ``[0, 1]``.
        subjects: the subject of each crop: the medians then carry a 95 % interval over subjects
            (:func:`~kornia_ilum_lab.evaluation.bootstrap.subject_interval`).
        looks: names of :data:`~kornia_ilum_lab.synth.colour_looks.LOOKS`.
        prediction: the estimator's lighting on ``images`` as they are, if already made (saves a pass).
        batch_size: crops per pass.

    Returns:
        a dict: ``"table"`` maps each look to ``"angle"`` and ``"ratio"`` (their quantiles), ``"angle_ci"`` (the
        median angle's interval, or ``None`` without ``subjects``) and ``"no_direction"`` (a count); ``"angle"``
        and ``"ratio"`` map each look to ``(N,)`` values: the angles in degrees (NaN where either estimate has no
        main direction) and the ratios ``E(look) / E(original)``.

    Raises:
        ValueCheckError: an unknown look, or ``subjects`` of another length than ``images``.

    Shape:
        - images: :math:`(N, 3, H, W)`; prediction: :math:`(N, 3, S, S)`

    Convention:
        Directions in the camera frame (docs/conventions.rst, "Frames"); sRGB crops ("Images").

    Examples:
        >>> from kornia_ilum.estimators import create_estimator
        >>> out = colour_check(create_estimator("uniform"), torch.rand(2, 3, 64, 64), looks=["greyscale"])
        >>> out["table"]["greyscale"]["no_direction"]  # a uniform light has no main direction
        2
    """
    check_positive_int(batch_size, "batch_size")
    unknown = [name for name in looks if name not in LOOKS]
    if unknown:
        raise ValueCheckError(f"unknown looks {unknown}; the looks are {', '.join(sorted(LOOKS))}")
    if subjects is not None and len(subjects) != len(images):
        raise ValueCheckError(f"subjects has {len(subjects)} entries for {len(images)} images")

    def batches(name: str | None):
        for i in range(0, len(images), batch_size):
            crops = as_floats(images[i:i + batch_size])
            yield crops if name is None else apply_look(crops, Look.named(name, len(crops)))

    if prediction is None:
        energy, direction, _ = estimates(estimator, batches(None), directions=True)
    else:
        ball = prediction.double()
        energy, direction = lighting_energy(ball), dominant_direction(ball)
    table, angles, ratios = {}, {}, {}
    for name in looks:
        e, d, _ = estimates(estimator, batches(name), directions=True)
        angles[name], ratios[name] = angle_degrees(d, direction), e / energy
        table[name] = {"angle": quantiles(angles[name]), "ratio": quantiles(ratios[name]),
                       "angle_ci": None if subjects is None else subject_interval(angles[name], list(subjects)),
                       "no_direction": int(torch.isnan(angles[name]).sum())}
    return {"table": table, "angle": angles, "ratio": ratios}


def colour_markdown(tables: dict[str, dict[str, Any]]) -> list[str]:
    r"""The colour check's Markdown table: per method, photos and look, the median angle [95 % interval over
    subjects] and the median energy ratio.

    Args:
        tables: method name to ``{"eval" | "photos" | "flash": colour_check(...)["table"]}``.

    Returns:
        the table's lines (none for no method).

    Examples:
        >>> row = {"angle": {"median": 2.0}, "ratio": {"median": 1.1}, "angle_ci": [1.0, 3.0], "no_direction": 0}
        >>> lines = colour_markdown({"ours": {"eval": {"greyscale": row}}})
        >>> "| ours | eval crops | 2.0 [1.0, 3.0] |" in lines, lines[-1]
        (True, '| ours | eval crops | 1.10 |')
    """
    if not tables:
        return []
    looks = list(dict.fromkeys(look for sets in tables.values() for t in sets.values() for look in t))
    labels = {"eval": "eval crops", "photos": "real photos", "flash": "real-flash photos"}
    lines = ["", "## Colour check: how far the main light turns (degrees, median [95 % interval over subjects]) "
             "under each look, and E(look) / E(original) (median)", ""]
    lines += ["| method | photos | " + " | ".join(looks) + " |", "|---|---|" + "---:|" * len(looks)]
    for name, sets in tables.items():
        for which, table in sets.items():
            cells = []
            for look in looks:
                row = table.get(look)
                angle = None if row is None else row["angle"]["median"]
                text = "-" if angle is None else f"{angle:.1f}"
                if row is not None and row.get("angle_ci") is not None:
                    text += " [{:.1f}, {:.1f}]".format(*row["angle_ci"])
                cells.append(text)
            lines.append(f"| {name} | {labels.get(which, which)} | " + " | ".join(cells) + " |")
    lines += ["", "| method | photos | " + " | ".join(f"E ratio {look}" for look in looks) + " |",
              "|---|---|" + "---:|" * len(looks)]
    for name, sets in tables.items():
        for which, table in sets.items():
            cells = ["-" if table.get(look) is None or table[look]["ratio"]["median"] is None
                     else f"{table[look]['ratio']['median']:.2f}" for look in looks]
            lines.append(f"| {name} | {labels.get(which, which)} | " + " | ".join(cells) + " |")
    return lines
