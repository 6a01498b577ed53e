"""Image files: linear HDR (OpenEXR, Radiance HDR) and sRGB LDR (PNG, JPEG, TIFF) through OpenImageIO."""

from kornia_ilum.io.image import HALF_MAX, check_ldr, read_hdr, read_ldr, write_hdr, write_ldr

__all__ = ["HALF_MAX", "check_ldr", "read_hdr", "read_ldr", "write_hdr", "write_ldr"]
