"""Colour transfer functions: exact sRGB, gamma 2.2 (finite slope at 0), quantisation and 8-bit sRGB codes."""

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
