"""Synthetic data: lighting environments, sphere promotion, backgrounds, camera effects, the light stage.

- :mod:`~kornia_ilum.synth.environments`: lighting environments (real HDR maps, procedural skies, rooms and
  portrait lights), their augmentation and the sampler that draws them reproducibly per ``(seed, index)``;
- :mod:`~kornia_ilum.synth.promotion`: LDR-to-HDR promotion of three-sphere photographs (LeGendre et al.
  2020); :func:`promote_spheres` and :class:`PromoteSpheres` are re-exported here;
- :mod:`~kornia_ilum.synth.background`: the view of an environment behind a portrait, tone-mapped to 8-bit
  sRGB;
- :mod:`~kornia_ilum.synth.camera_effects`: phone-camera effects (lens blur, vignette, sensor noise, tone
  curve, JPEG);
- :mod:`~kornia_ilum.synth.stats`: statistics of lighting environments, to compare generated sets with real
  maps;
- :mod:`~kornia_ilum.synth.lightstage`: the virtual light stage (synthetic subjects, their OLAT reflectance
  fields rendered with Mitsuba 3, and portraits relit from them);
- :mod:`~kornia_ilum.synth.cli`: the ``kornia-ilum synth`` sub-commands.

Only the promotion is imported with this package: import the others by name
(``from kornia_ilum.synth.environments import EnvironmentSampler``).
"""

from kornia_ilum.synth.promotion import CLIP_THRESHOLD, PromoteSpheres, PromotionResult, promote_spheres

__all__ = ["CLIP_THRESHOLD", "PromoteSpheres", "PromotionResult", "promote_spheres"]
