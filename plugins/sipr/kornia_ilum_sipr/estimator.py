r"""The ``sipr`` estimator: the encoder and lighting head of the SIPR U-Net (Sun et al. 2019).

Sun et al., "Single Image Portrait Relighting" (SIGGRAPH 2019), train a U-Net that relights a portrait and, at
its bottleneck, estimates the portrait's lighting; LeGendre et al. 2020 compare against that lighting
estimate. At inference only the encoder and the lighting head run (:mod:`kornia_ilum_sipr.network`), on
batches of any size; the relighting decoder is training-only (:mod:`kornia_ilum_sipr.recipe`) and not in the
shipped weights. The recipe imports this module, never the other way: creating the estimator does not import
the training code.

The head predicts a 16 x 32 lat-long ``z = log(1 + L)``; the estimate's ``mirror_ball`` is ``L = exp(z) - 1``
resampled to the 32 x 32 equal-area mirror ball of docs/conventions.rst ("Mirror ball") by energy-conserving
area averaging (:func:`~kornia_ilum.geometry.latlong_to_mirror_ball`, ``mode="area"``: ``sum(L * omega)`` per
channel is kept), and ``log_mirror_ball`` is ``log(1 + mirror_ball)``. Lighting is in the units of the input
image.

Exposure, by design (issue 39): ``normalize_exposure=True`` (the default) re-exposes each crop to a
centre-weighted mean luminance of 0.18 before the network (:func:`kornia_ilum.color.normalize_exposure`, as
``ours`` does) and multiplies the estimate by the factor back, so it follows the photo's exposure exactly
wherever nothing clips. The shipped weights were trained on crops auto-exposed to keys 0.1 to 0.3, so a crop
at 0.18 is one they saw; the training path (:meth:`SIPREstimator.log_latlong`) is the network alone, as
trained. ``False`` gives the network as it was trained, which read 2.55 times the light of a photo darkened 4
times.

The spread of the strength (``spread_head=True``): one linear layer from the bottleneck, averaged over its
8 x 8 positions, to ``log b``, the scale of a Laplace distribution of the true lighting's log energy around the
estimate's (:attr:`~kornia_ilum.estimators.LightingEstimate.log_energy_spread`). It is fitted after training
with the rest of the network frozen (``kornia-ilum train --estimator sipr --fit-spread N``,
:func:`kornia_ilum_lab.train.calibration.fit_spread`), so the lighting is the trained network's, unchanged. A weight file that
has it turns it on when loaded.
"""

from __future__ import annotations

from typing import Any

import torch
from torch import Tensor, nn

from kornia_ilum.color import normalize_exposure
from kornia_ilum.core.check import trusted
from kornia_ilum.estimators import EstimatorInfo, LightingEstimate, LightingEstimator, WeightFile, adopt_spread_head
from kornia_ilum.estimators.ours import LOG_SPREAD_RANGE
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum_sipr.network import ENCODER_DEPTHS, LIGHTING_SHAPE, Encoder, LightingHead, log_latlong_to_mirror_ball

__all__ = ["INPUT_SIZE", "LIGHTING_SIZE", "PAPER", "SIPREstimator"]

#: Side of the mirror ball of the estimate.
LIGHTING_SIZE = 32
#: Side of the face crops that ``sipr`` is trained and run at: 128, half the paper's 256. The cut that makes its
#: training fit the project's budget (a step costs about a quarter of one at 256; plugins/sipr/README.md,
#: "Training cost"). The network is fully convolutional, so nothing else changes: the bottleneck is 8 x 8
#: instead of 16 x 16, and the confidence-weighted head pools over it. :func:`~kornia_ilum.estimate_lighting`
#: cuts each face's crop at this size, and ``kornia-ilum evaluate`` resizes its 256 px eval crops to it.
INPUT_SIZE = 128

PAPER = (
    'Sun et al. 2019, "Single Image Portrait Relighting", ACM TOG 38(4) (SIGGRAPH), doi:10.1145/3306346.3323008; '
    "the architecture of the public reimplementation ken2576/nelf (network/u_net.py), rewritten, as the "
    'baseline of LeGendre et al. 2020, "Learning Illumination from Diverse Portraits"'
)


class SIPREstimator(LightingEstimator):
    r"""The SIPR encoder and lighting head: face crop -> 16 x 32 log lat-long -> 32 x 32 HDR mirror ball.

    See the module docstring and :mod:`kornia_ilum_sipr.network`.

    Args:
        normalize_exposure: re-expose the crop to a metered 0.18 and scale the estimate back (module
            docstring, "Exposure"); not saved in the weights.
        spread_head: add the spread head (module docstring): the estimate then has ``log_energy_spread``. A
            weight file that has the head turns it on when loaded.

    Returns:
        (from ``forward``) a :class:`~kornia_ilum.estimators.LightingEstimate` with ``mirror_ball``,
        ``log_mirror_ball`` (``log(1 + mirror_ball)``) and ``valid``, and ``log_energy_spread`` with the
        spread head.

    Shape:
        - Input: :math:`(B, 3, 128, 128)` (:data:`INPUT_SIZE`), sRGB in ``[0, 1]``
        - Output: ``mirror_ball``, ``log_mirror_ball``: :math:`(B, 3, 32, 32)`

    Convention:
        docs/conventions.rst, "Mirror ball" and "Units of lighting". The outputs have the dtype of the module's
        parameters, also under :func:`torch.autocast` (the resampling runs in float32, then is cast).

    Examples:
        >>> net = SIPREstimator()
        >>> sum(p.numel() for p in net.parameters())
        18874139
        >>> est = net(torch.rand(2, 3, 128, 128))
        >>> tuple(est.mirror_ball.shape), bool((est.mirror_ball >= 0).all())
        ((2, 3, 32, 32), True)
        >>> tuple(net.latlong(torch.rand(1, 3, 128, 128)).shape)
        (1, 3, 16, 32)
    """

    info = EstimatorInfo(
        name="sipr",
        description="Sun et al. 2019's portrait-relighting U-Net (GroupNorm, PReLU, /16 bottleneck), its "
        "confidence-weighted lighting head: 128 x 128 face crop (the paper's 256, halved for the training budget) "
        "-> 16 x 32 log-HDR lat-long -> 32 x 32 mirror ball",
        paper=PAPER,
        input_size=INPUT_SIZE,
        weights=(
            WeightFile("sipr.safetensors", "2260ef97637cb7807fcc756d1e632b630160e9a8f51e56db53ef75b84cd003d2"),
        ),
        install_hint="pip install ./plugins/sipr (package kornia_ilum_sipr); its weights ship inside it "
        "(kornia_ilum_sipr/weights/); reinstall it",
        needs_weights=True,
    )

    def __init__(self, normalize_exposure: bool = True, spread_head: bool = False) -> None:
        super().__init__()
        self.normalize_exposure = bool(normalize_exposure)
        self.encoder = Encoder()
        self.head = LightingHead(LIGHTING_SHAPE)
        self.spread: nn.Linear | None = nn.Linear(ENCODER_DEPTHS[-1], 1) if spread_head else None
        self.register_buffer("valid", mirror_ball_valid(LIGHTING_SIZE), persistent=False)

    def _load_from_state_dict(self, state_dict: dict[str, Any], prefix: str, *args: Any) -> None:
        adopt_spread_head(self, state_dict, prefix, ENCODER_DEPTHS[-1])
        super()._load_from_state_dict(state_dict, prefix, *args)

    def log_latlong(self, crops: Tensor, features: list[Tensor] | None = None) -> Tensor:
        r"""The raw network: ``log(1 + L)`` on the 16 x 32 lat-long grid, no input checks (the training path).

        Args:
            crops: sRGB crops in ``[0, 1]``, :math:`(B, 3, H, W)` (multiples of 16).
            features: the encoder's outputs for ``crops``, when the caller has them.

        Returns:
            :math:`(B, 3, 16, 32)` float32, non-negative.
        """
        if features is None:
            features = self.encoder(crops.to(self.head.out.weight.dtype))
        return self.head(features[-1])

    def latlong(self, crops: Tensor) -> Tensor:
        r"""The estimate on the network's own grid: linear lat-long lighting :math:`(B, 3, 16, 32)`, float32."""
        return torch.expm1(self.log_latlong(crops))

    def predict(self, crops: Tensor) -> LightingEstimate:
        dtype = self.head.out.weight.dtype
        scale = None
        if self.normalize_exposure:
            with torch.autocast(crops.device.type, enabled=False), trusted():  # forward() checked the crops
                crops, scale = normalize_exposure(crops.float())
        features = self.encoder(crops.to(dtype))
        z = self.log_latlong(crops, features)
        log_spread = None
        if self.spread is not None:
            log_spread = self.spread(features[-1].mean((2, 3))).float()[:, 0].clamp(*LOG_SPREAD_RANGE)
        with torch.autocast(z.device.type, enabled=False):
            mirror_ball = log_latlong_to_mirror_ball(z, LIGHTING_SIZE)
            if scale is not None:
                mirror_ball = mirror_ball * scale[:, None, None, None]
            log_mirror_ball = torch.log1p(mirror_ball)
        return LightingEstimate(
            mirror_ball=mirror_ball.to(dtype).contiguous(),
            valid=self.valid,
            log_mirror_ball=log_mirror_ball.to(dtype).contiguous(),
            log_energy_spread=None if log_spread is None else torch.exp(log_spread).to(dtype),
        )
