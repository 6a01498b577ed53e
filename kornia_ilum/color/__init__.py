"""Colour transfer functions (exact sRGB, gamma 2.2 with a finite slope at 0, quantisation, 8-bit sRGB codes) and
exposure (centre-weighted metering, exposure normalisation)."""

from kornia_ilum.color.exposure import (
    EXPOSURE_KEY,
    LUMINANCE,
    METERING_SIGMA,
    NormalizeExposure,
    centre_weights,
    metered_luminance,
    normalize_exposure,
)
from kornia_ilum.color.transfer import (
    GAMMA_KNEE,
    SRGB8_TABLE_SIZE,
    GammaEncode,
    LinearToSrgb,
    Quantize,
    SrgbToLinear,
    encode_srgb8,
    gamma_decode,
    gamma_encode,
    gamma_encode_unchecked,
    linear_to_srgb,
    quantize,
    srgb8_table,
    srgb_to_linear,
)

__all__ = [
    "EXPOSURE_KEY",
    "LUMINANCE",
    "METERING_SIGMA",
    "NormalizeExposure",
    "centre_weights",
    "metered_luminance",
    "normalize_exposure",
    "GAMMA_KNEE",
    "SRGB8_TABLE_SIZE",
    "GammaEncode",
    "LinearToSrgb",
    "Quantize",
    "SrgbToLinear",
    "encode_srgb8",
    "gamma_decode",
    "gamma_encode",
    "gamma_encode_unchecked",
    "linear_to_srgb",
    "quantize",
    "srgb8_table",
    "srgb_to_linear",
]
