r"""The project's own held-out evaluation (``kornia-ilum evaluate``).

- :mod:`~kornia_ilum_lab.evaluation.split`: what is held out (eval subjects, eval real maps, the eval sampler
  seed :data:`EVAL_SEED`).
- :mod:`~kornia_ilum_lab.evaluation.evaluate`: the deterministic eval set (:func:`build_eval_set`), the oracles,
  the estimators (:func:`load_estimator`; a run's weight file through :func:`load_checkpoint`, which records
  its SHA-256) and the per-sample scores (:func:`evaluate`).
- :mod:`~kornia_ilum_lab.evaluation.checks`: the checks kept running for every estimator: the label-free transfer
  check (:func:`transfer_check`), exposure equivariance (:func:`exposure_equivariance`) and crop stability
  (:func:`crop_stability`), and the calibration of the spread of the log energy (:func:`spread_calibration`),
  with the lighting's energy and dominant direction they compare.
- :mod:`~kornia_ilum_lab.evaluation.measures`: what the checks measure (:func:`dominant_direction`,
  :func:`estimates`, :func:`angle_degrees`, :func:`quantiles`).
- :mod:`~kornia_ilum_lab.evaluation.colour`: the colour check (:func:`colour_check`): the same portraits through
  the colour looks users apply, and how far the main light turns.
- :mod:`~kornia_ilum_lab.evaluation.flash`: the real-flash check (:func:`real_flash_check`): real faces under one
  flash of known direction (:func:`load_flash_set`, :func:`flash_crops`).
- :mod:`~kornia_ilum_lab.evaluation.rule`: the shipping rule (:func:`shipping_rule`), read from one evaluation.
- :mod:`~kornia_ilum_lab.evaluation.bootstrap`: intervals over subjects (:func:`subject_interval`,
  :func:`ratio_interval`) for the per-tone figures.
- :mod:`~kornia_ilum_lab.evaluation.curve`: the learning curve of a run's snapshots (:func:`learning_curve`,
  :func:`write_curve`, :func:`read_curve`; :func:`equal_budget` reads several at equal budgets).
- :mod:`~kornia_ilum_lab.evaluation.report`: the tables (:func:`summarize`, :func:`format_markdown`,
  :func:`write_report`).
- :mod:`~kornia_ilum_lab.evaluation.cli`: :func:`~kornia_ilum_lab.evaluation.cli.add_evaluate_parser` and
  :func:`~kornia_ilum_lab.evaluation.cli.run_evaluate`.
"""

from kornia_ilum_lab.evaluation.checks import (
    BACKGROUNDS,
    CHECKS,
    EXPOSURE_FACTORS,
    INTERVAL_RATIOS,
    SPREAD_NOMINAL,
    check_runner,
    composite_background,
    flash_checks,
    crop_stability,
    darken,
    default_photos,
    dominant_direction,
    exposure_equivariance,
    face_crops,
    jitter_boxes,
    run_checks,
    spread_calibration,
    transfer_check,
)
from kornia_ilum_lab.evaluation.bootstrap import ratio_interval, subject_interval, subject_resamples
from kornia_ilum_lab.evaluation.colour import COLOUR_LOOKS, colour_check
from kornia_ilum_lab.evaluation.flash import FlashSet, flash_crops, flash_direction, load_flash_set, real_flash_check
from kornia_ilum_lab.evaluation.measures import angle_degrees, estimates, quantiles
from kornia_ilum_lab.evaluation.rule import shipping_rule
from kornia_ilum_lab.evaluation.curve import (
    CURVE_FIELDS,
    equal_budget,
    format_equal_budget,
    learning_curve,
    read_curve,
    snapshot_files,
    write_curve,
)
from kornia_ilum_lab.evaluation.evaluate import (
    BRDF_NAMES,
    DEFAULT_SAMPLES,
    ORACLES,
    EvalSet,
    build_eval_set,
    evaluate,
    fit_crops,
    load_checkpoint,
    load_estimator,
    oracle_predictions,
    predict,
    probe_eval_set,
    score,
)
from kornia_ilum_lab.evaluation.report import format_markdown, paired_differences, summarize, write_report
from kornia_ilum_lab.evaluation.split import EVAL_SEED, eval_environment_sources, eval_fields, heldout_maps

__all__ = [
    "BACKGROUNDS",
    "BRDF_NAMES",
    "CHECKS",
    "COLOUR_LOOKS",
    "CURVE_FIELDS",
    "DEFAULT_SAMPLES",
    "EVAL_SEED",
    "EXPOSURE_FACTORS",
    "INTERVAL_RATIOS",
    "ORACLES",
    "SPREAD_NOMINAL",
    "EvalSet",
    "FlashSet",
    "angle_degrees",
    "colour_check",
    "estimates",
    "flash_checks",
    "flash_crops",
    "flash_direction",
    "load_flash_set",
    "quantiles",
    "real_flash_check",
    "build_eval_set",
    "probe_eval_set",
    "fit_crops",
    "check_runner",
    "composite_background",
    "crop_stability",
    "darken",
    "default_photos",
    "dominant_direction",
    "eval_environment_sources",
    "eval_fields",
    "equal_budget",
    "evaluate",
    "exposure_equivariance",
    "face_crops",
    "format_equal_budget",
    "format_markdown",
    "paired_differences",
    "heldout_maps",
    "jitter_boxes",
    "learning_curve",
    "load_checkpoint",
    "load_estimator",
    "oracle_predictions",
    "predict",
    "read_curve",
    "ratio_interval",
    "run_checks",
    "shipping_rule",
    "spread_calibration",
    "subject_interval",
    "subject_resamples",
    "score",
    "snapshot_files",
    "summarize",
    "transfer_check",
    "write_curve",
    "write_report",
]
