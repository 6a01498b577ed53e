r"""Reproducible sampling of lighting environments from weighted sources, with augmentation.

:class:`EnvironmentSampler` draws environment number ``index`` from a generator seeded by a hash of
``(seed, index)``: the same pair always gives the same environment, whatever was drawn before, in any order
and in any process (so data loaders with several workers need no shared state). Without sources it uses
the embedded procedural defaults (:func:`default_sources`: skies, rooms and portrait lights), which need no
files.

Shares of the draws (:func:`default_weights`): the portrait lights
(:class:`~kornia_ilum_lab.synth.environments.PortraitLightSource`) take a quarter of them, and the other sources
share the rest half indoor, half outdoor, as before they came. A quarter because portraits, the estimators'
input, are taken most often under exactly these lights (an on-camera flash, studio lights or a lamp in a dark
room, a window, a street lamp at night) and the skies, rooms and real maps have none of them: the project's
transfer check measured the light of real flash photos 32 degrees off (a "light from the camera" guess is 60
degrees off) for a model trained without them. A quarter, not more, keeps three quarters for the skies, rooms
and real maps, whose lighting is still most of what a photo's background shows; the on-camera flash alone
(35 % of the portrait lights, 8.75 % of all draws) is then about as frequent as one of the five sky
conditions (7.5 % each).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence

import torch

from kornia_ilum.core.check import check_tensor
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.core.seeding import hashed_generator
from kornia_ilum_lab.synth.environments.augment import Augment
from kornia_ilum_lab.synth.environments.base import Environment, EnvironmentSource
from kornia_ilum_lab.synth.environments.indoor import IndoorSource
from kornia_ilum_lab.synth.environments.portrait import PortraitLightSource
from kornia_ilum_lab.synth.environments.real import HDRFolderSource
from kornia_ilum_lab.synth.environments.sky import SkySource

__all__ = ["EnvironmentSampler", "default_sources", "default_weights", "generator_for"]


def default_sources(
    folder: str | os.PathLike[str] | None = None, height: int = 128
) -> list[EnvironmentSource]:
    r"""The default sources: procedural skies, rooms and portrait lights, plus the real maps of ``folder``.

    Args:
        folder: a folder of lat-long ``.hdr`` / ``.exr`` maps (:class:`HDRFolderSource`), or ``None``.
        height: the working height of the lat-long maps.

    Returns:
        ``[SkySource(height=height), IndoorSource(height=height), PortraitLightSource(height=height)]``, then
        ``HDRFolderSource(folder, height)`` when ``folder`` is given.

    Examples:
        >>> [type(s).__name__ for s in default_sources()]
        ['SkySource', 'IndoorSource', 'PortraitLightSource']
    """
    sources: list[EnvironmentSource] = [
        SkySource(height=height),
        IndoorSource(height=height),
        PortraitLightSource(height=height),
    ]
    if folder is not None:
        sources.append(HDRFolderSource(folder, height=height))
    return sources


def default_weights(sources: Sequence[EnvironmentSource]) -> list[float]:
    r"""Fixed shares first, then half of the rest to indoor sources and half to outdoor ones.

    A source with a ``default_share`` attribute (a fraction of all draws, such as the portrait lights'
    0.25, :data:`~kornia_ilum_lab.synth.environments.portrait.PORTRAIT_SHARE`; module docstring) gets it: its
    environments may carry either label, so its ``label`` takes no part in the balance. The other sources
    share the remaining mass, half to those labelled indoor and half to those labelled outdoor, equally within
    a label (when all of them have one label, equally). So the procedural defaults get
    ``[0.375, 0.375, 0.25]`` (sky, indoor, portrait), and with a folder of mostly outdoor maps
    ``[0.1875, 0.375, 0.25, 0.1875]`` (sky, indoor, portrait, real): indoor rooms, thin among real maps, make
    half of what the portrait lights leave. With the portrait lights' own labels (88 % indoor by default),
    0.595 of the draws are indoor. When the shares add up to 1 or more, they are the weights (normalised by
    the sampler) and the other sources get none.

    Args:
        sources: the environment sources, each with a ``label`` and optionally a ``default_share``.

    Returns:
        one weight per source, in order (not normalised when the fixed shares exceed 1).

    Raises:
        ValueCheckError: a ``default_share`` that is not a number in ``[0, 1]``.

    Examples:
        >>> class S:
        ...     def __init__(self, label, share=None):
        ...         self.label = label
        ...         if share is not None: self.default_share = share
        >>> default_weights([S("outdoor"), S("indoor"), S("outdoor")])
        [0.25, 0.5, 0.25]
        >>> default_weights([S("outdoor"), S("indoor"), S("indoor", share=0.25)])
        [0.375, 0.375, 0.25]
    """
    shares = [getattr(s, "default_share", None) for s in sources]
    for k, share in enumerate(shares):
        if share is not None and (
            isinstance(share, bool) or not isinstance(share, (int, float)) or not 0.0 <= share <= 1.0
        ):
            raise ValueCheckError(f"sources[{k}].default_share must be a number in [0, 1], got {share!r}")
    fixed = sum(float(x) for x in shares if x is not None)
    rest = max(0.0, 1.0 - fixed)
    labels = [getattr(s, "label", None) for s, x in zip(sources, shares, strict=True) if x is None]
    present = sorted(set(labels), key=str)
    out = []
    for s, share in zip(sources, shares, strict=True):
        if share is not None:
            out.append(float(share))
        else:
            lab = getattr(s, "label", None)
            out.append(rest / (len(present) * labels.count(lab)))
    return out


def generator_for(seed: int, index: int) -> torch.Generator:
    """A CPU generator seeded with the first 8 bytes of ``blake2b(f"kornia_ilum.synth:{seed}:{index}")``.

    Args:
        seed: the seed of a set of environments (any int).
        index: the environment's index in the set, non-negative.

    Returns:
        a new CPU :class:`torch.Generator`, the same state for the same ``(seed, index)`` on every machine.

    Raises:
        TypeCheckError: ``seed`` or ``index`` is not an int.
        ValueCheckError: ``index`` is negative.

    Examples:
        >>> a, b = generator_for(0, 5), generator_for(0, 5)
        >>> torch.equal(torch.rand(3, generator=a), torch.rand(3, generator=b))
        True
    """
    for name, value in (("seed", seed), ("index", index)):
        if isinstance(value, bool) or not isinstance(value, int):
            raise TypeCheckError(f"{name} must be an int, got {type(value).__name__}")
    if index < 0:
        raise ValueCheckError(f"index must be non-negative, got {index}")
    return hashed_generator(f"kornia_ilum.synth:{seed}:{index}")


class EnvironmentSampler:
    r"""Environments from weighted sources, augmented, deterministic per ``(seed, index)``.

    ``sample(index)`` seeds a generator with :func:`generator_for` ``(seed, index)``, picks a source with
    probability proportional to its weight (one uniform draw), lets it draw an environment, and augments
    it, all with that generator.

    Args:
        sources: objects with a ``label`` and ``sample(generator) -> Environment`` depending only on the
            generator (:class:`~kornia_ilum_lab.synth.environments.EnvironmentSource`); ``None``: the
            procedural defaults of :func:`default_sources` (no files needed).
        weights: non-negative weights, one per source, not all 0; ``None``: :func:`default_weights` (a
            quarter to the portrait lights, the rest half indoor, half outdoor).
        augment: a callable ``(env, generator) -> Environment`` applied to every sample
            (:class:`~kornia_ilum_lab.synth.environments.Augment`; stateless, so the shared default is safe),
            or ``None`` for none.
        seed: the seed (any int).

    Raises:
        TypeCheckError: a source lacks ``sample``, ``seed`` or ``index`` is not an int.
        ValueCheckError: bad weights, negative ``index``, or a source returned negative lighting.
        ShapeError: a source returned an environment with wrong shapes.

    Convention:
        ``Environment.params["sampler"]`` holds ``{"seed", "index", "source"}`` (the source's position in
        ``sources``). Lighting as in :mod:`kornia_ilum_lab.synth.environments.base` (frame of
        docs/conventions.rst).

    Examples:
        >>> sampler = EnvironmentSampler(seed=3)
        >>> a, b = sampler.sample(7), sampler.sample(7)
        >>> torch.equal(a.mirror_ball, b.mirror_ball), tuple(a.mirror_ball.shape)
        (True, (3, 32, 32))
    """

    def __init__(
        self,
        sources: Sequence[EnvironmentSource] | None = None,
        weights: Sequence[float] | None = None,
        augment: Callable[[Environment, torch.Generator], Environment] | None = Augment(),  # noqa: B008
        seed: int = 0,
    ) -> None:
        self.sources = list(default_sources() if sources is None else sources)
        if not self.sources:
            raise ValueCheckError("sources must not be empty")
        for k, source in enumerate(self.sources):
            if not callable(getattr(source, "sample", None)):
                raise TypeCheckError(
                    f"sources[{k}] must have a sample(generator) method, got {type(source).__name__}"
                )
        if weights is None:
            weights = default_weights(self.sources)
        weights = [float(w) for w in weights]
        bad = any(not 0.0 <= w < float("inf") for w in weights)
        if len(weights) != len(self.sources) or bad or sum(weights) <= 0.0:
            raise ValueCheckError(
                f"weights must be {len(self.sources)} finite non-negative numbers, not all 0, got {weights}"
            )
        if augment is not None and not callable(augment):
            raise TypeCheckError(f"augment must be callable or None, got {type(augment).__name__}")
        generator_for(seed, 0)  # checks the seed
        self.weights = [w / sum(weights) for w in weights]
        self._cumulative = torch.tensor(self.weights, dtype=torch.float64).cumsum(0)
        self.augment = augment
        self.seed = seed

    def __repr__(self) -> str:
        pairs = zip(self.sources, self.weights, strict=True)
        parts = ", ".join(f"{type(s).__name__}: {w:.3g}" for s, w in pairs)
        return f"EnvironmentSampler({parts}; augment={self.augment!r}, seed={self.seed})"

    def sample(self, index: int) -> Environment:
        """Environment number ``index`` (a non-negative int) of this seed."""
        generator = generator_for(self.seed, index)
        u = torch.rand(1, generator=generator, dtype=torch.float64)
        k = int(torch.searchsorted(self._cumulative, u * self._cumulative[-1], right=True))
        k = min(k, len(self.sources) - 1)
        env = self.sources[k].sample(generator)
        if self.augment is not None:
            env = self.augment(env, generator)
        _check_environment(env, f"sources[{k}]")
        return Environment(
            latlong=env.latlong,
            mirror_ball=env.mirror_ball,
            label=env.label,
            source=env.source,
            params={**env.params, "sampler": {"seed": self.seed, "index": index, "source": k}},
        )


def _check_environment(env: object, where: str) -> None:
    if not isinstance(env, Environment):
        raise TypeCheckError(f"{where} must return an Environment, got {type(env).__name__}")
    check_tensor(env.latlong, f"{where}: latlong", ["3", "H", "2H"], nonnegative=True)
    check_tensor(env.mirror_ball, f"{where}: mirror_ball", ["3", "32", "32"], nonnegative=True)
    if env.latlong.shape[-1] != 2 * env.latlong.shape[-2]:
        raise ShapeError(f"{where}: latlong must have shape (3, H, 2H), got {tuple(env.latlong.shape)}")
    if env.label not in ("indoor", "outdoor"):
        raise ValueCheckError(f"{where}: label must be 'indoor' or 'outdoor', got {env.label!r}")
