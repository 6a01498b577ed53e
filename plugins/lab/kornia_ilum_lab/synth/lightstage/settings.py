r"""Settings of the OLAT renderers: frozen dataclasses, validated once when they are made.

- :class:`OnePass`: the one-pass renderer (:mod:`~kornia_ilum_lab.synth.lightstage.onepass`, every light in one
  vectorised Dr.Jit pass) and its post-processing (subsurface scattering, the denoiser);
- :class:`Reference`: the per-light reference renderer (:mod:`~kornia_ilum_lab.synth.lightstage.reference`, one
  Mitsuba render per light; also interreflection);
- :class:`Auto`: the one-pass renderer where the Mitsuba variant is vectorised, else the reference, with only
  the settings that both share (what :func:`~kornia_ilum_lab.synth.lightstage.olat.render_olat` and
  :func:`~kornia_ilum_lab.synth.lightstage.cache.build_cache` use when given no settings).

Defaults that a setting leaves to the renderer (``None``) are resolved when the object is made, so its fields
hold the values that are used (``OnePass(spp=16).shade_spp == 4``); :func:`dataclasses.replace` keeps those
resolved values.

Examples:
    >>> settings = OnePass(spp=16)
    >>> settings.shade_spp, settings.edge_spp, settings.demodulate
    (4, 16, True)
    >>> Auto(spp=8).resolve("scalar_rgb")
    Reference(lighting_size=32, spp=8, max_depth=4, seed=0, envmap_height=128, lights=None)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from kornia_ilum.core.check import check_positive_int
from kornia_ilum.core.errors import TypeCheckError, ValueCheckError
from kornia_ilum.geometry import mirror_ball_valid

__all__ = [
    "ONEPASS_CHUNK_LANES",
    "ONEPASS_EDGE_SPP",
    "ONEPASS_SHADE_SPP",
    "ONEPASS_SPP",
    "REFERENCE_MAX_DEPTH",
    "REFERENCE_SPP",
    "Auto",
    "OnePass",
    "Reference",
    "is_vectorised",
]

#: Default camera samples per pixel of the one-pass renderer (``spp``: coverage, albedo, G-buffer, glints).
#:
#: With :data:`ONEPASS_SHADE_SPP` = 4 of them tracing the lights in plain pixels and :data:`ONEPASS_EDGE_SPP`
#: = 16 in mixed ones (silhouettes, hair, several parts, creases), demodulated by albedo and coverage
#: (:mod:`~kornia_ilum_lab.synth.lightstage.onepass`). Chosen with ``benchmarks/bench_olat.py --reference
#: onepass`` (MakeHuman seed 1, view 0, 192 px, one thread on the loaded 2-core machine): PSNR of relit 8-bit
#: sRGB portraits (exposure: reference's median subject luminance -> 0.18, black background, covered pixels
#: only, no subsurface) under pedestrian_overpass (sun) / phalzer_forest_01 (overcast), against the mean of
#: two one-pass fields at 32 samples that all trace every light (they agree to 41.3 / 40.1 dB; a 256-spp
#: ``render_lighting`` render agrees with their mean to 38.9 / 38.2 dB, its own noise). ``spp:shade:edge``:
#: 4:4:4 (the previous default, every sample traced) 30.8 / 30.7 dB; 16:4:4 33.5 / 34.5; 16:4:16 35.4 / 36.6;
#: 32:3:16 34.9 / 38.4; 32:4:8 36.6 / 37.3; 32:4:12 37.2 / 38.3; 32:4:16 37.5 / 38.7; 64:4:16 36.7 / 39.1 (and
#: a slower camera stage); on seed 2 view 1, 4:4:4 30.1 / 31.1 and 32:4:16 39.0 / 40.9. 32:4:16 traces 5.3
#: samples per pixel in the light stage; its cost is in docs/lightstage.rst. The denoiser lowers this PSNR (it
#: smooths texture and edge detail that the reference has), so :class:`OnePass` does not denoise by default.
ONEPASS_SPP = 32

#: Default camera samples per pixel that trace the lights in plain pixels (:class:`OnePass`'s ``shade_spp``).
ONEPASS_SHADE_SPP = 4

#: Default samples per pixel that trace the lights in mixed pixels (:class:`OnePass`'s ``edge_spp``).
ONEPASS_EDGE_SPP = 16

#: Default light-hit pairs per kernel launch of the one-pass renderer (about 100 MB of outputs).
ONEPASS_CHUNK_LANES = 1 << 21

#: Default samples per pixel of each OLAT render of the reference renderer.
REFERENCE_SPP = 16

#: Default path depth of the reference renderer: direct light and two bounces of interreflection.
REFERENCE_MAX_DEPTH = 4


def is_vectorised(variant: str) -> bool:
    """Whether a Mitsuba variant is vectorised (``llvm_*``, ``cuda_*``): what the one-pass renderer needs.

    Args:
        variant: a Mitsuba variant name (``"llvm_ad_rgb"``, ``"scalar_rgb"``, ...).

    Returns:
        True for the LLVM and CUDA variants.

    Examples:
        >>> is_vectorised("llvm_ad_rgb"), is_vectorised("scalar_rgb")
        (True, False)
    """
    return variant.startswith(("llvm", "cuda"))


def _check_seed(seed: Any) -> None:
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueCheckError(f"seed must be a non-negative int, got {seed!r}")


def _check_bool(value: Any, name: str) -> None:
    if not isinstance(value, bool):
        raise TypeCheckError(f"{name} must be a bool, got {type(value).__name__}")


@dataclass(frozen=True, kw_only=True)
class OnePass:
    r"""Settings of the one-pass renderer (:mod:`~kornia_ilum_lab.synth.lightstage.onepass`), validated once.

    Args:
        lighting_size: the mirror-ball side ``S`` of the lighting basis (``N = S^2`` lights).
        spp: camera samples per pixel ``C`` (coverage, albedo, G-buffer, glints); default :data:`ONEPASS_SPP`.
        shade_spp: camera samples per pixel that trace the lights in plain pixels (the expensive part), at
            most ``spp``; default ``min(spp, ONEPASS_SHADE_SPP)``.
        edge_spp: with demodulation, the samples that trace the lights in mixed pixels (silhouettes, hair,
            creases), at most ``spp``; default ``min(spp, max(shade_spp, ONEPASS_EDGE_SPP))``. Without
            demodulation it is ``shade_spp``.
        demodulate: scale the traced samples' shading by the coverage and albedo of all ``spp`` camera samples
            (:mod:`~kornia_ilum_lab.synth.lightstage.onepass`, step 4); default ``shade_spp < spp``. Without it
            every camera sample traces the lights (``shade_spp`` must be ``spp``).
        seed: the random seed (camera jitter and light samples).
        subsurface: apply :func:`~kornia_ilum_lab.synth.lightstage.subsurface.subsurface_scatter` to the skin's
            diffuse part.
        denoise: apply :func:`~kornia_ilum_lab.synth.lightstage.denoise.denoise_field` (off by default: it lowers
            the PSNR of relit portraits at :data:`ONEPASS_SPP`, see there).
        chunk_lanes: light-hit pairs per kernel launch.

    The renderer is direct light only (Mitsuba's ``max_depth = 2``).

    Raises:
        TypeCheckError, ValueCheckError: a setting out of its range.

    Examples:
        >>> s = OnePass(spp=4)
        >>> s.shade_spp, s.edge_spp, s.demodulate
        (4, 4, False)
    """

    lighting_size: int = 32
    spp: int = ONEPASS_SPP
    shade_spp: int | None = None
    edge_spp: int | None = None
    demodulate: bool | None = None
    seed: int = 0
    subsurface: bool = True
    denoise: bool = False
    chunk_lanes: int = ONEPASS_CHUNK_LANES

    def __post_init__(self) -> None:
        check_positive_int(self.lighting_size, "lighting_size")
        spp = self.spp
        check_positive_int(spp, "spp")
        shade_spp = min(spp, ONEPASS_SHADE_SPP) if self.shade_spp is None else self.shade_spp
        check_positive_int(shade_spp, "shade_spp")
        if shade_spp > spp:
            raise ValueCheckError(f"shade_spp must be at most spp = {spp}, got {shade_spp}")
        demodulate = shade_spp < spp if self.demodulate is None else self.demodulate
        _check_bool(demodulate, "demodulate")
        edge_spp = min(spp, max(shade_spp, ONEPASS_EDGE_SPP)) if self.edge_spp is None else self.edge_spp
        check_positive_int(edge_spp, "edge_spp")
        if edge_spp > spp:
            raise ValueCheckError(f"edge_spp must be at most spp = {spp}, got {edge_spp}")
        if not demodulate and shade_spp != spp:
            raise ValueCheckError(
                "demodulate=False needs shade_spp == spp (every camera sample traces the lights)"
            )
        _check_seed(self.seed)
        _check_bool(self.subsurface, "subsurface")
        _check_bool(self.denoise, "denoise")
        check_positive_int(self.chunk_lanes, "chunk_lanes")
        object.__setattr__(self, "shade_spp", shade_spp)
        object.__setattr__(self, "demodulate", demodulate)
        object.__setattr__(self, "edge_spp", edge_spp if demodulate else shade_spp)

    def to_dict(self) -> dict[str, Any]:
        """The settings as a JSON-ready dict, with ``"method": "onepass"``."""
        return {"method": "onepass", **{k: getattr(self, k) for k in self.__dataclass_fields__}}


@dataclass(frozen=True, kw_only=True)
class Reference:
    r"""Settings of the per-light reference renderer (:mod:`~kornia_ilum_lab.synth.lightstage.reference`).

    Args:
        lighting_size: the mirror-ball side ``S`` of the lighting basis (``N = S^2`` lights).
        spp: samples per pixel of each OLAT render; the stratified sampler rounds it up to a product of two
            near-equal integers (16 and 25 stay, 32 becomes 35); the field's ``meta["spp"]`` holds the count
            used.
        max_depth: Mitsuba's path depth: 2 is direct light only, 4 adds two bounces of interreflection.
        seed: the sampler seed, the same for every light.
        envmap_height: lat-long rows of the light bitmaps; default ``4 S`` (1.4 degree texels at ``S = 32``).
        lights: render only these light indices (the other columns stay 0); default all valid lights. For
            benchmarks and tests.

    Raises:
        ValueCheckError: a setting out of its range, or ``lights`` that are not valid lights of the basis.

    Examples:
        >>> Reference(lighting_size=4, lights=[5, 6]).lights
        (5, 6)
    """

    lighting_size: int = 32
    spp: int = REFERENCE_SPP
    max_depth: int = REFERENCE_MAX_DEPTH
    seed: int = 0
    envmap_height: int | None = None
    lights: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        check_positive_int(self.lighting_size, "lighting_size")
        check_positive_int(self.spp, "spp")
        check_positive_int(self.max_depth, "max_depth")
        _check_seed(self.seed)
        height = 4 * self.lighting_size if self.envmap_height is None else self.envmap_height
        check_positive_int(height, "envmap_height")
        object.__setattr__(self, "envmap_height", height)
        if self.lights is not None:
            todo = np.asarray(self.lights, dtype=np.int64).ravel()
            valid = np.flatnonzero(mirror_ball_valid(self.lighting_size).flatten().numpy())
            if len(todo) == 0 or not np.isin(todo, valid).all():
                raise ValueCheckError(
                    f"lights must be valid light indices of the {self.lighting_size}^2 mirror ball"
                )
            object.__setattr__(self, "lights", tuple(int(n) for n in todo))

    def to_dict(self) -> dict[str, Any]:
        """The settings as a JSON-ready dict, with ``"method": "reference"``."""
        out = {k: getattr(self, k) for k in self.__dataclass_fields__}
        out["lights"] = None if self.lights is None else list(self.lights)
        return {"method": "reference", **out}


@dataclass(frozen=True, kw_only=True)
class Auto:
    r"""The one-pass renderer where the Mitsuba variant is vectorised, else the reference (:meth:`resolve`).

    Args:
        lighting_size: the mirror-ball side ``S`` of the lighting basis.
        spp: camera samples per pixel; ``None``: the renderer's default (:data:`ONEPASS_SPP` or
            :data:`REFERENCE_SPP`).
        seed: the random seed.

    Raises:
        ValueCheckError: a setting out of its range.

    Examples:
        >>> auto = Auto(lighting_size=8, spp=4)
        >>> type(auto.resolve("llvm_ad_rgb")).__name__, type(auto.resolve("scalar_rgb")).__name__
        ('OnePass', 'Reference')
        >>> auto.to_dict()
        {'method': 'auto', 'lighting_size': 8, 'spp': 4, 'seed': 0}
    """

    lighting_size: int = 32
    spp: int | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        check_positive_int(self.lighting_size, "lighting_size")
        if self.spp is not None:
            check_positive_int(self.spp, "spp")
        _check_seed(self.seed)

    def resolve(self, variant: str) -> OnePass | Reference:
        """:class:`OnePass` with these settings if ``variant`` is vectorised, else :class:`Reference`.

        Examples:
            >>> Auto(lighting_size=8).resolve("llvm_ad_rgb").spp
            32
        """
        if is_vectorised(variant):
            spp = ONEPASS_SPP if self.spp is None else self.spp
            return OnePass(lighting_size=self.lighting_size, spp=spp, seed=self.seed)
        spp = REFERENCE_SPP if self.spp is None else self.spp
        return Reference(lighting_size=self.lighting_size, spp=spp, seed=self.seed)

    def to_dict(self) -> dict[str, Any]:
        """The settings as a JSON-ready dict, with ``"method": "auto"``."""
        return {"method": "auto", "lighting_size": self.lighting_size, "spp": self.spp, "seed": self.seed}
