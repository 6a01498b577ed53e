r"""The ``sh`` estimator: the encoder of ``ours`` regressing order-2 SH coefficients of linear HDR lighting.

The common low-frequency baseline of single-image lighting estimation (for portraits: SfSNet, DPR, DECA
all predict order-2 SH), trained here on the same data and with the same rendering loss as ``ours``
(LeGendre et al. 2020), so the two differ only in the lighting representation: 27 numbers instead of a
32 x 32 mirror ball.

Network (4,878,011 parameters at ``latent_dim=1024``): the encoder of
:class:`~kornia_ilum.estimators.OursEstimator`, built by :func:`kornia_ilum.estimators.ours.build_encoder`
(its ``encoder`` and ``to_latent`` modules: five 3 x 3 convolutions of depths 16 to 256, each with ReLU and
blur-pooling, 256 -> 8 px, the 8 x 8 convolution with ReLU, the fully-connected layer to the 1024-d latent),
on the crop shifted to ``[-0.5, 0.5]`` as in ``ours``; then a linear head ``1024 -> 27``, read as the
``(B, 9, 3)`` radiance SH coefficients of docs/conventions.rst ("Spherical harmonics": real, orthonormal,
order 2, the order and frame of docs/conventions.rst), in the units of the input image (linear, not log: SH
of log lighting is not lighting).

Negative lobes. An order-2 function is negative near the antipode of a bright light (the order-2 SH of a
point light dips to -20 % of its peak), but docs/conventions.rst ("Images") says HDR lighting is never
negative. So:

- ``estimate.sh`` holds the raw, unclamped coefficients (what the network predicts);
- ``estimate.mirror_ball`` is ``sh_reconstruct(sh, 32, clamp_negative=True)``: the reconstruction at the
  pixel centres, clamped at 0 (valid lighting, but no longer exactly an order-2 function);
  ``log_mirror_ball`` is ``log(1 + mirror_ball)``;
- training (:mod:`kornia_ilum_sh.recipe`) renders the spheres from the *unclamped* reconstruction, so the
  loss sees the negative lobes as the SH lighting really is (``softclip`` counts negative sphere values as
  0, docs/conventions.rst, "The paper's error measure L_rec"), plus a small penalty on negative radiance
  (see there). The recipe imports this module, never the other way: creating the estimator does not import
  the training code.

Exposure, by design (issue 39): ``normalize_exposure=True`` (the default) re-exposes each crop to a
centre-weighted mean luminance of 0.18 before the network (:func:`kornia_ilum.color.normalize_exposure`, as
``ours`` does) and multiplies the coefficients by the factor back, so the estimate follows the photo's
exposure exactly wherever nothing clips. The shipped weights were trained on crops auto-exposed to keys 0.1 to
0.3, so a crop at 0.18 is one they saw; the training path (:meth:`SHEstimator.coefficients`) is the network
alone, as trained. ``False`` gives the network as it was trained, which read 1.74 times the light of a photo
darkened 4 times.

The spread of the strength (``spread_head=True``, as in ``ours``): one linear layer from the latent to ``log b``,
the scale of a Laplace distribution of the true lighting's log energy around the estimate's
(:attr:`~kornia_ilum.estimators.LightingEstimate.log_energy_spread`), trained by its negative log-likelihood
(``kornia-ilum train --estimator sh --lambda-nll``, docs/training.rst). It changes nothing else. A weight file
that has it turns it on when loaded.

The head's bias starts at uniform radiance :data:`INIT_RADIANCE` (coefficient (0, 0) =
``INIT_RADIANCE * sqrt(4 pi)``, the others 0), so that the untrained network's spheres are positive and the
rendering loss has gradients from the first step (negative sphere pixels have none).
"""

from __future__ import annotations

import math

import torch
from typing import Any

from torch import Tensor, nn

from kornia_ilum.color import normalize_exposure
from kornia_ilum.core.check import check_positive_int, trusted
from kornia_ilum.estimators import EstimatorInfo, LightingEstimate, LightingEstimator, WeightFile, adopt_spread_head
from kornia_ilum.estimators.ours import LOG_SPREAD_RANGE, build_encoder
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum.sh import sh_reconstruct

__all__ = ["INIT_RADIANCE", "LIGHTING_SIZE", "NUM_COEFFICIENTS", "PAPER", "SHEstimator"]

#: Side of the mirror ball of the estimate.
LIGHTING_SIZE = 32
#: Order-2 SH: 9 coefficients per channel.
NUM_COEFFICIENTS = 9
#: Uniform radiance of the untrained network's bias (input-image units).
INIT_RADIANCE = 0.5

_INPUT_SIZE = 256

PAPER = (
    "baseline: order-2 SH lighting (Ramamoorthi & Hanrahan 2001, as predicted by SfSNet, Sengupta et al. "
    "CVPR 2018, and DPR, Zhou et al. ICCV 2019) from the encoder of LeGendre et al. 2020, "
    '"Learning Illumination from Diverse Portraits", SIGGRAPH Asia 2020 Technical Communications, '
    "doi:10.1145/3410700.3425432, trained with its rendering loss"
)


class SHEstimator(LightingEstimator):
    r"""The encoder of ``ours`` plus a linear head: face crop -> order-2 SH of linear HDR lighting.

    See the module docstring for the network, the negative lobes and the initialisation.

    Args:
        latent_dim: size of the encoder's fully-connected bottleneck (1024, as in ``ours``).
        normalize_exposure: re-expose the crop to a metered 0.18 and scale the estimate back (module
            docstring, "Exposure"); not saved in the weights.
        spread_head: add the spread head (module docstring): the estimate then has ``log_energy_spread``. A
            weight file that has the head turns it on when loaded.

    Returns:
        (from ``forward``) a :class:`~kornia_ilum.estimators.LightingEstimate` with ``sh`` (the raw
        coefficients), ``mirror_ball`` (their reconstruction clamped at 0), ``log_mirror_ball``
        (``log(1 + mirror_ball)``) and ``valid``, and ``log_energy_spread`` with the spread head.

    Shape:
        - Input: :math:`(B, 3, 256, 256)`, sRGB in ``[0, 1]``
        - Output: ``sh``: :math:`(B, 9, 3)`; ``mirror_ball``, ``log_mirror_ball``: :math:`(B, 3, 32, 32)`

    Convention:
        docs/conventions.rst, "Spherical harmonics" (order, frame, orthonormal basis), "Mirror ball" and
        "Units of lighting": radiance in the units of the input image, 0 outside the ball. The outputs have
        the dtype of the module's parameters, also under :func:`torch.autocast` (the reconstruction runs in
        float32 outside autocast, then is cast).

    Examples:
        >>> net = SHEstimator()
        >>> sum(p.numel() for p in net.parameters())
        4878011
        >>> est = net(torch.rand(2, 3, 256, 256))
        >>> tuple(est.sh.shape), tuple(est.mirror_ball.shape)
        ((2, 9, 3), (2, 3, 32, 32))
        >>> from kornia_ilum.sh import sh_reconstruct
        >>> torch.equal(est.mirror_ball, sh_reconstruct(est.sh, 32).clamp(min=0))
        True
    """

    info = EstimatorInfo(
        name="sh",
        description="the encoder of 'ours' with a linear head: 256 x 256 face crop -> order-2 SH "
        "(9 x 3 coefficients) of linear HDR lighting, reconstructed on a 32 x 32 mirror ball",
        paper=PAPER,
        input_size=_INPUT_SIZE,
        weights=(WeightFile("sh.safetensors", "6d2f6e6aa19090508f5b1d05bc679b27d3de14e5f32e295d5aa53b683188507f"),),
        install_hint="pip install ./plugins/sh (package kornia_ilum_sh); its weights ship inside it "
        "(kornia_ilum_sh/weights/); reinstall it",
    )

    def __init__(self, latent_dim: int = 1024, normalize_exposure: bool = True, spread_head: bool = False) -> None:
        super().__init__()
        check_positive_int(latent_dim, "latent_dim")
        self.latent_dim = latent_dim
        self.normalize_exposure = bool(normalize_exposure)
        self.encoder, self.to_latent = build_encoder(latent_dim)  # the same encoder as ours
        self.head = nn.Linear(latent_dim, NUM_COEFFICIENTS * 3)
        with torch.no_grad():
            self.head.bias.zero_()
            self.head.bias[:3] = INIT_RADIANCE * math.sqrt(4 * math.pi)  # coefficient (0, 0), RGB
        self.spread: nn.Linear | None = nn.Linear(latent_dim, 1) if spread_head else None
        self.register_buffer("valid", mirror_ball_valid(LIGHTING_SIZE), persistent=False)

    def _load_from_state_dict(self, state_dict: dict[str, Any], prefix: str, *args: Any) -> None:
        adopt_spread_head(self, state_dict, prefix, self.latent_dim)
        super()._load_from_state_dict(state_dict, prefix, *args)

    def decode(self, crops: Tensor) -> tuple[Tensor, Tensor | None]:
        r"""The raw network: unclamped SH coefficients and the spread head's ``log b``, no input checks (the
        training path).

        Args:
            crops: sRGB crops in ``[0, 1]``, :math:`(B, 3, 256, 256)`.

        Returns:
            ``(sh, log_spread)``: :math:`(B, 9, 3)` radiance SH coefficients (the order of
            docs/conventions.rst), in the dtype of the head (or of an enclosing autocast), and :math:`(B,)`
            float32 ``log b`` clamped to :data:`~kornia_ilum.estimators.ours.LOG_SPREAD_RANGE` (``None`` without
            the spread head).
        """
        dtype = self.head.weight.dtype
        with trusted():  # the layers' own checks would scan every activation; the crops were checked
            latent = self.to_latent(self.encoder(crops.to(dtype) - 0.5))
        log_spread = None
        if self.spread is not None:
            log_spread = self.spread(latent)[:, 0].float().clamp(*LOG_SPREAD_RANGE)
        return self.head(latent).reshape(-1, NUM_COEFFICIENTS, 3), log_spread

    def coefficients(self, crops: Tensor) -> Tensor:
        r"""The unclamped SH coefficients of :meth:`decode`, :math:`(B, 9, 3)`."""
        return self.decode(crops)[0]

    def predict(self, crops: Tensor) -> LightingEstimate:
        dtype = self.head.weight.dtype
        scale = None
        if self.normalize_exposure:
            with torch.autocast(crops.device.type, enabled=False), trusted():  # forward() checked the crops
                crops, scale = normalize_exposure(crops.float())
        sh, log_spread = self.decode(crops)
        with torch.autocast(sh.device.type, enabled=False):
            sh = sh.float() if scale is None else sh.float() * scale[:, None, None]
            mirror_ball = sh_reconstruct(sh, LIGHTING_SIZE, "mirror_ball", clamp_negative=True)
            log_mirror_ball = torch.log1p(mirror_ball)
        return LightingEstimate(
            mirror_ball=mirror_ball.to(dtype),
            valid=self.valid,
            log_mirror_ball=log_mirror_ball.to(dtype),
            sh=sh.to(dtype),
            log_energy_spread=None if log_spread is None else torch.exp(log_spread).to(dtype),
        )
