r"""
Composite a virtual object with the estimated lighting
======================================================

The paper's own application: light a virtual object with the lighting estimated from the portrait, and
place it in the photograph. Because the estimate is in the units of the photograph (:doc:`/conventions`),
the render needs no exposure of its own: it is composited in linear values and encoded like the photo.

The estimate goes to Mitsuba 3 as a lat-long ``envmap`` (:func:`kornia_ilum.geometry.latlong_for_tool`
turns it into Mitsuba's convention; :doc:`/questions` gives Blender's, three.js's and Unity's). The scene is
built in the camera frame, so the object sees the light the face saw.
"""

import matplotlib.pyplot as plt
import numpy as np
import skimage.data
import torch

import kornia_ilum
from kornia_ilum.color import linear_to_srgb, srgb_to_linear
from kornia_ilum.geometry import latlong_for_tool
from kornia_ilum_lab.synth.lightstage.materials import import_mitsuba, select_mitsuba_variant

photo = torch.from_numpy(skimage.data.astronaut()).permute(2, 0, 1).float() / 255
estimate = kornia_ilum.estimate_lighting(photo)
latlong = latlong_for_tool(estimate.to_latlong(64), "mitsuba")[0]  # (3, 64, 128)

mi = import_mitsuba()
select_mitsuba_variant()
size = 128
scene = mi.load_dict({
    "type": "scene",
    "integrator": {"type": "path", "max_depth": 4, "hide_emitters": True},  # background: alpha 0
    "sensor": {
        "type": "orthographic",
        "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]),
        "film": {"type": "hdrfilm", "width": size, "height": size, "pixel_format": "rgba"},
        "sampler": {"type": "independent", "sample_count": 64},
    },
    "light": {"type": "envmap", "bitmap": mi.Bitmap(np.ascontiguousarray(latlong.permute(1, 2, 0).numpy()))},
    "glossy": {"type": "sphere", "radius": 0.8,
               "bsdf": {"type": "roughplastic", "alpha": 0.12,
                        "diffuse_reflectance": {"type": "rgb", "value": [0.55, 0.12, 0.08]}}},
})
render = torch.from_numpy(np.asarray(mi.render(scene, seed=0), dtype=np.float32).copy()).permute(2, 0, 1)
rgb, alpha = render[:3], render[3:].clamp(0, 1)

# %%
# Composite in linear values, in the photo's units
# ------------------------------------------------
# The object rests on the helmet at the lower right: ``over`` in linear values, then the
# sRGB curve of the photo.

linear = srgb_to_linear(photo)
top, left = 300, 330
patch = linear[:, top:top + size, left:left + size]
linear[:, top:top + size, left:left + size] = rgb + (1 - alpha) * patch
composite = linear_to_srgb(linear.clamp(0, 1))

fig, axes = plt.subplots(1, 2, figsize=(9, 4.6), layout="constrained")
axes[0].imshow(photo.permute(1, 2, 0))
axes[0].set_title("photograph")
axes[1].imshow(composite.permute(1, 2, 0))
axes[1].set_title("with a glossy sphere lit by the estimate")
for ax in axes:
    ax.axis("off")
plt.show()
