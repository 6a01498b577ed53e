"""Lighting environments: real HDR maps with augmentation, procedural skies, rooms and portrait lights."""

from kornia_ilum_lab.synth.environments.base import Environment, EnvironmentSource, Label
from kornia_ilum_lab.synth.environments.augment import (
    Augment,
    RotateLatLong,
    lighting_rotation,
    rotate_latlong,
    white_balance_gains,
)
from kornia_ilum_lab.synth.environments.real import HDRFolderSource, ResizeLatLong, guess_label, resize_latlong
from kornia_ilum_lab.synth.environments.sampler import EnvironmentSampler, default_sources, default_weights
from kornia_ilum_lab.synth.environments.sky import (
    CctToRgb,
    SkyRadiance,
    SkySource,
    cct_to_rgb,
    render_outdoor,
    sky_radiance,
)
from kornia_ilum_lab.synth.environments.indoor import IndoorSource, render_room
from kornia_ilum_lab.synth.environments.portrait import PortraitLightSource, key_direction, render_portrait

__all__ = ["Environment", "EnvironmentSource", "Label"]
__all__ += ["Augment", "RotateLatLong", "lighting_rotation", "rotate_latlong", "white_balance_gains"]
__all__ += ["HDRFolderSource", "ResizeLatLong", "guess_label", "resize_latlong"]
__all__ += ["EnvironmentSampler", "default_sources", "default_weights"]
__all__ += ["SkySource", "SkyRadiance", "sky_radiance", "CctToRgb", "cct_to_rgb", "render_outdoor"]
__all__ += ["IndoorSource", "render_room"]
__all__ += ["PortraitLightSource", "key_direction", "render_portrait"]
