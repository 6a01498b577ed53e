r"""
Relight a light-stage subject
=============================

The virtual light stage renders each subject once per light of a 32 x 32 mirror ball (one light at a time,
OLAT) into a reflectance field ``R``; any lighting ``L`` then relights the subject exactly, as a product
``I = R L`` (:func:`kornia_ilum.render.relight`; Debevec et al. 2000). Training relights every field with
thousands of environments this way.

This builds one view of one synthetic subject, the project's embedded ``mannequin`` (no data needed; the
training subjects are MakeHuman heads, ``kornia-ilum synth subjects --family makehuman``), with Mitsuba 3, and
relights it with three procedural environments: a clear sky, a room, and a studio's portrait lights.
"""

import tempfile

import matplotlib.pyplot as plt
import torch

from kornia_ilum.color import linear_to_srgb
from kornia_ilum_lab.synth.environments import IndoorSource, PortraitLightSource, SkySource
from kornia_ilum_lab.synth.lightstage import Auto, SampledViews, Workers, build_cache
from kornia_ilum_lab.synth.lightstage.portraits import load_fields, relight_portraits

with tempfile.TemporaryDirectory() as cache:
    build_cache("mannequin", [1], out_dir=cache, renderer=Auto(spp=4), views=SampledViews(1, size=96),
                workers=Workers(processes=1), progress=False)
    field = load_fields(cache)[0]
print("reflectance field:", tuple(field.field.shape), field.field.dtype, "(channels, pixels, lights)")

# %%
# One product per batch of lightings
# ----------------------------------
# :func:`~kornia_ilum_lab.synth.lightstage.portraits.relight_portraits` takes mirror balls in the camera frame
# and returns the premultiplied subject and its matte.

generator = torch.Generator().manual_seed(0)
environments = [source.sample(generator) for source in (SkySource(), IndoorSource(), PortraitLightSource())]
balls = torch.stack([env.mirror_ball for env in environments])
image, alpha = relight_portraits(field, balls)

fig, axes = plt.subplots(2, 3, figsize=(8, 5.4), layout="constrained")
for column, env in enumerate(environments):
    shown = image[column] / image[column].amax().clamp(min=1e-6) * 1.5  # exposed per image for display
    axes[0, column].imshow(linear_to_srgb(shown.clamp(0, 1)).permute(1, 2, 0))
    axes[0, column].set_title(env.source)
    ball = env.mirror_ball / env.mirror_ball.mean() / 4
    axes[1, column].imshow(linear_to_srgb(ball.clamp(0, 1)).permute(1, 2, 0))
for ax in axes.flat:
    ax.axis("off")
plt.show()
