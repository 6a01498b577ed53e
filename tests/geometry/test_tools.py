"""kornia_ilum.geometry.tools: a lat-long map handed to another tool lights a scene as the library says it does.

Mitsuba 3 renders it here: a diffuse sphere lit by a test map (a red light from +X, a green one from +Y, a
blue one from +Z, the camera's side) through ``latlong_for_tool(..., "mitsuba")`` matches the library's own
diffuse sphere (:func:`kornia_ilum.render.render_spheres`), and the map as it is on disk does not.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.geometry import TOOLS, latlong_for_tool, latlong_to_mirror_ball, orientation_map
from kornia_ilum.render import render_spheres


def _mitsuba_diffuse(latlong: torch.Tensor, size: int = 32, spp: int = 256) -> torch.Tensor:
    """Mitsuba's render of a sphere of albedo 0.8 at the origin, seen orthographically along -Z from +Z, under
    ``latlong`` ``(1, 3, H, 2H)`` as an ``envmap`` emitter with Mitsuba's defaults: ``(1, 3, S, S)``."""
    from kornia_ilum_lab.synth.lightstage.materials import import_mitsuba, select_mitsuba_variant  # lazy: Mitsuba

    mi = import_mitsuba()
    select_mitsuba_variant()
    bitmap = mi.Bitmap(np.ascontiguousarray(latlong[0].permute(1, 2, 0).numpy().astype(np.float32)))
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "direct"},
        "sensor": {
            "type": "orthographic",
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "light": {"type": "envmap", "bitmap": bitmap},
        "ball": {"type": "sphere", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.8}}},
    })
    image = np.asarray(mi.render(scene, seed=0), dtype=np.float32)[..., :3]
    return torch.from_numpy(image.copy()).permute(2, 0, 1)[None]


def _error(image: torch.Tensor, reference: torch.Tensor) -> float:
    """Mean absolute difference over the inner sphere pixels (the rim's pixels are partly background)."""
    size = image.shape[-1]
    yy, xx = torch.meshgrid(torch.arange(size), torch.arange(size), indexing="ij")
    centre = (size - 1) / 2
    inner = ((yy - centre) ** 2 + (xx - centre) ** 2) < (0.85 * size / 2) ** 2
    return float((image - reference).abs()[..., inner].mean() / reference[..., inner].mean())


def test_mitsuba_renders_the_map_as_the_library_does() -> None:
    latlong = orientation_map()
    ours = render_spheres(latlong_to_mirror_ball(latlong, 32), size=32)["diffuse"].float()
    theirs = _mitsuba_diffuse(latlong_for_tool(latlong, "mitsuba"))
    as_on_disk = _mitsuba_diffuse(latlong)
    right, top = ours[0, :, :, -8:].mean((1, 2)), ours[0, :, :8].mean((1, 2))
    assert int(right.argmax()) == 0 and int(top.argmax()) == 1  # red on the right, green at the top
    assert _error(theirs, ours) < 0.08  # measured 0.045: Monte Carlo noise and the coarse 32 x 32 lighting
    assert _error(as_on_disk, ours) > 0.5  # 0.76: the map as stored is turned half a turn in Mitsuba


def test_every_tool_is_a_roll_that_round_trips() -> None:
    latlong = orientation_map(8)
    for tool in TOOLS:
        moved = latlong_for_tool(latlong, tool)
        assert moved.shape == latlong.shape
        torch.testing.assert_close(latlong_for_tool(moved, tool, inverse=True), latlong)
    torch.testing.assert_close(latlong_for_tool(latlong, "kornia_ilum"), latlong)
    with pytest.raises(ValueCheckError, match="tool"):
        latlong_for_tool(latlong, "maya")
    with pytest.raises(ShapeError):
        latlong_for_tool(latlong[..., :-1], "mitsuba")
