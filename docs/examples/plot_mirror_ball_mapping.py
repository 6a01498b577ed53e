r"""
The mirror-ball and lat-long mappings
=====================================

Lighting in kornia_ilum lives on two grids (see :doc:`/conventions`): the ``S x S`` mirror ball
(Lambert azimuthal equal-area, the paper's format) and the ``H x 2H`` lat-long (equirectangular)
map. Both use one frame: **+X right, +Y up, +Z toward the camera**, and a pixel for direction ``d``
holds the light arriving *from* ``d``.

We colour every pixel by its direction, ``colour = (d + 1) / 2`` (so +X is reddish, +Y greenish,
+Z bluish), and mark where the six axis directions land, using the library's own inverse maps
:func:`kornia_ilum.geometry.direction_to_mirror_ball` and
:func:`kornia_ilum.geometry.direction_to_latlong`.
"""

import math

import matplotlib.pyplot as plt
import torch

import kornia_ilum.geometry as kg

# %%
# Direction maps
# --------------
# :func:`~kornia_ilum.geometry.mirror_ball_directions` gives the direction of every pixel centre and
# the mask of pixels on the ball; :func:`~kornia_ilum.geometry.latlong_directions` does the same for
# a lat-long map.

S, H = 128, 128
d_ball, valid = kg.mirror_ball_directions(S)
d_ll = kg.latlong_directions(H)

ball_rgb = torch.where(valid[..., None], (d_ball + 1) / 2, torch.ones(3))
ll_rgb = (d_ll + 1) / 2

# %%
# Where the axes land
# -------------------
# The centre of the ball is +Z (behind the camera) and its whole rim is -Z (behind the subject);
# +X, +Y, -X, -Y sit at radius ``sqrt(1/2)``. In the lat-long map the centre column looks along -Z,
# +X is three quarters of the way across, +Z is split between the left and right edges, and the top
# and bottom rows are +Y and -Y.

axes = {
    "+X": (1.0, 0.0, 0.0),
    "-X": (-1.0, 0.0, 0.0),
    "+Y": (0.0, 1.0, 0.0),
    "-Y": (0.0, -1.0, 0.0),
    "+Z": (0.0, 0.0, 1.0),
    "-Z": (0.0, 0.0, -1.0),
}
dirs = torch.tensor(list(axes.values()))
ball_px = kg.uv_to_pixel(kg.direction_to_mirror_ball(dirs), S)  # (col, row), centres are integers
phi, el = kg.direction_to_latlong(dirs)
ll_px = kg.angles_to_latlong_pixel(phi, el, H)

fig, (ax_ball, ax_ll) = plt.subplots(1, 2, figsize=(9.0, 3.6), width_ratios=[1, 2], layout="constrained")
style = {"color": "black", "fontsize": 10, "fontweight": "bold", "ha": "center", "va": "center"}
box = {"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.8}

ax_ball.imshow(ball_rgb.numpy(), extent=(-0.5, S - 0.5, S - 0.5, -0.5))
rim = plt.Circle(((S - 1) / 2, (S - 1) / 2), S / 2, fill=False, ls="--", lw=1.2, color="black")
ax_ball.add_patch(rim)
for (name, _), (col, row) in zip(axes.items(), ball_px.tolist()):
    if name == "-Z":  # the whole rim
        c = (S - 1) / 2
        rim_point = (c + S / 2 * math.cos(math.pi / 4), c + S / 2 * math.sin(math.pi / 4))
        ax_ball.annotate(
            "-Z (whole rim)",
            rim_point,
            xytext=(c + S * 0.3, c + S * 0.2),
            arrowprops={"arrowstyle": "->"},
            bbox=box,
            **style,
        )
        continue
    ax_ball.plot(col, row, "o", ms=5, mfc="white", mec="black")
    ax_ball.text(col, row - S * 0.07, name, bbox=box, **style)
ax_ball.set_title('mirror ball ("mirror_ball"), S x S')
ax_ball.set_xlabel("u  (+X right)")
ax_ball.set_ylabel("v  (+Y up)")
ax_ball.set_xticks([0, (S - 1) / 2, S - 1], ["-1", "0", "1"])
ax_ball.set_yticks([0, (S - 1) / 2, S - 1], ["1", "0", "-1"])

W = 2 * H
ax_ll.imshow(ll_rgb.numpy(), extent=(-0.5, W - 0.5, H - 0.5, -0.5))
for (name, _), (col, row) in zip(axes.items(), ll_px.tolist()):
    cols = [col] if name != "+Z" else [-0.5, W - 0.5]  # +Z is split between both edges
    for c in cols:
        c_text = min(max(c, W * 0.03), W * 0.97)
        row_text = min(max(row, H * 0.06), H * 0.94)
        if name in ("+Y", "-Y"):  # the whole top / bottom row
            name_shown = f"{name} (whole {'top' if name == '+Y' else 'bottom'} row)"
            c_text = W / 2 - 0.5
        else:
            name_shown = name
            ax_ll.plot(c, row, "o", ms=5, mfc="white", mec="black", clip_on=False)
            row_text = row - H * 0.08
        ax_ll.text(c_text, row_text, name_shown, bbox=box, **style)
ax_ll.set_title('lat-long ("latlong"), H x 2H')
ax_ll.set_xlabel("azimuth phi")
ax_ll.set_ylabel("elevation el")
ax_ll.set_xticks(
    [-0.5, W / 4 - 0.5, W / 2 - 0.5, 3 * W / 4 - 0.5, W - 0.5], ["-pi", "-pi/2", "0", "pi/2", "pi"]
)
ax_ll.set_yticks([-0.5, H / 2 - 0.5, H - 0.5], ["pi/2", "0", "-pi/2"])
fig.suptitle(
    "colour = (d + 1) / 2: light arriving from d  (+X right, +Y up, +Z toward the camera)", fontsize=10
)

# %%
# Checks
# ------
# The markers come from the inverse maps; going forward again returns the axes.

back_ball, _ = kg.mirror_ball_to_direction(kg.pixel_to_uv(ball_px, S))
back_ll = kg.latlong_to_direction(phi, el)
print("mirror ball round trip error:", (back_ball - dirs).abs().max().item())
print("lat-long round trip error:   ", (back_ll - dirs).abs().max().item())
print("solid angle of the ball:     ", kg.mirror_ball_solid_angles(32).sum().item(), "~ 4 pi =", 4 * math.pi)
