"""Synthesis: lighting environments, LDR-to-HDR promotion, and (later) the virtual light stage."""
