"""Check :data:`kornia_ilum.geometry.TOOLS` for Blender by rendering: a map handed to Blender through
``latlong_for_tool(..., "blender")`` lights a diffuse sphere as the library's own renderer does.

Run: ``python docs/_scripts/check_blender.py --blender-python PYTHON`` where ``PYTHON`` is an interpreter that
has Blender's ``bpy`` module (``pip install bpy``: a 370 MB wheel, hence not a test dependency; bpy 5.0.1 on
Python 3.11 was used). Blender's Cycles renders a sphere of albedo 0.8 from Blender's front view (an
orthographic camera at -Y looking along +Y, +Z up) under :func:`kornia_ilum.geometry.orientation_map` as
the world's Environment Texture, once for each of the four quarter-turn rolls of the map. It prints each
roll's mean relative difference to :func:`kornia_ilum.render.render_spheres`, and exits 1 unless the roll of
``TOOLS["blender"]`` is the one that matches (under 8 %, the bar of the Mitsuba test).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import torch

from kornia_ilum.geometry import TOOLS, latlong_to_mirror_ball, orientation_map
from kornia_ilum.io import read_hdr, write_hdr
from kornia_ilum.render import render_spheres

RENDER = r"""
import math, sys
import bpy
source, target, size, samples = sys.argv[-4], sys.argv[-3], int(sys.argv[-2]), int(sys.argv[-1])
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.engine = "CYCLES"
scene.cycles.device = "CPU"
scene.cycles.samples = samples
scene.cycles.use_denoising = False
scene.cycles.filter_width = 0.01
scene.render.resolution_x = scene.render.resolution_y = size
scene.render.resolution_percentage = 100
scene.view_settings.view_transform = "Standard"
bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=256, ring_count=128)
bpy.ops.object.shade_smooth()
material = bpy.data.materials.new("diffuse")
material.use_nodes = True
nodes, links = material.node_tree.nodes, material.node_tree.links
nodes.clear()
diffuse = nodes.new("ShaderNodeBsdfDiffuse")
diffuse.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
output = nodes.new("ShaderNodeOutputMaterial")
links.new(diffuse.outputs["BSDF"], output.inputs["Surface"])
bpy.context.object.data.materials.append(material)
camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
camera.data.type = "ORTHO"
camera.data.ortho_scale = 2.0
camera.location = (0.0, -5.0, 0.0)
camera.rotation_euler = (math.pi / 2, 0.0, 0.0)  # Blender's front view: looking along +Y, +Z up
scene.collection.objects.link(camera)
scene.camera = camera
world = bpy.data.worlds.new("world")
scene.world = world
world.use_nodes = True
wnodes, wlinks = world.node_tree.nodes, world.node_tree.links
environment = wnodes.new("ShaderNodeTexEnvironment")
environment.image = bpy.data.images.load(source)
wlinks.new(environment.outputs["Color"], wnodes["Background"].inputs["Color"])
scene.render.image_settings.file_format = "OPEN_EXR"
scene.render.image_settings.color_depth = "32"
scene.render.image_settings.color_mode = "RGB"
scene.render.filepath = target
bpy.ops.render.render(write_still=True)
"""


def relative_error(image: torch.Tensor, reference: torch.Tensor) -> float:
    """Mean absolute difference over the sphere's inner pixels, over the reference's mean there."""
    size = image.shape[-1]
    yy, xx = torch.meshgrid(torch.arange(size), torch.arange(size), indexing="ij")
    centre = (size - 1) / 2
    inner = ((yy - centre) ** 2 + (xx - centre) ** 2) < (0.85 * size / 2) ** 2
    return float((image - reference).abs()[..., inner].mean() / reference[..., inner].mean())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blender-python", required=True, help="a Python interpreter with bpy")
    parser.add_argument("--samples", type=int, default=256)
    args = parser.parse_args(argv)
    latlong = orientation_map()
    ours = render_spheres(latlong_to_mirror_ball(latlong, 32), size=32)["diffuse"].float()
    errors = {}
    with tempfile.TemporaryDirectory() as tmp:
        for quarter in (0.0, 0.25, 0.5, -0.25):
            source, target = Path(tmp) / f"map_{quarter}.exr", Path(tmp) / f"render_{quarter}.exr"
            write_hdr(source, torch.roll(latlong, round(quarter * latlong.shape[-1]), dims=-1)[0])
            subprocess.run([args.blender_python, "-c", RENDER, str(source), str(target), "32", str(args.samples)],
                           check=True, capture_output=True)
            errors[quarter] = relative_error(read_hdr(target)[None], ours)
            print(f"roll by {quarter:+.2f} of the width: mean relative difference {errors[quarter]:.3f}")
    best = min(errors, key=errors.get)
    print(f"TOOLS['blender'] = {TOOLS['blender']:+.2f}; the best roll: {best:+.2f} ({errors[best]:.3f})")
    return 0 if best == TOOLS["blender"] and errors[best] < 0.08 else 1


if __name__ == "__main__":
    sys.exit(main())
