r"""The library's lat-long maps in the conventions of other tools: Mitsuba 3, Blender, three.js and Unity.

Every tool here reads an equirectangular image with the top row up (+Y, or Blender's +Z). They differ in
which direction the image's columns face, so one roll of the columns converts a map
(:func:`latlong_for_tool`). Each tool's world is the camera frame of docs/conventions.rst (+X right, +Y up,
+Z toward the camera, the camera looking along -Z), named in that tool's own terms:

================ ===================================================== =========================== ============
tool             the camera frame in the tool's world                  the map's columns            checked by
================ ===================================================== =========================== ============
``mitsuba``      the same axes: a scene built in the camera frame,     centre = +Z                  a render
                 ``envmap`` emitter with its default ``to_world``
``blender``      Blender's front view: right = +X, forward (-Z here)    centre = +X                  a render
                 = +Y, up = +Z; the world's Environment Texture with
                 its default mapping
``threejs``      the same axes (right-handed, +Y up, cameras look      centre = +X                  the source
                 along -Z); ``EquirectangularReflectionMapping``
``unity``        left-handed, +Z forward: (x, y, z) here is            centre = +X                  the source
                 (x, y, -z) in Unity; ``Skybox/Panoramic``, rotation 0
================ ===================================================== =========================== ============

"Checked by a render": ``tests/geometry/test_tools.py`` renders a test map in Mitsuba and compares it with
:func:`~kornia_ilum.render.render_spheres` (4.5 % apart, Monte Carlo noise included; the map as stored: 76 %);
``docs/_scripts/check_blender.py`` does the same in Blender's Cycles (``bpy`` 5.0.1), outside the test suite
since its wheel is 370 MB: 0.6 % apart, against 52 % to 74 % for the three other quarter-turn rolls.
"The source": three.js's ``equirectUv`` (``u = atan2(z, x) / 2 pi + 0.5``, ``v = asin(y) / pi + 0.5``, image
rows flipped on upload) and Unity's
``Skybox-Panoramic.shader`` (``ToRadialCoords``: ``u = 0.5 - atan2(z, x) / 2 pi``, ``v = 1 - acos(y) / pi``),
not rendered here.
"""

from __future__ import annotations

import torch

from kornia_ilum.core.check import check_positive_int, check_tensor
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.geometry.latlong import latlong_directions

__all__ = ["TOOLS", "latlong_for_tool", "orientation_map"]

#: For each tool, where the column at ``u`` of the library's map (``u`` in ``[0, 1)`` across the width) goes
#: in the tool's map: ``u + TOOLS[tool]``, wrapped.
TOOLS: dict[str, float] = {"kornia_ilum": 0.0, "mitsuba": 0.5, "blender": -0.25, "threejs": -0.25, "unity": -0.25}


def latlong_for_tool(latlong: torch.Tensor, tool: str, *, inverse: bool = False) -> torch.Tensor:
    r"""A lat-long map turned into ``tool``'s convention (module docstring), or back with ``inverse=True``.

    Args:
        latlong: lat-long maps, width twice the height.
        tool: one of :data:`TOOLS`.
        inverse: convert from the tool's convention to the library's.

    Returns:
        the maps with their columns rolled, same shape, dtype and device.

    Raises:
        ValueCheckError: an unknown ``tool``.
        ShapeError: not ``(*, H, 2H)``.

    Shape:
        - latlong: :math:`(*, H, 2H)`
        - Output: :math:`(*, H, 2H)`

    Convention:
        docs/conventions.rst, "Lat-long": the library's centre column faces -Z (the way the camera looks).
        A map for Mitsuba is the library's turned half a turn; with ``inverse=True``, a map made for the tool
        comes back in the library's frame.

    Examples:
        >>> latlong = torch.zeros(1, 4, 8)
        >>> latlong[0, :, 4] = 1.0  # the column just right of the centre: ahead of the camera
        >>> latlong_for_tool(latlong, "mitsuba")[0, 0].tolist()  # Mitsuba's centre faces +Z: ahead is the edge
        [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    """
    if tool not in TOOLS:
        raise ValueCheckError(f"tool must be one of {', '.join(TOOLS)}, got {tool!r}")
    check_tensor(latlong, "latlong", ["*", "H", "W"], finite=False)
    height, width = latlong.shape[-2:]
    if width != 2 * height:
        raise ShapeError(f"latlong must be (*, H, 2H), got {tuple(latlong.shape)}")
    shift = round(TOOLS[tool] * width) * (-1 if inverse else 1)
    return torch.roll(latlong, shifts=shift, dims=-1)


def orientation_map(height: int = 32) -> torch.Tensor:
    r"""A lat-long test map for a tool's orientation: a dim grey sky, a red light from +X (the camera's right),
    a green one from +Y (above) and a blue one from +Z (the camera's side).

    A diffuse sphere lit by it in the tool, through :func:`latlong_for_tool`, must be red on its right, green at
    its top and blue at its centre, as :func:`~kornia_ilum.render.render_spheres` renders it
    (``tests/geometry/test_tools.py`` for Mitsuba, ``docs/_scripts/check_blender.py`` for Blender).

    Args:
        height: the map's height ``H``.

    Returns:
        the map, float32 linear radiance: 0.05 everywhere plus ``2 max(d . axis, 0)^2`` in each axis' channel.

    Raises:
        TypeCheckError: ``height`` is not an int.
        ValueCheckError: ``height`` is not positive.

    Shape:
        - Output: :math:`(1, 3, H, 2H)`

    Convention:
        docs/conventions.rst, "Frames" and "Lat-long".

    Examples:
        >>> test = orientation_map(16)
        >>> tuple(test.shape), int(test[0, :, 8, 24].argmax())  # three quarters across: +X, red
        ((1, 3, 16, 32), 0)
    """
    check_positive_int(height, "height")
    d = latlong_directions(height, dtype=torch.float64)
    lobes = 2.0 * d.clamp(min=0) ** 2  # (H, 2H, 3): channel c lit from axis c
    return (0.05 + lobes).permute(2, 0, 1)[None].float()
