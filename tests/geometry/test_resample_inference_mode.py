"""The resampling's cached constants, first built under torch.inference_mode(), serve a later call with autograd."""

from __future__ import annotations

import torch

from kornia_ilum.geometry import latlong_to_mirror_ball, mirror_ball_to_latlong


def test_constants_built_in_inference_mode_work_with_autograd() -> None:
    for size, mode in ((7, "area"), (9, "bilinear")):  # grid sizes no other test builds first
        with torch.inference_mode():
            latlong_to_mirror_ball(torch.rand(1, 3, size, 2 * size), 8, mode=mode)
            mirror_ball_to_latlong(torch.rand(1, 3, 8, 8), size)
        x = torch.rand(1, 3, size, 2 * size, requires_grad=True)
        latlong_to_mirror_ball(x, 8, mode=mode).sum().backward()
        y = torch.rand(1, 3, 8, 8, requires_grad=True)
        mirror_ball_to_latlong(y, size).sum().backward()
        assert x.grad is not None and y.grad is not None
