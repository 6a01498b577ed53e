"""Synthetic data: lighting environments, backgrounds, camera effects, the light stage.

- :mod:`~kornia_ilum_lab.synth.environments`: lighting environments (real HDR maps, procedural skies, rooms and
  portrait lights), their augmentation and the sampler that draws them reproducibly per ``(seed, index)``;
- :mod:`~kornia_ilum_lab.synth.background`: the view of an environment behind a portrait, tone-mapped to 8-bit
  sRGB;
- :mod:`~kornia_ilum_lab.synth.camera_effects`: phone-camera effects (lens blur, vignette, sensor noise, tone
  curve, JPEG);
- :mod:`~kornia_ilum_lab.synth.colour_looks`: what users do to a photo's colours after the camera (greyscale,
  desaturation, white balance, colour grades) and what that does to its lighting;
- :mod:`~kornia_ilum_lab.synth.stats`: statistics of lighting environments, to compare generated sets with real
  maps;
- :mod:`~kornia_ilum_lab.synth.lightstage`: the virtual light stage (synthetic subjects, their OLAT reflectance
  fields rendered with Mitsuba 3, and portraits relit from them);
- :mod:`~kornia_ilum_lab.synth.cli`: the ``kornia-ilum synth`` sub-commands.

Nothing is imported with this package: import the modules by name
(``from kornia_ilum_lab.synth.environments import EnvironmentSampler``). The LDR-to-HDR promotion of sphere
photographs, an op on real photos, is the library's :mod:`kornia_ilum.promotion`.
"""
