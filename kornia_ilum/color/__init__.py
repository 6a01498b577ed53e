"""Colour transfer functions: exact sRGB, gamma 2.2 with a finite slope at 0, quantisation and 8-bit sRGB codes."""

from kornia_ilum.color.transfer import (
    GAMMA_KNEE,
    GammaEncode,
    LinearToSrgb,
    Quantize,
    SrgbToLinear,
    encode_srgb8,
    gamma_decode,
    gamma_encode,
    linear_to_srgb,
    quantize,
    srgb_to_linear,
)

__all__ = [
    "GAMMA_KNEE",
    "GammaEncode",
    "LinearToSrgb",
    "Quantize",
    "SrgbToLinear",
    "encode_srgb8",
    "gamma_decode",
    "gamma_encode",
    "linear_to_srgb",
    "quantize",
    "srgb_to_linear",
]
