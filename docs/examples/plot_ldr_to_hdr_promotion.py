r"""
Promote an LDR sphere photograph to HDR lighting
================================================

The paper records its ground truth with three reference spheres (mirror, matte silver, diffuse) filmed by a
phone: 8-bit, so the sun clips in the mirror ball. :func:`kornia_ilum.promotion.promote_spheres` recovers the
clipped energy from the two rougher spheres, which never clip, by non-negative least squares (LeGendre et al.
2020, Eq. 1-3).

Here the spheres are rendered from a procedural clear sky with a sun
(:class:`kornia_ilum_lab.synth.environments.SkySource`), exposed so that the sun clips, and encoded to 8 bits.
"""

import matplotlib.pyplot as plt
import torch

from kornia_ilum.color import gamma_encode, quantize
from kornia_ilum.render import render_spheres
from kornia_ilum.promotion import promote_spheres
from kornia_ilum_lab.synth.environments import SkySource

env = SkySource().sample(torch.Generator().manual_seed(3))
truth = env.mirror_ball[None]  # (1, 3, 32, 32), linear HDR with a sun
spheres = render_spheres(truth, size=32)
exposure = 0.18 / float(spheres["diffuse"].mean())  # the diffuse ball at mid-grey: the sun clips in the mirror
ldr = {k: quantize(gamma_encode((v * exposure).clamp(0, 1))) for k, v in spheres.items()}
result = promote_spheres(ldr["mirror"], ldr["diffuse"], ldr["matte_silver"])
print("clipped directions:", int(result.clipped.sum()))

# %%
# The energy that the clipped mirror lost comes back: compare the total radiance of the truth, the clipped
# mirror (divided by its reflectivity) and the promoted lighting.

naive = (ldr["mirror"] ** 2.2) / 0.827 / exposure
for name, x in (("truth", truth), ("clipped mirror", naive), ("promoted", result.lighting / exposure)):
    print(f"{name:15s} total radiance {float(x.sum()):9.1f}")


def show(x: torch.Tensor) -> torch.Tensor:
    return (x[0] / float(truth.mean()) / 4).clamp(0, 1).pow(1 / 2.2).permute(1, 2, 0)


fig, axes = plt.subplots(1, 4, figsize=(9, 2.6), layout="constrained")
for ax, (title, x) in zip(axes, (("8-bit mirror", ldr["mirror"] ** 2.2 / exposure), ("8-bit diffuse",
                                 ldr["diffuse"] ** 2.2 / exposure), ("promoted", result.lighting / exposure),
                                 ("truth", truth)), strict=True):
    ax.imshow(show(x))
    ax.set_title(title)
    ax.axis("off")
plt.show()
