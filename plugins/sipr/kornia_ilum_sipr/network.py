r"""The SIPR U-Net (Sun et al. 2019), as reimplemented by its first author's group (``ken2576/nelf``,
``network/u_net.py``), rewritten here.

Encoder (:class:`Encoder`): ten :class:`ConvNormAct` blocks (convolution, GroupNorm of ``min(32, C)`` groups,
PReLU) with output depths 32, 64, 64, 128, 128, 256, 256, 512, 512, 512. The first block is 7 x 7 and makes
29 channels, which are concatenated with the RGB input (32 in all); blocks 2, 4, 6 and 8 have stride 2, so
a 256 x 256 crop becomes a 16 x 16 x 512 bottleneck. Every block's output is kept as a skip connection.

Lighting head (:class:`LightingHead`): at every bottleneck pixel, a 3 x 3 :class:`ConvNormAct` (512) and a
3 x 3 convolution to ``4 N`` channels, ``N = 16 x 32`` lat-long texels: per texel three log-lighting values
and one confidence, all through softplus. The estimate is the confidence-weighted mean over the bottleneck
pixels. The lighting values are ``log(1 + L)`` (natural log, so never negative: softplus keeps ``L >= 0``).

Relighting decoder (:class:`RelightingDecoder`, training only): the target lighting's ``log(1 + L)`` (16 x 32 x
3 = 1536 values) goes through two 1 x 1 :class:`ConvNormAct` (512, 256), is tiled over the bottleneck, and
ten 3 x 3 blocks decode it, each after concatenating the matching encoder output (upsampling by 2 before
blocks 3, 5, 7 and 9), down to a sigmoid RGB image of the crop's size.

Where this differs from ``nelf`` (which hard-codes batch 1 and an 8 x 16 lighting):

- any batch size, and 16 x 32 lighting (Sun et al.'s own size, so the mirror sphere has detail to show);
- the lighting head's last convolution and the decoder's last one have no GroupNorm: normalising the
  ``4 N`` outputs over groups of texels would fight their HDR range, and normalising the output image per
  channel over space would fix its brightness;
- the lighting is ``log(1 + L)`` throughout (``nelf`` predicts linear lighting through softplus and feeds
  the target lighting linear), which keeps the 1 x 1 encoder's input in a sane range under a sun.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from kornia_ilum.geometry import latlong_to_mirror_ball, mirror_ball_to_latlong

__all__ = [
    "ENCODER_DEPTHS",
    "LIGHTING_SHAPE",
    "ConvNormAct",
    "Encoder",
    "LightingHead",
    "RelightingDecoder",
    "log_latlong_target",
    "log_latlong_to_mirror_ball",
]

#: Output depths of the encoder's blocks (the first is 29 convolution channels + the 3 input channels).
ENCODER_DEPTHS: tuple[int, ...] = (32, 64, 64, 128, 128, 256, 256, 512, 512, 512)
#: Blocks of stride 2 (0-based).
_STRIDED = (1, 3, 5, 7)
#: The lat-long lighting of the head: 16 rows, 32 columns.
LIGHTING_SHAPE: tuple[int, int] = (16, 32)
#: Depth of the tiled target-lighting code.
_LIGHT_CODE = 256


def log_latlong_target(mirror_ball: Tensor) -> Tensor:
    r"""``log(1 + L)`` of a ground-truth mirror ball on SIPR's 16 x 32 lat-long grid (area averaging).

    Examples:
        >>> from kornia_ilum.geometry import mirror_ball_valid
        >>> z = log_latlong_target(torch.ones(1, 3, 32, 32) * mirror_ball_valid(32))
        >>> tuple(z.shape), round(z.mean().item(), 3)  # log(2)
        ((1, 3, 16, 32), 0.693)
    """
    return torch.log1p(mirror_ball_to_latlong(mirror_ball.float(), LIGHTING_SHAPE[0], mode="area"))


def log_latlong_to_mirror_ball(log_latlong: Tensor, size: int = 32) -> Tensor:
    r"""The inverse way: the lighting of a ``log(1 + L)`` lat-long map on the ``size`` mirror ball of
    docs/conventions.rst, float32, by area averaging (``sum(L * omega)`` per channel kept).

    Examples:
        >>> ball = log_latlong_to_mirror_ball(torch.full((1, 3, 16, 32), math.log(2.0)))
        >>> tuple(ball.shape), round(ball.max().item(), 3)
        ((1, 3, 32, 32), 1.0)
    """
    return latlong_to_mirror_ball(torch.expm1(log_latlong.float()), size, mode="area")


class ConvNormAct(nn.Sequential):
    """Convolution (``same`` padding), GroupNorm of ``min(32, out)`` groups, then PReLU (one slope per channel).

    Examples:
        >>> ConvNormAct(3, 8, 3, stride=2)(torch.rand(1, 3, 16, 16)).shape
        torch.Size([1, 8, 8, 8])
    """

    def __init__(self, depth_in: int, depth_out: int, kernel: int, stride: int = 1) -> None:
        super().__init__(
            nn.Conv2d(depth_in, depth_out, kernel, stride=stride, padding=(kernel - 1) // 2),
            nn.GroupNorm(min(32, depth_out), depth_out),
            nn.PReLU(depth_out),
        )


class Encoder(nn.Module):
    r"""The U-Net encoder: crops -> the ten blocks' outputs (the last is the bottleneck).

    Shape:
        - Input: :math:`(B, 3, H, W)`, ``H`` and ``W`` multiples of 16
        - Output: a list of ten tensors, :math:`(B, 32, H, W)` first, :math:`(B, 512, H/16, W/16)` last

    Examples:
        >>> [tuple(f.shape[1:]) for f in Encoder()(torch.rand(1, 3, 32, 32))][::3]
        [(32, 32, 32), (128, 8, 8), (256, 4, 4), (512, 2, 2)]
    """

    def __init__(self) -> None:
        super().__init__()
        blocks, depth_in = [], 3
        for k, depth in enumerate(ENCODER_DEPTHS):
            out = depth - 3 if k == 0 else depth  # block 0's output joins the input
            blocks.append(ConvNormAct(depth_in, out, 7 if k == 0 else 3, 2 if k in _STRIDED else 1))
            depth_in = depth
        self.blocks = nn.ModuleList(blocks)

    def forward(self, crops: Tensor) -> list[Tensor]:
        features = []
        x = crops
        for k, block in enumerate(self.blocks):
            x = torch.cat([x, block(x)], 1) if k == 0 else block(x)
            features.append(x)
        return features


class LightingHead(nn.Module):
    r"""Bottleneck -> lat-long ``log(1 + L)``: the confidence-weighted mean of every pixel's prediction.

    Args:
        shape: the lat-long lighting's ``(rows, columns)``.

    Shape:
        - Input: :math:`(B, 512, h, w)`
        - Output: :math:`(B, 3, rows, columns)`, non-negative, float32

    Examples:
        >>> head = LightingHead((2, 4))
        >>> head(torch.rand(3, 512, 4, 4)).shape
        torch.Size([3, 3, 2, 4])
    """

    def __init__(self, shape: tuple[int, int] = LIGHTING_SHAPE) -> None:
        super().__init__()
        self.shape = tuple(shape)
        texels = self.shape[0] * self.shape[1]
        self.hidden = ConvNormAct(ENCODER_DEPTHS[-1], ENCODER_DEPTHS[-1], 3)
        self.out = nn.Conv2d(ENCODER_DEPTHS[-1], 4 * texels, 3, padding=1)

    def forward(self, bottleneck: Tensor) -> Tensor:
        b = bottleneck.shape[0]
        rows, cols = self.shape
        y = F.softplus(self.out(self.hidden(bottleneck)).float()).reshape(b, 4, rows, cols, -1)
        light, confidence = y[:, :3], y[:, 3:] + 1e-6  # (B, 3, rows, cols, P), (B, 1, rows, cols, P)
        return (light * confidence).sum(-1) / confidence.sum(-1)


class RelightingDecoder(nn.Module):
    r"""Encoder outputs + target ``log(1 + L)`` lighting -> the relit crop (sigmoid RGB), training only.

    Shape:
        - Input: the :class:`Encoder`'s ten outputs, and the target lighting :math:`(B, 3, 16, 32)`
        - Output: :math:`(B, 3, H, W)` in ``[0, 1]``

    Examples:
        >>> enc, dec = Encoder(), RelightingDecoder((2, 4))
        >>> dec(enc(torch.rand(2, 3, 32, 32)), torch.rand(2, 3, 2, 4)).shape
        torch.Size([2, 3, 32, 32])
    """

    def __init__(self, shape: tuple[int, int] = LIGHTING_SHAPE) -> None:
        super().__init__()
        texels = shape[0] * shape[1]
        self.light = nn.Sequential(ConvNormAct(3 * texels, 512, 1), ConvNormAct(512, _LIGHT_CODE, 1))
        blocks, depth_in = [], _LIGHT_CODE
        outs = (*ENCODER_DEPTHS[-2::-1], 3)  # 512, 512, 256, ..., 32, then RGB
        for k, (skip, depth) in enumerate(zip(ENCODER_DEPTHS[::-1], outs, strict=True)):
            if k == len(outs) - 1:
                blocks.append(nn.Conv2d(depth_in + skip, depth, 3, padding=1))
            else:
                blocks.append(ConvNormAct(depth_in + skip, depth, 3))
            depth_in = depth
        self.blocks = nn.ModuleList(blocks)

    def forward(self, features: list[Tensor], target_log_lighting: Tensor) -> Tensor:
        bottleneck = features[-1]
        code = self.light(target_log_lighting.to(bottleneck.dtype).flatten(1)[..., None, None])
        x = code.expand(-1, -1, *bottleneck.shape[-2:])
        for k, block in enumerate(self.blocks):
            x = torch.cat([x, features[-1 - k]], 1)
            if k in (2, 4, 6, 8):
                x = F.interpolate(x, scale_factor=2, mode="bilinear", align_corners=False)
            x = block(x)
        return torch.sigmoid(x)
