"""Input checks and typed errors shared by every kornia_ilum entry point."""

from kornia_ilum.core.check import (
    check_choice,
    check_positive_int,
    check_same_device,
    check_tensor,
    checks_active,
    trusted,
    value_range,
)
from kornia_ilum.core.errors import (
    BaseError,
    EmptyTensorError,
    HDRIOError,
    IlumError,
    MissingWeightsError,
    NoFaceError,
    NonFiniteError,
    ShapeError,
    TruncatedImageError,
    TypeCheckError,
    ValueCheckError,
    WeightsChecksumError,
)

__all__ = [
    "check_choice",
    "check_tensor",
    "check_same_device",
    "check_positive_int",
    "checks_active",
    "trusted",
    "value_range",
    "BaseError",
    "EmptyTensorError",
    "HDRIOError",
    "IlumError",
    "MissingWeightsError",
    "NoFaceError",
    "NonFiniteError",
    "ShapeError",
    "TruncatedImageError",
    "TypeCheckError",
    "ValueCheckError",
    "WeightsChecksumError",
]
