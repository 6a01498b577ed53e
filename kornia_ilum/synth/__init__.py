"""Synthesis: lighting environments, LDR-to-HDR promotion, and (later) the virtual light stage."""

from kornia_ilum.synth.promotion import CLIP_THRESHOLD, PromoteSpheres, PromotionResult, promote_spheres

__all__ = ["CLIP_THRESHOLD", "PromoteSpheres", "PromotionResult", "promote_spheres"]
