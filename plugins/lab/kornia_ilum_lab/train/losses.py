r"""The training losses of the lighting estimators (LeGendre et al. 2020, Sec. 3.4).

- :func:`training_losses`: the multi-scale rendering loss ``sum_s lambda_s sum_k lambda_k L_rec(k, s)``, with
  the training form of ``L_rec`` (:func:`~kornia_ilum.metrics.reconstruction_loss`, ``gamma="safe"``) and
  the ground truth brought to each scale by the energy-keeping pyramid (docs/conventions.rst, "Multi-scale");
- :func:`discriminator_images`: the clipped, gamma-encoded mirror spheres that the discriminator sees;
- :func:`log_l2_loss`: the L2 distance of ``log(1 + L)`` on the mirror ball, the loss of the paper's ablation
  "log-L2 on the HDR lighting instead of the rendering losses" (:attr:`~kornia_ilum_lab.train.TrainConfig.loss`);
- :func:`energy_loss`: ``|log E_pred - log E_true|`` per channel, the lighting's energy, an optional term that is
  not the paper's (:attr:`~kornia_ilum_lab.train.TrainConfig.lambda_energy`);
- :func:`to_true_energy` and :func:`energy_nll`: the scale taken out of ``L_rec`` and learned on its own, with
  its spread (:attr:`~kornia_ilum_lab.train.TrainConfig.lambda_nll`, docs/training.rst, "The scale apart");
- :func:`albedo_loss`: the auxiliary task of telling the skin's albedo from the face
  (:attr:`~kornia_ilum_lab.train.TrainConfig.lambda_albedo`);
- :data:`BRDF_WEIGHTS`: the paper's ``lambda_k``.

The default step (:func:`~kornia_ilum_lab.train.recipes.train_step`), the recipes of the plugins and the weight
export (:func:`~kornia_ilum_lab.train.export_weights`) all use them.
"""

from __future__ import annotations

import torch

from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum.metrics import reconstruction_loss, total_radiance
from kornia_ilum.render import mirror_ball_pyramid, sphere_pyramid
from kornia_ilum_lab.synth.lightstage.subjects import SKIN_ALBEDO

__all__ = [
    "BRDF_WEIGHTS",
    "albedo_loss",
    "discriminator_images",
    "energy_loss",
    "energy_nll",
    "log_l2_loss",
    "log_energy",
    "to_true_energy",
    "training_losses",
]

#: lambda_k of the paper: mirror 0.2, diffuse 0.6, matte silver 0.2.
BRDF_WEIGHTS: dict[str, float] = {"diffuse": 0.6, "matte_silver": 0.2, "mirror": 0.2}


def discriminator_images(lightings: dict[int, torch.Tensor]) -> dict[int, torch.Tensor]:
    r"""The clipped, gamma-encoded mirror spheres that the discriminator sees, one per scale.

    Args:
        lightings: ``{size: (B, 3, size, size)}`` linear mirror-ball lighting per scale.

    Returns:
        ``{size: (B, 3, size, size)}``: the ``"mirror"`` sphere of each scale
        (:func:`~kornia_ilum.render.sphere_pyramid`, ``gamma="safe"``).

    Examples:
        >>> images = discriminator_images({4: torch.ones(1, 3, 4, 4), 8: torch.ones(1, 3, 8, 8)})
        >>> {s: tuple(x.shape) for s, x in images.items()}
        {4: (1, 3, 4, 4), 8: (1, 3, 8, 8)}
    """
    return {s: sphere_pyramid(x, sizes=(s,), brdfs=("mirror",), gamma="safe")[f"mirror_{s}"]
            for s, x in lightings.items()}


def training_losses(pred: dict[int, torch.Tensor], target: torch.Tensor, *, brdf_weights: dict[str, float],
                    lambda_scale: float = 1.0, truth: dict[int, torch.Tensor] | None = None
                    ) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    r"""The multi-scale rendering loss ``sum_s lambda_s sum_k lambda_k L_rec(k, s)`` (training form).

    Args:
        pred: ``{size: (B, 3, size, size)}`` predicted linear lighting per scale.
        target: ``(B, 3, 32, 32)`` ground-truth lighting; brought to each size by the energy-keeping pyramid.
        brdf_weights: ``lambda_k`` per sphere.
        lambda_scale: ``lambda_s``, the same for every scale.
        truth: ``target``'s pyramid at the sizes of ``pred``, when the caller has it already.

    Returns:
        the loss and its parts: ``rec_<brdf>`` at 32 px (detached).

    Examples:
        >>> truth = torch.ones(1, 3, 32, 32)
        >>> loss, parts = training_losses(mirror_ball_pyramid(truth, (4, 32)), truth,
        ...                               brdf_weights=BRDF_WEIGHTS)
        >>> round(loss.item(), 6), sorted(parts)
        (0.0, ['rec_diffuse', 'rec_matte_silver', 'rec_mirror'])
    """
    if truth is None:
        truth = mirror_ball_pyramid(target, tuple(pred))
    total = target.new_zeros(())
    parts = {}
    for s, x in pred.items():
        for brdf, weight in brdf_weights.items():
            term = reconstruction_loss(x, truth[s], brdf=brdf, size=s, gamma="safe")
            total = total + lambda_scale * weight * term
            if s == max(pred):
                parts[f"rec_{brdf}"] = term.detach()
    return total, parts


def log_l2_loss(pred: dict[int, torch.Tensor], truth: dict[int, torch.Tensor], lambda_scale: float = 1.0
                ) -> torch.Tensor:
    r"""``sum_s lambda_s mean((log(1 + L_pred) - log(1 + L_true))^2)`` over each scale's mirror-ball texels and
    channels: the loss on the HDR lighting itself that LeGendre et al. 2020 ablate against their rendering
    losses (Sec. 5, Table 4), and that Sun et al. 2019 train SIPR's lighting with.

    Args:
        pred: ``{size: (B, 3, size, size)}`` predicted linear mirror-ball lighting per scale.
        truth: the ground truth at the same sizes (:func:`~kornia_ilum.render.mirror_ball_pyramid`).
        lambda_scale: the weight of each scale.

    Returns:
        the loss, a float32 scalar (negative radiance counts as 0).

    Shape:
        - pred[size], truth[size]: :math:`(B, 3, size, size)`
        - Output: :math:`()`

    Convention:
        docs/conventions.rst, "Mirror ball" (only the texels on the ball count) and "Units of lighting".

    Examples:
        >>> light = {4: torch.ones(2, 3, 4, 4), 32: torch.ones(2, 3, 32, 32)}
        >>> float(log_l2_loss(light, light))
        0.0
        >>> dark = {s: torch.zeros_like(x) for s, x in light.items()}
        >>> round(float(log_l2_loss(dark, light)), 4)  # two scales of log(2)^2
        0.9609
    """
    total = next(iter(pred.values())).new_zeros((), dtype=torch.float32)
    for s, x in pred.items():
        valid = mirror_ball_valid(s, device=x.device).float()
        d = (torch.log1p(x.float().clamp_min(0)) - torch.log1p(truth[s].float().clamp_min(0))).square() * valid
        total = total + lambda_scale * d.sum() / (valid.sum() * d.shape[0] * d.shape[1])
    return total


def energy_loss(pred: torch.Tensor, target: torch.Tensor, eps: float = 1e-4) -> torch.Tensor:
    r"""How far the lighting's energy is off, in log: the mean over the batch and R, G, B of
    ``|log(E_pred + eps) - log(E_true + eps)|``, with ``E_c = sum_p Omega_p L_c,p``
    (:func:`~kornia_ilum.metrics.total_radiance`).

    ``L_rec`` compares gamma-encoded, soft-clipped spheres, so a lighting too dark by a factor costs less than
    one too bright by it; this term is symmetric in log and its minimum is the median of the energy's ratio at
    1 (docs/training.rst, "Why the energy drifts low, and the energy term").

    Negative radiance counts as 0 (docs/conventions.rst: lighting is never negative), as in the estimate's
    ``mirror_ball``: an unclamped order-2 SH reconstruction (``sh``'s training path) can have a negative total,
    whose log would be NaN.

    Args:
        pred: ``(B, 3, S, S)`` predicted linear mirror-ball lighting.
        target: ``(B, 3, S, S)`` ground truth at the same size.
        eps: added to both energies (in the lighting's units times steradians), for black lightings.

    Returns:
        the loss, a float32 scalar.

    Shape:
        - pred, target: :math:`(B, 3, S, S)`
        - Output: :math:`()`

    Convention:
        docs/conventions.rst, "Mirror ball" and "Units of lighting": both lightings in the same units.

    Examples:
        >>> light = torch.ones(2, 3, 32, 32)
        >>> float(energy_loss(light, light))
        0.0
        >>> round(float(energy_loss(2 * light, light)), 4)  # log 2
        0.6931
        >>> bool(energy_loss(-light, light).isfinite())  # negative radiance counts as 0
        True
    """
    e_pred, e_true = total_radiance(pred.clamp(min=0), torch.float32), total_radiance(target, torch.float32)
    return ((e_pred + eps).log() - (e_true + eps).log()).abs().mean()


def log_energy(lighting: torch.Tensor, eps: float = 1e-4) -> torch.Tensor:
    r"""``log(E + eps)`` per lighting, ``E`` the energy averaged over R, G, B
    (:func:`~kornia_ilum.metrics.total_radiance`), negative radiance counted as 0; float32.

    Args:
        lighting: ``(B, 3, S, S)`` linear mirror-ball lighting.
        eps: added to the energy (in the lighting's units times steradians), for black lightings.

    Returns:
        ``(B,)`` float32.

    Examples:
        >>> from kornia_ilum.geometry import mirror_ball_valid
        >>> round(float(log_energy(torch.ones(1, 3, 32, 32) * mirror_ball_valid(32), eps=0.0)[0].exp()), 4)
        12.5664
    """
    return (total_radiance(lighting.clamp(min=0), torch.float32).mean(-1) + eps).log()


def to_true_energy(pred: dict[int, torch.Tensor], truth: dict[int, torch.Tensor]) -> dict[int, torch.Tensor]:
    r"""Each prediction scaled so that its energy is the truth's: the lighting's shape without its strength.

    ``L_pred * E_true / E_pred`` per lighting and scale, with ``E`` the energy averaged over R, G, B (so the
    colour stays the prediction's). ``L_rec`` of the result is blind to the prediction's overall scale,
    exactly (its gradient has no component along it): the scale is then learned by :func:`energy_nll` alone,
    and the L1's pull of the energy below the truth (docs/training.rst, "Why the energy drifts low") is gone.

    Args:
        pred: ``{size: (B, 3, size, size)}`` predicted linear lighting.
        truth: the ground truth at the same sizes.

    Returns:
        ``{size: (B, 3, size, size)}`` float32.

    Examples:
        >>> light = torch.rand(2, 3, 8, 8) + 0.1
        >>> out = to_true_energy({8: 5.0 * light}, {8: light})
        >>> torch.allclose(out[8], light)
        True
    """
    out = {}
    for s, p in pred.items():
        gain = (log_energy(truth[s], eps=0.0) - log_energy(p, eps=0.0)).exp()
        out[s] = p.float() * gain[:, None, None, None]
    return out


def energy_nll(pred: torch.Tensor, target: torch.Tensor, log_spread: torch.Tensor) -> torch.Tensor:
    r"""The Laplace negative log-likelihood of the true log energy under the estimate's and its spread.

    ``mean(|log E_true - log E_pred| / b + log b)`` over the batch, with ``b = exp(log_spread)`` and ``E`` the
    energy averaged over R, G, B (:func:`log_energy`; up to the constant ``log 2``). Its minimum over
    ``E_pred`` is the median of the true energy given the crop (symmetric in log: a light read twice too
    bright costs what one read half as bright does), and over ``b`` the mean absolute error of that log, so
    that ``+-b`` holds the truth for ``1 - 1/e`` of the portraits (the calibration that ``kornia-ilum evaluate
    --checks spread`` measures). Portraits that cannot settle the strength (large ``b``) pull less on it.

    Args:
        pred: ``(B, 3, S, S)`` predicted linear lighting.
        target: ``(B, 3, S, S)`` the ground truth at the same size.
        log_spread: ``(B,)`` the spread head's ``log b``.

    Returns:
        a float32 scalar.

    Examples:
        >>> light = torch.ones(2, 3, 8, 8)
        >>> float(energy_nll(light, light, torch.zeros(2)))
        0.0
        >>> round(float(energy_nll(torch.e * light, light, torch.zeros(2))), 4)  # |log e| / 1 + log 1
        1.0
    """
    error = (log_energy(target) - log_energy(pred)).abs()
    log_spread = log_spread.float()
    return (error * torch.exp(-log_spread) + log_spread).mean()


def albedo_loss(log_albedo: torch.Tensor, skin_tone: torch.Tensor) -> torch.Tensor:
    r"""How far the predicted log skin albedo is from the subject's tone's: ``mean |pred - log a(tone)|``.

    ``a(tone)`` is the mean over R, G, B of the tone's calibrated albedo
    (:data:`~kornia_ilum_lab.synth.lightstage.subjects.SKIN_ALBEDO`, Monk tones 1 to 10: 0.386 to 0.036); samples of
    unknown tone (``-1``) are left out (0 when none is known). Under any light the face shows its albedo only
    relative to the light, so this asks the encoder for what the strength of the light depends on.

    Args:
        log_albedo: ``(B,)`` predicted natural log albedo.
        skin_tone: ``(B,)`` int Monk tones, ``-1`` unknown.

    Returns:
        a float32 scalar.

    Examples:
        >>> truth = torch.tensor([sum(SKIN_ALBEDO[0]) / 3, sum(SKIN_ALBEDO[9]) / 3]).log()
        >>> float(albedo_loss(truth, torch.tensor([1, 10]))), float(albedo_loss(truth, torch.tensor([-1, -1])))
        (0.0, 0.0)
    """
    table = torch.tensor(SKIN_ALBEDO, dtype=torch.float32, device=log_albedo.device).mean(-1).log()
    known = (skin_tone >= 1) & (skin_tone <= len(SKIN_ALBEDO))
    if not bool(known.any()):
        return log_albedo.new_zeros((), dtype=torch.float32)
    tone = skin_tone.to(log_albedo.device)[known] - 1
    return (log_albedo.float()[known] - table[tone]).abs().mean()
