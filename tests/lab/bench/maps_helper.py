"""Three tiny real maps (two held out, one for training) for the bench's clips."""

from __future__ import annotations

import torch

from kornia_ilum.io import write_hdr


def three_maps(folder):
    folder.mkdir()
    for i, name in enumerate(("studio.exr", "forest.exr", "interior.exr")):  # eval, eval, train
        sky = torch.full((3, 16, 32), 0.2)
        sky[:, 3, 5 + 7 * i] = 50.0
        write_hdr(folder / name, sky)
    return folder
