r"""
Estimate the lighting of a photograph
=====================================

:func:`kornia_ilum.estimate_lighting` finds the face, crops it as the paper does (a square of 1.25 times the
face box, 256 x 256) and runs the estimator. The result is a :class:`~kornia_ilum.estimators.LightingEstimate`:
a 32 x 32 mirror ball of linear HDR lighting in the units of the photograph (:doc:`/conventions`).

The photograph here is scikit-image's ``astronaut`` (NASA, public domain), the built-in sample of
``kornia-ilum estimate``.
"""

import matplotlib.pyplot as plt
import skimage.data
import torch

import kornia_ilum
from kornia_ilum.filters import soft_clip

image = torch.from_numpy(skimage.data.astronaut()).permute(2, 0, 1).float() / 255  # (3, H, W) sRGB
estimate = kornia_ilum.estimate_lighting(image)  # detector "opencv", estimator "ours"
print(estimate)

# %%
# What came out
# -------------
# The mirror ball is linear; for display we soft-clip it and apply a gamma. The reference spheres (diffuse,
# matte silver, mirror) lit by the estimate show what it means for a surface. The main light and the ambient
# SH (:meth:`~kornia_ilum.estimators.LightingEstimate.dominant_light`) are what a renderer or an AR framework
# asks for.

spheres = estimate.render_spheres(32)
light = estimate.dominant_light()
print("main light from", [round(v, 2) for v in light.direction[0].tolist()],
      "colour", [round(v, 2) for v in light.color[0].tolist()])


def show(x: torch.Tensor) -> torch.Tensor:
    return (soft_clip(x / x.amax().clamp(min=1e-6)) ** (1 / 2.2))[0].permute(1, 2, 0).clamp(0, 1)


x0, y0, x1, y1 = estimate.boxes[0].tolist()
fig, axes = plt.subplots(1, 5, figsize=(11, 2.6), layout="constrained", width_ratios=[1.6, 1, 1, 1, 1])
axes[0].imshow(image.permute(1, 2, 0))
axes[0].add_patch(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, color="yellow", lw=1.5))
axes[0].set_title("photo and face box")
axes[1].imshow(show(estimate.mirror_ball))
axes[1].set_title("lighting (mirror ball)")
for ax, name in zip(axes[2:], ("diffuse", "matte_silver", "mirror"), strict=True):
    ax.imshow(show(spheres[name]))
    ax.set_title(name.replace("_", " "))
for ax in axes:
    ax.axis("off")
plt.show()

# %%
# Writing it
# ----------
# ``estimate.save("light.exr")`` writes the mirror ball (``latlong_height=128`` for a lat-long map), and
# ``kornia-ilum estimate photo.jpg -o light.exr`` does all of the above from the command line, with the main
# light as JSON beside the ``.exr``.
