"""Lighting environments: real HDR maps with augmentation, procedural outdoor and indoor scenes."""

from kornia_ilum.synth.environments.base import Environment, EnvironmentSource, Label

__all__ = ["Environment", "EnvironmentSource", "Label"]
