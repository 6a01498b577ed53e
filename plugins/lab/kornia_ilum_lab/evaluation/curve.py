r"""The learning curve of a training run: ``L_rec`` on the held-out split at every kept snapshot.

A run trained with ``--snapshot-every N`` keeps its estimator's weights as
``RUN/snapshots/step_NNNNNN.safetensors``, with the step, the samples seen and the training wall time in each
file's metadata (:func:`~kornia_ilum_lab.train.save_snapshot`). :func:`learning_curve` scores every snapshot on an
eval set (:func:`~kornia_ilum_lab.evaluation.build_eval_set`) and :func:`write_curve` writes ``RUN/curve.csv`` and
``RUN/curve.png``: whether the run had stopped learning, and, read at equal samples or equal wall time, how
estimators of different cost compare (``kornia-ilum evaluate --curve RUN``). :func:`equal_budget` reads
several runs' curves at a shared budget of portraits seen and of training wall time
(``kornia-ilum evaluate --curve RUN_A --curve RUN_B ...`` prints it); :func:`read_curve` reads a written
``curve.csv`` back, so a table can be rebuilt from curves whose snapshots are gone.
"""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import Any

from safetensors import safe_open

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.core.files import atomic_write
from kornia_ilum_lab.evaluation.evaluate import BRDF_NAMES, EvalSet, load_checkpoint, predict, score

__all__ = ["CURVE_FIELDS", "equal_budget", "format_equal_budget", "learning_curve", "read_curve",
           "snapshot_files", "write_curve"]

#: The columns of ``curve.csv``: where the snapshot was taken, then the mean ``L_rec`` per sphere.
CURVE_FIELDS: tuple[str, ...] = ("step", "samples", "elapsed_s", *BRDF_NAMES)


def snapshot_files(run: str | os.PathLike[str]) -> list[Path]:
    r"""The snapshots of a run, in step order.

    Args:
        run: the run's folder (``kornia-ilum train --out``); its snapshots are ``snapshots/step_*.safetensors``.

    Returns:
        the snapshot files, sorted by name (the step is zero-padded, so that is step order).

    Raises:
        ValueCheckError: the run keeps none (it was trained without ``--snapshot-every``).

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as run:
        ...     Path(run, "snapshots").mkdir()
        ...     for step in (200, 100):
        ...         _ = Path(run, "snapshots", f"step_{step:06d}.safetensors").write_bytes(b"")
        ...     [p.name for p in snapshot_files(run)]
        ['step_000100.safetensors', 'step_000200.safetensors']
    """
    files = sorted(Path(run, "snapshots").glob("step_*.safetensors"))
    if not files:
        raise ValueCheckError(f"{run} keeps no snapshots/step_*.safetensors: train it with --snapshot-every N")
    return files


def learning_curve(eval_set: EvalSet, run: str | os.PathLike[str], batch_size: int = 32) -> list[dict[str, Any]]:
    r"""Score every snapshot of ``run`` on ``eval_set``: one row per snapshot, in step order.

    Each snapshot is loaded as its metadata's registered estimator (:func:`~kornia_ilum_lab.evaluation.
    load_checkpoint`: safetensors only) and scored as :func:`~kornia_ilum_lab.evaluation.evaluate` scores it.

    Args:
        eval_set: the set to score on (:func:`~kornia_ilum_lab.evaluation.build_eval_set`).
        run: the run's folder (:func:`snapshot_files`).
        batch_size: crops per forward pass.

    Returns:
        rows with :data:`CURVE_FIELDS`: ``step``, ``samples``, ``elapsed_s`` (the run's training wall time at
        the snapshot) and the mean ``L_rec`` per sphere.

    Raises:
        ValueCheckError: the run keeps no snapshot, or a snapshot's metadata lacks the estimator or step.

    Convention:
        docs/conventions.rst, "The paper's error measure L_rec" and "Reference spheres".

    Examples:
        A run of the ``uniform`` estimator (no parameters: its snapshot holds only the metadata), scored on 8
        portraits of the probe:

        >>> import tempfile, safetensors.torch
        >>> from kornia_ilum_lab.evaluation import probe_eval_set
        >>> meta = {"estimator": "uniform", "step": "100", "samples": "3200", "elapsed_s": "60.0"}
        >>> with tempfile.TemporaryDirectory() as run:
        ...     Path(run, "snapshots").mkdir()
        ...     safetensors.torch.save_file({}, str(Path(run, "snapshots", "step_000100.safetensors")), metadata=meta)
        ...     rows = learning_curve(probe_eval_set(slice(64, 72)), run)
        >>> len(rows), tuple(rows[0]) == CURVE_FIELDS, rows[0]["samples"], rows[0]["diffuse"] > 0
        (1, True, 3200, True)
    """
    rows = []
    for path in snapshot_files(run):
        with safe_open(str(path), framework="pt") as f:
            meta = f.metadata() or {}
        if not {"estimator", "step", "samples", "elapsed_s"} <= meta.keys():
            raise ValueCheckError(f"{path} is not a training snapshot: its metadata lacks the estimator or step")
        model, _ = load_checkpoint(meta["estimator"], path)
        scores = score(predict(model, eval_set.images, batch_size), eval_set.mirror_ball)
        rows.append({"step": int(meta["step"]), "samples": int(meta["samples"]),
                     "elapsed_s": float(meta["elapsed_s"]), **{b: float(scores[b].mean()) for b in BRDF_NAMES}})
    return rows


def read_curve(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
    r"""Read a ``curve.csv`` that :func:`write_curve` wrote: the rows of :func:`learning_curve`, in step order.

    Args:
        path: the ``curve.csv`` file; other columns than :data:`CURVE_FIELDS` are ignored.

    Returns:
        the rows, sorted by step: ``step`` and ``samples`` as ints, the other fields as floats.

    Raises:
        ValueCheckError: the file is missing, has no row, or lacks a column of :data:`CURVE_FIELDS`.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as run:
        ...     _ = Path(run, "curve.csv").write_text("step,samples,elapsed_s,diffuse,matte_silver,mirror\n"
        ...                                           "400,12800,393.8,0.16,0.18,0.33\n")
        ...     rows = read_curve(Path(run, "curve.csv"))
        >>> rows[0]["step"], rows[0]["samples"], abs(rows[0]["mirror"] - 0.33) < 1e-9
        (400, 12800, True)
    """
    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        raise ValueCheckError(f"cannot read the learning curve {path}: {e.strerror or e}") from e
    missing = [k for k in CURVE_FIELDS if not rows or k not in rows[0]]
    if missing:
        raise ValueCheckError(f"{path} is not a curve.csv: it needs a row with the columns {', '.join(CURVE_FIELDS)}"
                              f" (missing: {', '.join(missing)})")
    try:
        out = [{k: (int(r[k]) if k in ("step", "samples") else float(r[k])) for k in CURVE_FIELDS} for r in rows]
    except (TypeError, ValueError) as e:
        raise ValueCheckError(f"{path} has a value that is not a number: {e}") from e
    return sorted(out, key=lambda r: r["step"])


def write_curve(run: str | os.PathLike[str], rows: list[dict[str, Any]]) -> list[Path]:
    r"""Write ``run/curve.csv`` and, where matplotlib is installed, ``run/curve.png`` (``L_rec`` per sphere
    against the samples seen); both atomically. Returns the paths written.

    Args:
        run: an existing folder, the run's.
        rows: the rows of :func:`learning_curve` (each with :data:`CURVE_FIELDS`); the scores are written with 6
            significant digits.

    Returns:
        ``[run/curve.csv]``, and ``run/curve.png`` after it where matplotlib is installed.

    Examples:
        Without matplotlib (hidden here), only the CSV is written; :func:`read_curve` reads it back:

        >>> import tempfile
        >>> from unittest import mock
        >>> rows = [{"step": 400, "samples": 12800, "elapsed_s": 393.8, "diffuse": 0.16, "matte_silver": 0.18,
        ...          "mirror": 0.33}]
        >>> with tempfile.TemporaryDirectory() as run, mock.patch.dict("sys.modules", {"matplotlib": None}):
        ...     written = write_curve(run, rows)
        ...     back = read_curve(written[0])
        >>> [p.name for p in written], back == rows
        (['curve.csv'], True)
    """
    run = Path(run)

    def table(tmp: Path) -> None:
        with open(tmp, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=CURVE_FIELDS)
            w.writeheader()
            for row in rows:
                w.writerow({k: (row[k] if k in ("step", "samples") else f"{row[k]:.6g}") for k in CURVE_FIELDS})

    atomic_write(run / "curve.csv", table)
    written = [run / "curve.csv"]
    try:
        import matplotlib  # lazy: only for the figure, and optional

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt  # lazy: as matplotlib, after the backend is set
    except ImportError:  # the CSV has the numbers
        return written
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for b in BRDF_NAMES:
        ax.plot([r["samples"] for r in rows], [r[b] for r in rows], marker="o", label=b)
    ax.set(xlabel="portraits seen", ylabel="L_rec on the eval split", title=run.name)
    ax.legend()
    fig.tight_layout()
    atomic_write(run / "curve.png", lambda tmp: fig.savefig(tmp, dpi=100, format="png"))
    plt.close(fig)
    return [*written, run / "curve.png"]


def _at_budget(rows: list[dict[str, Any]], key: str, budget: float) -> dict[str, Any] | None:
    """The last row whose ``key`` is at most ``budget`` (a snapshot taken within it), or ``None``."""
    within = [r for r in rows if r[key] <= budget * (1 + 1e-9)]
    return max(within, key=lambda r: r[key]) if within else None


def equal_budget(curves: dict[str, list[dict[str, Any]]]) -> dict[str, Any]:
    r"""Several runs' learning curves read at equal budgets: whether an ordering is a matter of compute.

    The budgets are the smallest, over the runs, of their last snapshot's portraits seen and of its training
    wall time: every run has reached both. Each run is read at its last snapshot within the budget (no
    interpolation between snapshots: the numbers are measured ones).

    Args:
        curves: run name to its rows (:func:`learning_curve`, in step order).

    Returns:
        ``{"samples": {"budget": S, "runs": {name: row}}, "elapsed_s": {"budget": T, "runs": {name: row}}}``.

    Raises:
        ValueCheckError: fewer than two runs, or a run without rows.

    Examples:
        >>> fast = [{"step": 1, "samples": 10, "elapsed_s": 5.0, "diffuse": 0.3},
        ...         {"step": 2, "samples": 20, "elapsed_s": 10.0, "diffuse": 0.2}]
        >>> slow = [{"step": 1, "samples": 10, "elapsed_s": 50.0, "diffuse": 0.25}]
        >>> table = equal_budget({"fast": fast, "slow": slow})
        >>> table["samples"]["budget"], table["samples"]["runs"]["fast"]["diffuse"]
        (10, 0.3)
        >>> table["elapsed_s"]["budget"], table["elapsed_s"]["runs"]["fast"]["diffuse"]
        (10.0, 0.2)
    """
    if len(curves) < 2 or not all(curves.values()):
        raise ValueCheckError("equal_budget needs at least two runs, each with at least one snapshot")
    table = {}
    for key in ("samples", "elapsed_s"):
        budget = min(rows[-1][key] for rows in curves.values())
        table[key] = {"budget": budget, "runs": {name: _at_budget(rows, key, budget) for name, rows in curves.items()}}
    return table


def format_equal_budget(table: dict[str, Any]) -> str:
    """:func:`equal_budget`'s table as Markdown: one row per run and budget, ``L_rec`` per sphere.

    Args:
        table: from :func:`equal_budget`.

    Returns:
        the Markdown table, ending in a newline: the portraits budget first, then the wall-time budget (in
        minutes); a run without a snapshot within a budget gets dashes.

    Examples:
        >>> row = {"step": 1, "samples": 10, "elapsed_s": 60.0, "diffuse": 0.3, "matte_silver": 0.4, "mirror": 0.5}
        >>> budget = {"budget": 10, "runs": {"a": row, "b": None}}
        >>> lines = format_equal_budget({"samples": budget, "elapsed_s": {**budget, "budget": 60.0}}).splitlines()
        >>> print("\\n".join(lines[2:4]))
        | portraits 10 | a | 1 | 10 | 1.0 | 0.3000 | 0.4000 | 0.5000 |
        | portraits 10 | b | - | - | - | - | - | - |
        >>> len(lines)
        6
    """
    lines = ["| budget | run | step | portraits | wall time (min) | " + " | ".join(BRDF_NAMES) + " |",
             "|---|---|---:|---:|---:|" + "---:|" * len(BRDF_NAMES)]
    for key, what in (("samples", "portraits"), ("elapsed_s", "wall time")):
        budget = table[key]["budget"]
        label = f"{what} {budget}" if key == "samples" else f"{what} {budget / 60:.1f} min"
        for name, r in table[key]["runs"].items():
            if r is None:  # no snapshot within the budget
                lines.append(f"| {label} | {name} | - | - | - | " + " | ".join("-" for _ in BRDF_NAMES) + " |")
                continue
            lines.append(f"| {label} | {name} | {r['step']} | {r['samples']} | {r['elapsed_s'] / 60:.1f} | "
                         + " | ".join(f"{r[b]:.4f}" for b in BRDF_NAMES) + " |")
    return "\n".join(lines) + "\n"
