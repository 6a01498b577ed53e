"""Fingerprint of the outputs a user sees: the SHA-256 of what ``estimate_lighting`` and ``kornia-ilum estimate``
give for scikit-image's astronaut, under several settings.

Run: ``python benchmarks/output_fingerprint.py``

Prints one line per setting: the SHA-256 of the estimate's mirror ball, boxes and spread (their float32 bytes),
and of the CLI's ``.json`` and of the ``.exr``'s pixels (the file itself holds OpenImageIO's write time). A
refactor that must not change the outputs is checked by running this before and after it on the same machine
(as ``benchmarks/train_fingerprint.py`` does for training): the lines must be identical.
"""

from __future__ import annotations

import hashlib
import subprocess
import sys
import tempfile
from pathlib import Path

import skimage.data
import torch

from kornia_ilum import estimate_lighting
from kornia_ilum.io import read_hdr

#: The settings: name -> keyword arguments of ``estimate_lighting`` (all keyword, as every version takes them).
SETTINGS = {"defaults": {}, "haar, all faces": {"detector": "opencv", "faces": "all"},
            "fused, tta 2": {"faces": "fused", "tta": 2}, "sh": {"estimator": "sh"}}


def digest(*tensors: torch.Tensor | None) -> str:
    h = hashlib.sha256()
    for t in tensors:
        h.update(b"none" if t is None else t.detach().float().contiguous().numpy().tobytes())
    return h.hexdigest()[:16]


def main() -> None:
    photo = skimage.data.astronaut()
    for name, kw in SETTINGS.items():
        e = estimate_lighting(photo, **kw)
        print(f"api {name:16s} {digest(e.mirror_ball, e.boxes, e.log_energy_spread)}")
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([sys.executable, "-m", "kornia_ilum", "estimate", "-o", f"{tmp}/"], check=True,
                       capture_output=True)
        json = hashlib.sha256((Path(tmp) / "astronaut.json").read_bytes()).hexdigest()[:16]
        print(f"cli estimate      json {json}  exr pixels {digest(read_hdr(Path(tmp) / 'astronaut.exr'))}")


if __name__ == "__main__":
    main()
