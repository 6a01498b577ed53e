r"""The real-flash check: real faces under one flash of known direction, and where the estimate puts the main light.

The light stage is synthetic; a check on it cannot say whether an estimator reads real faces. A set of real
photographs, each of one person under one flash of known direction in a dark room, can: the flash is the light,
so the main light's direction is known. The Extended Yale Face Database B is such a set (its ``yaleb_dev``
subset: 10 people under 64 flashes each; Georghiades, Belhumeur and Kriegman, "From Few to Many", IEEE TPAMI
2001; Lee, Ho and Kriegman, "Acquiring Linear Subspaces for Face Recognition under Variable Lighting", IEEE TPAMI
2005). It is read by path and never copied, trained on or shipped (its terms: research use, with
acknowledgement).

- :func:`load_flash_set` reads a folder of such photographs, named ``<subject>_P<pose>A<azimuth>E<elevation>``
  (the database's names: ``yaleB01_P00A+035E+40.pgm``), and gives each flash's direction in the project's
  frame, :func:`flash_direction`: ``d = (-sin A cos E, sin E, cos A cos E)`` (+X image right, +Y up, +Z toward
  the camera; a positive azimuth lights the image's left half).
- :func:`flash_crops` cuts the face crop of each photograph as :func:`kornia_ilum.estimate_lighting` does (the
  default detector's largest face; the full image's centred square where no face is found, as its
  ``fallback="full_image"``; the photographs are tight face crops, so some need it), and records which fell back.
- :func:`real_flash_check` runs an estimator on them and reports the main light's direction error (the angle
  between the estimate's dominant direction, its l = 1 "dipole", and the flash's), its median over all flashes
  and for flashes within 25 degrees of the camera axis, 25 to 60 and beyond 60, split into its elevation bias
  (the estimate's elevation minus the flash's: a light put above where it is) and its azimuth error; the
  left/right and up/down sign
  agreement (over flashes at least 10 degrees off the vertical, resp. horizontal, plane); and, for each flash
  across the people, the spread (standard deviation) of the estimated log energy against the spread of the
  faces' own log brightness: one flash has one strength, so an estimator that reads the light and not the skin
  keeps the first well below the second. Every median carries a 95 % interval over people
  (:func:`~kornia_ilum_lab.evaluation.bootstrap.subject_interval`).
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import kornia
import torch

from kornia_ilum.api import find_faces, full_image_box
from kornia_ilum.color import LUMINANCE, srgb_to_linear
from kornia_ilum.core.check import check_positive_int
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.detection import DEFAULT_DETECTOR, FaceDetector, crop_faces
from kornia_ilum.io import read_ldr
from kornia_ilum_lab.evaluation.bootstrap import median, subject_interval
from kornia_ilum_lab.evaluation.measures import Estimator, angle_degrees, as_floats, estimates, quantiles

__all__ = ["AXIS_BANDS", "FLASH_NAME", "FlashSet", "flash_crops", "flash_direction", "flash_markdown",
           "load_flash_set", "real_flash_check"]

#: A photograph's name: subject, pose, flash azimuth and elevation in degrees (the database's own names).
FLASH_NAME = re.compile(r"^(?P<subject>.+?)_P(?P<pose>\d+)A(?P<azimuth>[+-]\d+)E(?P<elevation>[+-]\d+)"
                        r"\.(?:pgm|png|jpe?g|tiff?|bmp)$", re.IGNORECASE)
#: The bands of the flash's angle to the camera axis, in degrees: ``(name, low, high)``, ``low <= angle < high``.
AXIS_BANDS: tuple[tuple[str, float, float], ...] = (("within 25", 0.0, 25.0), ("25-60", 25.0, 60.0),
                                                    ("beyond 60", 60.0, 181.0))
#: The sign checks leave out flashes closer than this (degrees) to the plane that splits the sides.
SIGN_MARGIN_DEG = 10.0


def flash_direction(azimuth_deg: torch.Tensor, elevation_deg: torch.Tensor) -> torch.Tensor:
    r"""The flash's direction in the project's frame from its azimuth and elevation (module docstring).

    Args:
        azimuth_deg, elevation_deg: angles in degrees, relative to the camera axis.

    Returns:
        unit vectors, float64.

    Shape:
        - azimuth_deg, elevation_deg: :math:`(N,)`
        - Output: :math:`(N, 3)`

    Convention:
        docs/conventions.rst, "Frames": +X right, +Y up, +Z toward the camera; light arriving from ``d``.

    Examples:
        >>> flash_direction(torch.tensor([0.0, 90.0]), torch.tensor([0.0, 0.0])).round(decimals=6).tolist()
        [[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]]
    """
    a = torch.deg2rad(torch.as_tensor(azimuth_deg, dtype=torch.float64))
    e = torch.deg2rad(torch.as_tensor(elevation_deg, dtype=torch.float64))
    return torch.stack([-torch.sin(a) * torch.cos(e), torch.sin(e), torch.cos(a) * torch.cos(e)], -1)


@dataclass(frozen=True)
class FlashSet:
    r"""Photographs under one known flash each (:func:`load_flash_set`).

    Args:
        paths: the files.
        subjects: the person of each (the name's subject).
        azimuth, elevation: ``(N,)`` the flash's angles in degrees.
        directions: ``(N, 3)`` the flash's direction (:func:`flash_direction`).
    """

    paths: tuple[str, ...]
    subjects: tuple[str, ...]
    azimuth: torch.Tensor
    elevation: torch.Tensor
    directions: torch.Tensor

    def __len__(self) -> int:
        return len(self.paths)

    @property
    def people(self) -> list[int]:
        """The person of each photograph as an index (the subjects' names, sorted)."""
        return _subject_ids(self.subjects)

    @property
    def axis_angle(self) -> torch.Tensor:
        """``(N,)`` the flash's angle to the camera axis, in degrees."""
        return torch.rad2deg(torch.arccos(self.directions[:, 2].clamp(-1.0, 1.0)))


def load_flash_set(folder: str | os.PathLike[str]) -> FlashSet:
    r"""The photographs of ``folder`` (searched recursively) whose names give their flash (:data:`FLASH_NAME`).

    Args:
        folder: the folder, e.g. ``../shared/data/yaleb_dev``.

    Returns:
        the :class:`FlashSet`, sorted by path.

    Raises:
        ValueCheckError: the folder is missing or holds no such photograph.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     _ = Path(tmp, "p1_P00A+035E-20.pgm").write_bytes(b"")
        ...     found = load_flash_set(tmp)
        >>> found.subjects, found.azimuth.tolist(), found.elevation.tolist()
        (('p1',), [35.0], [-20.0])
    """
    root = Path(folder)
    if not root.is_dir():
        raise ValueCheckError(f"the real-flash folder {os.fspath(folder)!r} does not exist")
    rows = []
    for path in sorted(root.rglob("*")):
        m = FLASH_NAME.match(path.name)
        if m and path.is_file():
            rows.append((os.fspath(path), m["subject"], float(m["azimuth"]), float(m["elevation"])))
    if not rows:
        raise ValueCheckError(f"no photograph named like yaleB01_P00A+035E+40.pgm in {os.fspath(folder)!r}")
    paths, subjects, azimuth, elevation = zip(*rows, strict=True)
    az, el = torch.tensor(azimuth, dtype=torch.float64), torch.tensor(elevation, dtype=torch.float64)
    return FlashSet(paths=paths, subjects=subjects, azimuth=az, elevation=el, directions=flash_direction(az, el))


def flash_crops(flash_set: FlashSet, detector: str | FaceDetector = DEFAULT_DETECTOR, *, size: int = 256
                ) -> tuple[torch.Tensor, torch.Tensor]:
    r"""The face crop of each photograph, as :func:`kornia_ilum.estimate_lighting` cuts it (module docstring).

    Args:
        flash_set: the photographs.
        detector: a registered detector name or a :class:`~kornia_ilum.detection.FaceDetector`.
        size: the crops' side.

    Returns:
        ``(crops, fell_back)``: ``(N, 3, size, size)`` float32 sRGB crops, and ``(N,)`` bool, the photographs in
        which the detector found no face (their crop is the full image's centred square).

    Shape:
        - Output: :math:`(N, 3, size, size)`, :math:`(N,)`
    """
    check_positive_int(size, "size")
    crops, fell_back = [], []
    for path in flash_set.paths:
        image = read_ldr(path)[None]
        found = find_faces(image, detector, fallback="full_image")
        crops.append(crop_faces(image, found.crop_boxes, size=size).clamp(0.0, 1.0))
        # the fallback's square is the full image's (a detection's square never is exactly)
        fell_back.append(bool(torch.equal(found.crop_boxes.cpu(), full_image_box(*image.shape[-2:]))))
    return torch.cat(crops), torch.tensor(fell_back)


def _face_brightness(crops: torch.Tensor) -> torch.Tensor:
    """The log mean linear luminance of each crop's central half (the face), float64."""
    s = crops.shape[-1]
    centre = srgb_to_linear(crops[..., s // 4: s - s // 4, s // 4: s - s // 4].double())
    luminance = kornia.color.rgb_to_grayscale(centre, torch.tensor(LUMINANCE, dtype=centre.dtype))
    return torch.log(luminance.mean((1, 2, 3)).clamp(min=1e-6))


def _rate(hits: torch.Tensor, subjects: Sequence[str]) -> dict[str, Any]:
    """The share of ``hits`` (float 0/1, NaN left out) with its interval over subjects."""
    keep = torch.isfinite(hits)
    kept = [s for s, k in zip(subjects, keep.tolist(), strict=True) if k]
    if not kept:
        return {"rate": None, "ci": None, "count": 0}
    ids = _subject_ids(kept)
    return {"rate": float(hits[keep].mean()), "count": int(keep.sum()),
            "ci": subject_interval(hits[keep], ids, statistic=torch.mean)}


def _subject_ids(subjects: Sequence[str]) -> list[int]:
    names = sorted(set(subjects))
    return [names.index(s) for s in subjects]


def real_flash_check(estimator: Estimator, flash_set: FlashSet, *, crops: torch.Tensor | None = None,
                     fell_back: torch.Tensor | None = None, detector: str | FaceDetector = DEFAULT_DETECTOR,
                     batch_size: int = 32) -> dict[str, Any]:
    r"""Where the estimator puts the main light on real photographs under one known flash (module docstring).

    Args:
        estimator: the estimator (:mod:`~kornia_ilum_lab.evaluation.measures`).
        flash_set: the photographs (:func:`load_flash_set`).
        crops, fell_back: their crops (:func:`flash_crops`), if already cut (the same for every estimator).
        detector: the detector that cuts them otherwise.
        batch_size: crops per pass.

    Returns:
        ``{"table": {...}, "error": (N,)}``: ``table`` has ``"direction"`` (per band of :data:`AXIS_BANDS` and
        ``"all"``: the quantiles of the error in degrees, the median's interval over people, and the error's two
        parts: ``"elevation_bias"``, the median of the estimate's elevation minus the flash's, and
        ``"azimuth_error"``, the median absolute difference of their azimuths),
        ``"left_right"`` and ``"up_down"`` (the share of agreeing signs, its interval, the count),
        ``"energy_spread"`` (per flash, over people: the median over flashes of the standard deviation of the
        estimated log energy, of the faces' log brightness, and of their ratio; and the frontal flash's, where
        there is one), ``"no_direction"`` (estimates without a main direction), ``"fell_back"`` (photographs
        without a detected face), ``"people"`` and ``"photos"``.

    Shape:
        - crops: :math:`(N, 3, H, W)`; fell_back: :math:`(N,)`

    Convention:
        The flash's direction and the estimate's in the camera frame (docs/conventions.rst, "Frames").
    """
    check_positive_int(batch_size, "batch_size")
    if crops is None:
        crops, fell_back = flash_crops(flash_set, detector)
    if len(crops) != len(flash_set):
        raise ValueCheckError(f"{len(crops)} crops for {len(flash_set)} photographs")
    energy, direction, _ = estimates(estimator, (as_floats(crops[i:i + batch_size])
                                                 for i in range(0, len(crops), batch_size)), directions=True)
    truth = flash_set.directions
    error = angle_degrees(direction, truth)
    people = flash_set.people
    axis = flash_set.axis_angle
    bands = {"all": torch.ones(len(error), dtype=torch.bool)}
    bands.update({name: (axis >= lo) & (axis < hi) for name, lo, hi in AXIS_BANDS})
    elevation = torch.rad2deg(torch.asin(direction[:, 1].double().clamp(-1.0, 1.0))) - flash_set.elevation
    azimuth = torch.rad2deg(torch.atan2(-direction[:, 0].double(), direction[:, 2].double())) - flash_set.azimuth
    azimuth = torch.remainder(azimuth + 180.0, 360.0) - 180.0
    none = direction.norm(dim=-1) == 0
    elevation, azimuth = elevation.masked_fill(none, float("nan")), azimuth.masked_fill(none, float("nan"))
    table: dict[str, Any] = {"direction": {}}
    for name, members in bands.items():
        ids = [p for p, m in zip(people, members.tolist(), strict=True) if m]
        table["direction"][name] = {**quantiles(error[members]),
                                    "ci": subject_interval(error[members], ids) if ids else None,
                                    "elevation_bias": quantiles(elevation[members])["median"],
                                    "azimuth_error": quantiles(azimuth[members].abs())["median"]}
    margin = math.sin(math.radians(SIGN_MARGIN_DEG))
    for key, axis_index in (("left_right", 0), ("up_down", 1)):
        t, p = truth[:, axis_index], direction[:, axis_index].double()
        hits = torch.where(t.abs() >= margin, ((t > 0) == (p > 0)).double(), float("nan"))
        hits = torch.where(direction.norm(dim=-1) == 0, float("nan"), hits)
        table[key] = _rate(hits, flash_set.subjects)
    table["energy_spread"] = _energy_spread(torch.log(energy.clamp(min=1e-30)), _face_brightness(crops), flash_set)
    table["no_direction"] = int(torch.isnan(error).sum())
    table["fell_back"] = int(fell_back.sum()) if fell_back is not None else None
    table["people"], table["photos"] = len(set(flash_set.subjects)), len(flash_set)
    return {"table": table, "error": error}


def _energy_spread(log_energy: torch.Tensor, log_face: torch.Tensor, flash_set: FlashSet) -> dict[str, Any]:
    """Per flash (azimuth, elevation) seen by at least 3 people: the standard deviations over them."""
    keys = [(float(a), float(e)) for a, e in zip(flash_set.azimuth, flash_set.elevation, strict=True)]
    rows = {}
    for key in sorted(set(keys)):
        members = torch.tensor([k == key for k in keys])
        if int(members.sum()) >= 3:
            est, face = log_energy[members].std(), log_face[members].std()
            rows[key] = (float(est), float(face), float(est / face) if face > 0 else float("nan"))
    if not rows:
        return {"flashes": 0}
    values = torch.tensor(list(rows.values()), dtype=torch.float64)
    out: dict[str, Any] = {"flashes": len(rows), "estimate": float(median(values[:, 0])),
                           "face": float(median(values[:, 1])), "ratio": float(median(values[:, 2]))}
    if (0.0, 0.0) in rows:
        out["frontal"] = dict(zip(("estimate", "face", "ratio"), rows[(0.0, 0.0)], strict=True))
    return out


def flash_markdown(tables: dict[str, dict[str, Any]]) -> list[str]:
    r"""The real-flash check's Markdown table, one row per method.

    Args:
        tables: method name to :func:`real_flash_check`'s ``"table"``.

    Returns:
        the table's lines (none for no method).
    """
    if not tables:
        return []
    first = next(iter(tables.values()))
    bands = list(first["direction"])
    lines = ["", f"## Real-flash check: {first['people']} people, {first['photos']} photographs under one known "
             "flash each; the main light's direction error in degrees (median [95 % interval over people]) by "
             "the flash's angle to the camera axis; sign agreement; the spread over people of the estimated log "
             "energy under one flash against that of the faces' log brightness (median over flashes)", ""]
    lines += ["| method | " + " | ".join(bands) + " | elevation bias / azimuth error, within 25 | left/right | "
              "up/down | sd log E / sd log face | no direction | no face found |",
              "|---|" + "---:|" * (len(bands) + 6)]

    def interval(ci: list[float] | None, digits: int) -> str:
        return "" if ci is None else f" [{ci[0]:.{digits}f}, {ci[1]:.{digits}f}]"

    for name, t in tables.items():
        cells = []
        for band in bands:
            row = t["direction"][band]
            cells.append("-" if row["median"] is None else f"{row['median']:.1f}{interval(row['ci'], 1)}")
        front = t["direction"].get("within 25") or {}
        bias, az = front.get("elevation_bias"), front.get("azimuth_error")
        cells.append("-" if bias is None else f"{bias:+.1f} / {az:.1f}")
        for key in ("left_right", "up_down"):
            row = t[key]
            cells.append("-" if row["rate"] is None else f"{row['rate']:.3f}{interval(row['ci'], 2)}")
        spread = t["energy_spread"]
        cells.append("-" if not spread.get("flashes") else
                     f"{spread['estimate']:.2f} / {spread['face']:.2f} = {spread['ratio']:.2f}")
        cells += [str(t["no_direction"]), str(t["fell_back"])]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return lines
