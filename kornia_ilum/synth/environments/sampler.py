r"""Reproducible sampling of lighting environments from weighted sources, with augmentation.

:class:`EnvironmentSampler` draws environment number ``index`` from a generator seeded by a hash of
``(seed, index)``: the same pair always gives the same environment, whatever was drawn before, in any order
and in any process (so data loaders with several workers need no shared state). Without sources it uses
the embedded procedural defaults (:func:`default_sources`), which need no files.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence

import torch

from kornia_ilum.core.check import check_tensor
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.core.seeding import hashed_generator
from kornia_ilum.synth.environments.augment import Augment
from kornia_ilum.synth.environments.base import Environment, EnvironmentSource
from kornia_ilum.synth.environments.indoor import IndoorSource
from kornia_ilum.synth.environments.real import HDRFolderSource
from kornia_ilum.synth.environments.sky import SkySource

__all__ = ["EnvironmentSampler", "default_sources", "default_weights", "generator_for"]


def default_sources(
    folder: str | os.PathLike[str] | None = None, height: int = 128
) -> list[EnvironmentSource]:
    r"""The default sources: procedural skies and rooms, plus the real maps of ``folder`` when given.

    Args:
        folder: a folder of lat-long ``.hdr`` / ``.exr`` maps (:class:`HDRFolderSource`), or ``None``.
        height: the working height of the lat-long maps.

    Returns:
        ``[SkySource(height=height), IndoorSource(height=height)]``, then
        ``HDRFolderSource(folder, height)`` when ``folder`` is given.

    Examples:
        >>> [type(s).__name__ for s in default_sources()]
        ['SkySource', 'IndoorSource']
    """
    sources: list[EnvironmentSource] = [SkySource(height=height), IndoorSource(height=height)]
    if folder is not None:
        sources.append(HDRFolderSource(folder, height=height))
    return sources


def default_weights(sources: Sequence[EnvironmentSource]) -> list[float]:
    r"""Half of the mass to indoor sources and half to outdoor ones, shared equally within each label.

    When all sources have one label they share the mass equally. So the procedural defaults get
    ``[0.5, 0.5]`` (sky, indoor), and with a folder of mostly outdoor maps ``[0.25, 0.5, 0.25]`` (sky, indoor,
    real): indoor scenes, thin among real maps, make half of the samples.

    Examples:
        >>> class S:
        ...     def __init__(self, label): self.label = label
        >>> default_weights([S("outdoor"), S("indoor"), S("outdoor")])
        [0.25, 0.5, 0.25]
    """
    labels = [getattr(s, "label", None) for s in sources]
    present = sorted(set(labels), key=str)
    return [1.0 / (len(present) * labels.count(lab)) for lab in labels]


def generator_for(seed: int, index: int) -> torch.Generator:
    """A CPU generator seeded with the first 8 bytes of ``blake2b(f"kornia_ilum.synth:{seed}:{index}")``.

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
            generator (:class:`~kornia_ilum.synth.environments.EnvironmentSource`); ``None``: the
            procedural defaults of :func:`default_sources` (no files needed).
        weights: non-negative weights, one per source, not all 0; ``None``: :func:`default_weights` (half
            indoor, half outdoor).
        augment: a callable ``(env, generator) -> Environment`` applied to every sample
            (:class:`~kornia_ilum.synth.environments.Augment`; stateless, so the shared default is safe),
            or ``None`` for none.
        seed: the seed (any int).

    Raises:
        TypeCheckError: a source lacks ``sample``, ``seed`` or ``index`` is not an int.
        ValueCheckError: bad weights, negative ``index``, or a source returned negative lighting.
        ShapeError: a source returned an environment with wrong shapes.

    Convention:
        ``Environment.params["sampler"]`` holds ``{"seed", "index", "source"}`` (the source's position in
        ``sources``). Lighting as in :mod:`kornia_ilum.synth.environments.base` (frame of
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
