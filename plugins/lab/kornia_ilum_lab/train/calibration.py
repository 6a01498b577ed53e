r"""Energy calibration at export: scale each output channel so that the estimated energy is right on the median.

The paper's ``L_rec`` compares gamma-encoded, soft-clipped spheres with an L1 norm. It is not symmetric in the
scale of the light: a lighting too dark by a factor costs less than one too bright by it
(``benchmarks/lrec_scale.py``; docs/training.rst, "Why the energy drifts low"), so under uncertainty a
network trained on it settles below the true energy. :func:`calibrate_energy` measures that bias after
training, on fresh portraits of the **training** distribution (training subjects, training environments, a
data stream that no training step draws), and folds it into the estimator's output as one gain per channel:

.. math::

    g_c = \exp\Big(\operatorname{median}_i \log \frac{E_c(\text{true}_i)}{E_c(\text{pred}_i)}\Big),

with :math:`E_c` the lighting's radiance summed over the sphere (:func:`~kornia_ilum.metrics.total_radiance`).
A gain changes no direction and no ratio between two estimates (the crop and transfer checks keep their
values); it moves the median of the energy's ratio to the truth to 1 on the training distribution. It never
reads the evaluation split. The recipe applies the gain (:meth:`~kornia_ilum_lab.train.recipes.Recipe.scale_output`;
for ``ours``, a constant added to the head's log-radiance bias: exact).

The spread of the strength, fitted at export (:func:`fit_spread`, ``--fit-spread N``): for an estimator whose
spread head was not trained with the network (``sipr``, whose recipe has no likelihood term), or to refit one
that was (the shipped heads of ``ours`` and ``sh``), the head alone
(a linear layer ``log b = w . f + c`` on the features the estimator gives it) is fitted on fresh portraits of
the same training stream, the rest frozen: the Laplace negative log-likelihood
``mean(|log E_true - log E_pred| e^(-log b) + log b)`` (:func:`~kornia_ilum_lab.train.losses.energy_nll`) is
convex in ``(w, c)``, so L-BFGS on the standardised features finds its minimum (a small ridge on ``w`` keeps
1000-odd features from fitting the portraits' noise). Then ``c`` moves so that ``+-b`` holds ``1 - 1/e`` of the
fitted portraits, what the spread promises (docs/questions.rst): the likelihood's ``b`` is the mean absolute
error, which holds ``1 - 1/e`` of Laplace errors but only 57.5 % of Gaussian ones, and the errors of the
estimators are closer to the latter. The lighting does not change.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import torch

from kornia_ilum.color import LUMINANCE
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.estimators.ours import LOG_SPREAD_RANGE
from kornia_ilum.metrics import total_radiance
from kornia_ilum_lab.synth.lightstage.portraits import PortraitDataset
from kornia_ilum_lab.train.data import collate
from kornia_ilum_lab.train.losses import log_energy
from kornia_ilum_lab.train.recipes import PROBE_STREAM, Recipe

__all__ = ["CALIBRATION_STREAM", "calibrate_energy", "energy_log_ratios", "fit_spread"]

#: The data stream of the calibration portraits: neither a training stream (``rank * workers + k``) nor the
#: float16 probe's (:data:`~kornia_ilum_lab.train.recipes.PROBE_STREAM`).
CALIBRATION_STREAM = PROBE_STREAM - 1


def energy_log_ratios(estimator: torch.nn.Module, dataset: PortraitDataset, samples: int,
                      batch: int = 32) -> torch.Tensor:
    r"""``log(E_true / E_pred)`` per portrait and channel, :math:`(N, 3)` float64, on ``samples`` portraits of
    ``dataset``'s :data:`CALIBRATION_STREAM` (the estimator runs in float32, without gradients).

    Args:
        estimator: a lighting estimator: ``estimator(crops).mirror_ball`` from sRGB crops in ``[0, 1]``.
        dataset: the training portraits (:func:`~kornia_ilum_lab.train.data.training_dataset`).
        samples: the number of portraits.
        batch: portraits per forward pass.

    Returns:
        ``log(E_true / E_pred)``, float64, with ``E`` the energy per channel
        (:func:`~kornia_ilum.metrics.total_radiance`).

    Raises:
        ValueCheckError: ``samples`` is not positive, or an estimate has no energy in some channel.

    Shape:
        - Output: :math:`(N, 3)`, ``N = samples``

    Convention:
        The estimate and the truth are mirror balls in the units of the crops (docs/conventions.rst, "Mirror
        ball" and "Units of lighting"); a positive log ratio means the estimate is too dark.

    Examples:
        ``samples`` is checked before any portrait is drawn:

        >>> energy_log_ratios(torch.nn.Identity(), None, samples=0)
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: samples must be a positive integer, got 0

        A real call draws portraits from a light-stage cache:

        >>> from kornia_ilum_lab.train import TrainConfig
        >>> from kornia_ilum_lab.train.data import training_dataset
        >>> dataset = training_dataset(TrainConfig(out="runs/ours", cache=("lightstage/",)))  # doctest: +SKIP
        >>> from kornia_ilum.estimators import create_estimator
        >>> energy_log_ratios(create_estimator("ours"), dataset, samples=64).shape  # doctest: +SKIP
        torch.Size([64, 3])
    """
    ratios = [torch.log(total_radiance(truth, torch.float64)) - torch.log(total_radiance(pred, torch.float64))
              for truth, pred in _estimates(estimator, dataset, samples, batch)]
    out = torch.cat(ratios)
    if not torch.isfinite(out).all():
        raise ValueCheckError("an estimate or a truth of the calibration portraits has no energy in a channel; "
                              "the energy cannot be calibrated")
    return out


def _estimates(estimator: torch.nn.Module, dataset: PortraitDataset, samples: int, batch: int
               ) -> Iterator[tuple[torch.Tensor, torch.Tensor]]:
    """``(truth, estimate)`` mirror balls of ``samples`` portraits of the :data:`CALIBRATION_STREAM`, ``batch`` at a
    time, the estimator run without gradients (``samples`` checked before any portrait is drawn)."""
    if isinstance(samples, bool) or not isinstance(samples, int) or samples <= 0:
        raise ValueCheckError(f"samples must be a positive integer, got {samples!r}")
    stream = dataset.samples(CALIBRATION_STREAM)
    for start in range(0, samples, batch):
        chunk = collate([next(stream) for _ in range(min(batch, samples - start))])
        with torch.no_grad():  # closed before the yield: the caller's grad mode is its own
            pred = estimator(chunk["image"].float() / 255.0).mirror_ball
        yield chunk["mirror_ball"], pred


def calibrate_energy(estimator: torch.nn.Module, recipe: Recipe, dataset: PortraitDataset,
                     samples: int, *, keep_luminance: bool = False) -> dict[str, Any]:
    r"""Scale ``estimator``'s output per channel, in place, by the gain of the module's docstring.

    With ``keep_luminance``, only the estimate's white balance is calibrated: the gains are divided by their
    geometric mean weighted by the luminance's coefficients (:data:`~kornia_ilum.color.LUMINANCE`),
    ``g_c / exp(sum_k w_k log g_k)``, so a grey light's luminance is unchanged and only the colour's cast is
    taken out (``kornia-ilum train --calibrate-colour N``): what a per-channel bias costs the rendered spheres
    without moving the overall level that ``L_rec`` prefers.

    Args:
        estimator: the trained estimator (float32, on the CPU), changed in place.
        recipe: its training recipe, which applies the gain (:meth:`~kornia_ilum_lab.train.recipes.Recipe.scale_output`).
        dataset: the training portraits (:func:`~kornia_ilum_lab.train.data.training_dataset`).
        samples: the portraits the gain is measured on (:func:`energy_log_ratios`).
        keep_luminance: calibrate the colour alone.

    Returns:
        ``{"samples", "gain", "median_ratio_before", "median_ratio_after"}`` (the ratios are
        ``E_pred / E_true`` per channel, R, G, B), for the run's ``summary.json``.

    Raises:
        ValueCheckError: as :func:`energy_log_ratios`, or the recipe cannot scale its estimator's output.

    Examples:
        It needs a light-stage cache and a trained estimator (``kornia-ilum train --calibrate-energy N`` calls
        it at export):

        >>> from kornia_ilum_lab.train import TrainConfig, get_recipe
        >>> from kornia_ilum_lab.train.data import training_dataset
        >>> from kornia_ilum.estimators import create_estimator
        >>> dataset = training_dataset(TrainConfig(out="runs/ours", cache=("lightstage/",)))  # doctest: +SKIP
        >>> report = calibrate_energy(create_estimator("ours"), get_recipe("ours"), dataset, 256)  # doctest: +SKIP
        >>> sorted(report)  # doctest: +SKIP
        ['gain', 'median_ratio_after', 'median_ratio_before', 'samples']
    """
    before = energy_log_ratios(estimator, dataset, samples)
    log_gain = before.median(0).values
    if keep_luminance:
        log_gain = log_gain - log_gain @ torch.tensor(LUMINANCE, dtype=log_gain.dtype)
    gain = torch.exp(log_gain)
    recipe.scale_output(estimator, gain)
    after = before - torch.log(gain)  # a recipe's gain is exact: no second pass over the portraits
    return {"samples": samples, "gain": gain.tolist(),
            "median_ratio_before": torch.exp(-before.median(0).values).tolist(),
            "median_ratio_after": torch.exp(-after.median(0).values).tolist()}


def fit_spread(estimator: torch.nn.Module, dataset: PortraitDataset, *, samples: int, ridge: float = 1e-2,
               batch: int = 32) -> dict[str, Any]:
    r"""Fit ``estimator``'s spread head alone, in place, on ``samples`` fresh training portraits (module docstring).

    Args:
        estimator: a trained estimator with a spread head ``estimator.spread`` (an ``nn.Linear`` to one
            output) whose ``forward`` returns ``log_energy_spread``; float32, on the CPU.
        dataset: the training portraits as the estimator's recipe draws them.
        samples: the portraits the head is fitted on (:data:`CALIBRATION_STREAM`).
        ridge: the weight of ``|w|^2`` on the standardised features.
        batch: portraits per forward pass.

    Returns:
        ``{"samples", "features", "nll_before", "nll_after", "coverage_shift", "within_one_spread",
        "median_spread"}`` on the fitted portraits (``coverage_shift``: the ``log b`` added so that
        ``within_one_spread``, the share whose true log energy lies within ``+-b``, is ``1 - 1/e``), for the
        run's ``summary.json``.

    Raises:
        ValueCheckError: ``samples`` is not positive, the estimator has no spread head, or an estimate or a
            truth has no energy.

    Examples:
        It needs a light-stage cache and a trained estimator (``kornia-ilum train --fit-spread N`` calls it at
        export):

        >>> from kornia_ilum_lab.train import TrainConfig
        >>> from kornia_ilum_lab.train.data import training_dataset
        >>> from kornia_ilum.estimators import create_estimator
        >>> dataset = training_dataset(TrainConfig(out="runs/sh", cache=("lightstage/",)))  # doctest: +SKIP
        >>> estimator = create_estimator("sh", spread_head=True)  # doctest: +SKIP
        >>> report = fit_spread(estimator, dataset, samples=2048)  # doctest: +SKIP
        >>> round(report["within_one_spread"], 1)  # doctest: +SKIP
        0.6
    """
    head = getattr(estimator, "spread", None)
    if not isinstance(head, torch.nn.Linear) or head.out_features != 1:
        raise ValueCheckError("fit_spread needs an estimator with a spread head (--model spread_head=True)")
    captured: list[torch.Tensor] = []
    hook = head.register_forward_pre_hook(lambda _, args: captured.append(args[0].detach().double()))
    try:
        errors = [(log_energy(truth.double()) - log_energy(pred.double())).abs()
                  for truth, pred in _estimates(estimator, dataset, samples, batch)]
    finally:
        hook.remove()
    error, features = torch.cat(errors), torch.cat(captured)
    if not torch.isfinite(error).all():
        raise ValueCheckError("an estimate or a truth of the calibration portraits has no energy; the spread "
                              "cannot be fitted")
    mean, std = features.mean(0), features.std(0).clamp(min=1e-6)
    x = (features - mean) / std
    w = torch.zeros(x.shape[1], dtype=torch.float64, requires_grad=True)
    c = torch.tensor(float(error.mean().clamp(min=1e-3).log()), dtype=torch.float64, requires_grad=True)

    def nll(log_b: torch.Tensor) -> torch.Tensor:
        return (error * torch.exp(-log_b) + log_b).mean()

    with torch.no_grad():
        before = float(nll(_log_b(head, features)))
    opt = torch.optim.LBFGS([w, c], lr=1.0, max_iter=200, line_search_fn="strong_wolfe")

    def closure() -> torch.Tensor:
        opt.zero_grad()
        loss = nll(x @ w + c) + ridge * w.square().sum()
        loss.backward()
        return loss

    opt.step(closure)
    with torch.no_grad():
        fitted = x @ w + c
        shift = float(torch.quantile(torch.log(error.clamp(min=1e-12)) - fitted, 1 - math.exp(-1)))
        weight = (w / std).to(head.weight)
        head.weight.copy_(weight[None])
        head.bias.fill_(float(c + shift - (mean / std) @ w))
        log_b = _log_b(head, features)
    return {"samples": samples, "features": int(x.shape[1]), "nll_before": before, "nll_after": float(nll(log_b)),
            "coverage_shift": shift,
            "within_one_spread": float((error <= log_b.exp()).double().mean()),
            "median_spread": float(log_b.exp().median())}


def _log_b(head: torch.nn.Linear, features: torch.Tensor) -> torch.Tensor:
    """The spread head's ``log b`` of captured features (float64), clamped as the estimators clamp it."""
    return (features @ head.weight.double()[0] + head.bias.double()[0]).clamp(*LOG_SPREAD_RANGE)
