r"""``ours``: the lighting network of LeGendre et al. 2020, "Learning Illumination from Diverse Portraits".

An encoder-decoder from a 256 x 256 sRGB face crop to a 32 x 32 log-HDR mirror ball (docs/conventions.rst,
"Mirror ball"). It ships trained weights (``weights/ours.safetensors``, trained by ``kornia-ilum train`` on
the light stage; its model card is ``weights/MODEL_CARD.md``): ``create_estimator("ours")`` loads them
(SHA-256 checked, safetensors), ``create_estimator("ours", pretrained=False)`` gives the untrained network.

Architecture (9,219,779 parameters at the default ``latent_dim=1024``, the paper's network size of
about 9.2 M). From the paper's description:

- input: the sRGB crop, shifted to ``[-0.5, 0.5]``; our addition (``normalize_exposure=True``, the default):
  the crop is first re-exposed so that its centre-weighted mean luminance is 0.18
  (:func:`kornia_ilum.color.normalize_exposure`) and the estimate is scaled back by the same factor, so the
  lighting follows the photo's exposure by design, not by what the training data happened to cover;
- encoder: five 3 x 3 convolutions of depths 16, 32, 64, 128, 256, each followed by blur-pooling
  (Zhang 2019, "Making convolutional networks shift-invariant again";
  :class:`kornia_ilum.filters.BlurPool2D`), 256 -> 8 pixels; then one 8 x 8 convolution of depth 256
  and a fully-connected layer to the 1024-d bottleneck (a latent code of the log-HDR lighting);
- decoder: three 3 x 3 convolutions of depths 64, 32, 16, each followed by bilinear 2x upsampling,
  4 -> 32 pixels, and a final 3 x 3 convolution to the 3-channel 32 x 32 log-HDR mirror ball.

Activations: ReLU after every convolution and after the latent-to-feature layer, as the paper says ("We
use the ReLU activation function for the generator network"). Our choices, where the paper says nothing:
no normalisation layers; "same" zero padding for the 3 x 3 convolutions and a
valid 8 x 8 convolution (8 x 8 -> 1 x 1); blur-pool kernel 3 (binomial ``[1, 2, 1]``, Kornia's default);
the bottleneck is linear and a second fully-connected layer maps it to the decoder's 4 x 4 x 256 input;
PyTorch's default initialisation. The 9.2 M count depends on these: the two fully-connected layers and
the 8 x 8 convolution hold 94 % of the parameters.

Output (the units of docs/conventions.rst): the head predicts ``y = log L`` (natural log of linear radiance)
per pixel. The estimate holds ``mirror_ball = exp(y)`` and ``log_mirror_ball = softplus(y) = log(1 + L)``,
both 0 outside the ball, so ``mirror_ball == expm1(log_mirror_ball)`` and the log form is non-negative, finite
and well-conditioned for losses in log space.

The spread of the strength (``spread_head=True``, our addition): one linear layer from the bottleneck to
``log b``, the scale of a Laplace distribution of the true lighting's log energy around the estimate's
(:attr:`~kornia_ilum.estimators.LightingEstimate.log_energy_spread`), trained by its negative log-likelihood
(``kornia-ilum train --lambda-nll``, docs/training.rst); the shipped head was then refitted at export on fresh
training portraits, the rest frozen (``--fit-spread``). It changes nothing else: the mirror ball is the
decoder's. A weight file that has it turns it on when loaded.

Training (:mod:`kornia_ilum_lab.train`) adds side branches that turn the decoder's 4, 8 and 16 px feature maps
(:meth:`OursEstimator.decode`) into 3-channel log lighting for the multi-scale losses; they belong to the
training model, never run at inference and are not in the shipped weights.
"""

from __future__ import annotations

import contextlib
from typing import Any, NamedTuple

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from kornia_ilum.color import normalize_exposure
from kornia_ilum.core.check import check_positive_int, trusted
from kornia_ilum.core.dtypes import saturating_cast
from kornia_ilum.estimators.base import (
    EstimatorInfo,
    LightingEstimate,
    LightingEstimator,
    WeightFile,
    adopt_spread_head,
)
from kornia_ilum.filters import BlurPool2D
from kornia_ilum.geometry import mirror_ball_valid

__all__ = [
    "DECODER_DEPTHS",
    "ENCODER_DEPTHS",
    "LIGHTING_SIZE",
    "LOG_SPREAD_RANGE",
    "Decoded",
    "OursEstimator",
    "build_encoder",
]

#: Depths of the five encoder convolutions (each followed by blur-pooling).
ENCODER_DEPTHS: tuple[int, ...] = (16, 32, 64, 128, 256)
#: Depths of the three decoder convolutions (each followed by 2x bilinear upsampling).
DECODER_DEPTHS: tuple[int, ...] = (64, 32, 16)
#: Side of the predicted mirror ball.
LIGHTING_SIZE = 32
#: ``log b`` of the spread head is clamped to this range (``b`` from 0.007 to 20 in natural log units: from
#: a strength known to 0.7 % to one not known at all), in training and inference alike.
LOG_SPREAD_RANGE: tuple[float, float] = (-5.0, 3.0)

_INPUT_SIZE = 256
_BOTTLENECK_SIDE = LIGHTING_SIZE >> len(DECODER_DEPTHS)  # 4
_BOTTLENECK_DEPTH = ENCODER_DEPTHS[-1]  # 256
_ENCODED_SIDE = _INPUT_SIZE >> len(ENCODER_DEPTHS)  # 8

PAPER = (
    "C. LeGendre, W.-C. Ma, R. Pandey, S. Fanello, C. Rhemann, J. Dourgarian, J. Busch, P. Debevec: "
    '"Learning Illumination from Diverse Portraits", SIGGRAPH Asia 2020 Technical Communications, '
    "doi:10.1145/3410700.3425432"
)


def _no_autocast(device: torch.device) -> contextlib.AbstractContextManager:
    """Autocast off on ``device`` (nothing to turn off on ``meta``, where ``torch.autocast`` refuses)."""
    return contextlib.nullcontext() if device.type == "meta" else torch.autocast(device.type, enabled=False)


def build_encoder(latent_dim: int = 1024) -> tuple[nn.Sequential, nn.Linear]:
    r"""The paper's encoder, ``(encoder, to_latent)``: five 3 x 3 conv + ReLU + blur-pool stages, the 8 x 8
    convolution, then the fully-connected layer to the ``latent_dim`` bottleneck (also used by plugins that
    share the encoder, such as ``sh``).

    Args:
        latent_dim: size of the bottleneck, the output of ``to_latent`` (1024 in the paper).

    Returns:
        ``(encoder, to_latent)``: the convolutional stages, ending in a flatten to 256 features, and the
        fully-connected layer from them to the bottleneck; both untrained (PyTorch's default initialisation).

    Shape:
        - Input of ``encoder``: :math:`(B, 3, 256, 256)`
        - Output of ``encoder``: :math:`(B, 256)`; of ``to_latent``: :math:`(B, latent\_dim)`

    Examples:
        >>> encoder, to_latent = build_encoder(64)
        >>> tuple(to_latent(encoder(torch.rand(1, 3, 256, 256))).shape)
        (1, 64)
    """
    check_positive_int(latent_dim, "latent_dim")
    layers: list[nn.Module] = []
    depth_in = 3
    for depth in ENCODER_DEPTHS:
        layers += [nn.Conv2d(depth_in, depth, 3, padding=1), nn.ReLU(), BlurPool2D(3, stride=2)]
        depth_in = depth
    layers += [nn.Conv2d(depth_in, _BOTTLENECK_DEPTH, _ENCODED_SIDE), nn.ReLU(), nn.Flatten(1)]
    return nn.Sequential(*layers), nn.Linear(_BOTTLENECK_DEPTH, latent_dim)


class Decoded(NamedTuple):
    """What :meth:`OursEstimator.decode` returns (see there)."""

    log_radiance: Tensor
    features: list[Tensor]
    log_scale: Tensor
    log_spread: Tensor | None
    latent: Tensor


class OursEstimator(LightingEstimator):
    r"""LeGendre et al. 2020's lighting network: face crop -> 32 x 32 log-HDR mirror ball.

    See the module docstring for the architecture (what follows the paper, what is our choice).

    Args:
        latent_dim: size of the fully-connected bottleneck (1024 in the paper).
        normalize_exposure: re-expose each crop to a centre-weighted mean luminance of 0.18 before the network
            and scale the estimate back (:func:`~kornia_ilum.color.normalize_exposure`), so the estimate scales
            exactly with the photo's exposure wherever nothing clips; ``False`` is the paper's network as is.
            The choice is saved with the weights (the buffer ``exposure_normalized``) and loading a state dict
            sets it; a file without that buffer is the paper's network (``False``).
        spread_head: add the spread head (module docstring): the estimate then has ``log_energy_spread``. A
            state dict that holds the head's weights adds it when loaded; one without them leaves a model's
            head as it is (a fine-tune that starts from a file which predates the head).

    Returns:
        (from ``forward``) a :class:`~kornia_ilum.estimators.LightingEstimate` with ``mirror_ball``,
        ``log_mirror_ball`` (``log(1 + L)``) and ``valid``, and ``log_energy_spread`` with the spread head;
        ``sh`` is ``None``.

    Shape:
        - Input: :math:`(B, 3, 256, 256)`, sRGB in ``[0, 1]``
        - Output: ``mirror_ball``, ``log_mirror_ball``: :math:`(B, 3, 32, 32)`; ``valid``: :math:`(32, 32)`

    Convention:
        docs/conventions.rst, "Mirror ball" and "Units of lighting": linear radiance in the units of the
        input image, 0 outside the ball. The outputs have the dtype of the module's parameters, also under
        :func:`torch.autocast` (the log-to-linear step runs in float32 outside autocast, then is cast);
        any memory format (``channels_last``) is accepted, the outputs are contiguous. Crops are cast to
        the parameters' dtype.

    Examples:
        >>> net = OursEstimator()
        >>> sum(p.numel() for p in net.parameters())
        9219779
        >>> est = net(torch.rand(2, 3, 256, 256))
        >>> tuple(est.mirror_ball.shape), est.sh is None
        ((2, 3, 32, 32), True)
        >>> torch.allclose(est.mirror_ball, torch.expm1(est.log_mirror_ball), rtol=1e-5)
        True
        >>> OursEstimator(spread_head=True)(torch.rand(2, 3, 256, 256)).log_energy_spread.shape
        torch.Size([2])
    """

    info = EstimatorInfo(
        name="ours",
        description="LeGendre et al. 2020's encoder-decoder (blur-pool encoder, 1024-d bottleneck): "
        "256 x 256 face crop -> 32 x 32 log-HDR mirror ball",
        paper=PAPER,
        input_size=_INPUT_SIZE,
        weights=(
            WeightFile(
                "ours.safetensors", "04b939680a8f422b179ce0d5375590e7dadc02c7127062d80006575df1c36b6d"
            ),
        ),
        install_hint="the weights ship inside kornia_ilum (kornia_ilum/estimators/weights/); reinstall it",
    )

    def __init__(self, latent_dim: int = 1024, normalize_exposure: bool = True, spread_head: bool = False) -> None:
        super().__init__()
        check_positive_int(latent_dim, "latent_dim")
        self.latent_dim = latent_dim
        self.normalize_exposure = bool(normalize_exposure)
        # saved with the weights, so a file says how it was trained (files without it predate the option: off)
        self.register_buffer("exposure_normalized", torch.tensor(float(self.normalize_exposure)))
        self.encoder, self.to_latent = build_encoder(latent_dim)
        self.from_latent = nn.Sequential(
            nn.Linear(latent_dim, _BOTTLENECK_DEPTH * _BOTTLENECK_SIDE**2), nn.ReLU()
        )
        blocks = []
        depth_in = _BOTTLENECK_DEPTH
        for depth in DECODER_DEPTHS:
            blocks.append(nn.Sequential(nn.Conv2d(depth_in, depth, 3, padding=1), nn.ReLU()))
            depth_in = depth
        self.decoder = nn.ModuleList(blocks)
        self.upsample = nn.Upsample(scale_factor=2, mode="bilinear", align_corners=False)
        self.head = nn.Conv2d(depth_in, 3, 3, padding=1)
        self.spread: nn.Linear | None = nn.Linear(latent_dim, 1) if spread_head else None
        self.register_buffer("valid", mirror_ball_valid(LIGHTING_SIZE), persistent=False)

    def _load_from_state_dict(self, state_dict: dict[str, Any], prefix: str, *args: Any) -> None:
        key = prefix + "exposure_normalized"
        if key not in state_dict:  # a weight file of the paper's network, written before the option existed
            state_dict[key] = torch.tensor(0.0)
        self.normalize_exposure = bool(state_dict[key] > 0.5)
        adopt_spread_head(self, state_dict, prefix, self.latent_dim)
        super()._load_from_state_dict(state_dict, prefix, *args)

    def decode(self, crops: Tensor) -> Decoded:
        r"""The raw network: natural-log radiance at 32 px, the decoder's feature maps at 4, 8, 16 px, the log
        of the exposure factor and the spread head's ``log b``.

        No input checks, no masking: this is the training path (:mod:`kornia_ilum_lab.train`), whose side
        branches read the feature maps (and add ``log_scale`` to their log radiance). Inference goes through
        ``forward``.

        Args:
            crops: sRGB crops in ``[0, 1]``, :math:`(B, 3, 256, 256)`.

        Returns:
            a :class:`Decoded` ``(log_radiance, features, log_scale, log_spread, latent)``: :math:`(B, 3, 32,
            32)` in the units of ``crops``, the decoder's activations :math:`(B, 64, 4, 4)`, :math:`(B, 32, 8,
            8)`, :math:`(B, 16, 16, 16)` (before each upsampling), :math:`(B, 1, 1, 1)`: ``log(scale)`` of
            :func:`~kornia_ilum.color.normalize_exposure` (0 without ``normalize_exposure``), already added to
            ``log_radiance``, :math:`(B,)` ``log b`` clamped to :data:`LOG_SPREAD_RANGE` (``None`` without
            the spread head), and the bottleneck :math:`(B, latent\_dim)`. ``log_radiance``, ``log_scale`` and
            ``log_spread`` are float32 (float64 for a float64 model), also under autocast.
        """
        dtype = self.head.weight.dtype
        work = torch.promote_types(dtype, torch.float32)  # the exposure and its log: never in bfloat16
        with _no_autocast(crops.device):
            if self.normalize_exposure:
                with trusted():  # the raw network: forward() checked the crops once, where they entered
                    crops, scale = normalize_exposure(crops.to(work))
                log_scale = torch.log(scale)[:, None, None, None]
            else:
                log_scale = crops.new_zeros(crops.shape[0], 1, 1, 1, dtype=work)
        with trusted():  # the layers' own checks would scan every activation; the crops were checked
            latent = self.to_latent(self.encoder(crops.to(dtype) - 0.5))
        x = self.from_latent(latent).reshape(-1, _BOTTLENECK_DEPTH, _BOTTLENECK_SIDE, _BOTTLENECK_SIDE)
        features = []
        for block in self.decoder:
            x = block(x)
            features.append(x)
            x = self.upsample(x)
        log_radiance = self.head(x)
        log_spread = None if self.spread is None else self.spread(latent)[:, 0]
        with _no_autocast(log_radiance.device):
            if log_spread is not None:
                log_spread = log_spread.to(work).clamp(*LOG_SPREAD_RANGE)
            return Decoded(log_radiance.to(work) + log_scale, features, log_scale, log_spread, latent)

    def predict(self, crops: Tensor) -> LightingEstimate:
        dtype = self.head.weight.dtype
        log_radiance, _, _, log_spread, _ = self.decode(crops)
        with _no_autocast(log_radiance.device):
            y = log_radiance.float()
            mirror_ball = torch.where(self.valid, torch.exp(y), 0.0)
            log_mirror_ball = torch.where(self.valid, F.softplus(y), 0.0)
        return LightingEstimate(  # a half-precision model saturates at its dtype's largest finite value
            mirror_ball=saturating_cast(mirror_ball, dtype).contiguous(),
            valid=self.valid,
            log_mirror_ball=log_mirror_ball.to(dtype).contiguous(),
            log_energy_spread=None if log_spread is None else saturating_cast(torch.exp(log_spread), dtype),
        )
