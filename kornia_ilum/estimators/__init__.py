"""Lighting estimators: one contract (``forward(crops) -> LightingEstimate``) and a registry by name.

Estimators come from entry points of the group ``kornia_ilum.estimators`` (the built-in ``ours`` and
plugin packages such as ``kornia_ilum_uniform``) and from :func:`register_estimator`. Weight files load only
through :func:`read_weights`, which checks their SHA-256. :class:`TestTimeAugmented` wraps any estimator to
average its estimate over jittered sub-crops and the mirror of each crop. :mod:`~kornia_ilum.estimators.runtime`
exports any estimator to ONNX and runs it with ONNX Runtime behind the same contract
(``create_estimator(name, runtime="onnx")``), in int8 or bfloat16 too, and :mod:`~kornia_ilum.estimators.probe`
holds the light-stage portraits that calibrate and check them. :mod:`~kornia_ilum.estimators.scene` reads the
light's strength from the whole photo and fuses it with a face estimate's.
"""

from kornia_ilum.estimators.base import (
    EstimatorInfo,
    LightingEstimate,
    LightingEstimator,
    WeightFile,
    adopt_spread_head,
    check_crops,
    read_weights,
)
from kornia_ilum.estimators.fusion import fuse_faces
from kornia_ilum.estimators.ours import OursEstimator
from kornia_ilum.estimators.registry import (
    DEFAULT_ESTIMATOR,
    ENTRY_POINT_GROUP,
    create_estimator,
    estimator_info,
    estimator_registry,
    list_estimators,
    register_estimator,
)
from kornia_ilum.estimators.runtime import (
    AUTO_ORDER,
    LREC_RTOL,
    PARITY_ATOL,
    RUNTIMES,
    Bf16Estimator,
    OnnxEstimator,
    cache_dir,
    export_onnx,
    export_scene_onnx,
    native_bf16,
    onnx_model,
    parity,
    probe_parity,
    quantize_int8,
    runtime_available,
    runtime_parity,
    with_runtime,
)
from kornia_ilum.estimators.scene import SceneStrength, fuse_strength, scene_input
from kornia_ilum.estimators.tta import (
    TestTimeAugmented,
    average_estimates,
    crop_windows,
    jitter_windows,
    mirror_sh,
)

__all__ = [
    "LightingEstimate",
    "LightingEstimator",
    "EstimatorInfo",
    "WeightFile",
    "check_crops",
    "read_weights",
    "adopt_spread_head",
    "fuse_faces",
    "SceneStrength",
    "fuse_strength",
    "scene_input",
    "OursEstimator",
    "DEFAULT_ESTIMATOR",
    "ENTRY_POINT_GROUP",
    "create_estimator",
    "estimator_info",
    "estimator_registry",
    "list_estimators",
    "register_estimator",
    "TestTimeAugmented",
    "jitter_windows",
    "crop_windows",
    "mirror_sh",
    "average_estimates",
    "AUTO_ORDER",
    "LREC_RTOL",
    "PARITY_ATOL",
    "RUNTIMES",
    "Bf16Estimator",
    "OnnxEstimator",
    "cache_dir",
    "export_onnx",
    "export_scene_onnx",
    "native_bf16",
    "onnx_model",
    "parity",
    "probe_parity",
    "quantize_int8",
    "runtime_available",
    "runtime_parity",
    "with_runtime",
]
