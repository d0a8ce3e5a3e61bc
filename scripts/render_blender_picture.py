"""Renders a coloured ShineVDB map (camera colours fused by ``shine map``) in Blender, headless.

Makes docs/images/kitti360_colour_blender.png from the real KITTI-360 drive (25 scans and their
front camera's images in /tmp/k360i: velodyne/, poses.txt, image_00/, calibration/):

    build/shine map /tmp/k360i -o /tmp/k360_colour          # about 25 s on 2 cores
    blender --background --factory-startup --python scripts/render_blender_picture.py -- \\
        --surface /tmp/k360_colour/surface.vdb --output docs/images/kitti360_colour_blender.png

(every image colours the map: no ``--holdout-every``). The surface is imported with the add-on's
own operator (File › Import › ShineVDB level set), from blender_addon/ next to this script unless
the add-on is installed and enabled; the import gives the mesh the attribute ``Col`` from
``mesh.ply`` beside the ``.vdb`` and the material ``ShineVDB colour``, used here unchanged.

Light: a uniform white world of strength 1 (diffuse albedo under it renders as itself, darkened
only where the surface occludes the sky) plus a weak sun for the shapes, and the Standard view
transform, so the fused camera colours read as they are stored; the camera rays see a grey-blue
sky instead. The view is from above and behind the car's start, looking along the drive (+x of
the first scan's frame), where the forward camera saw the street; the parts it never saw (behind
and beside the start, the far cross street) carry the seen vertices' mean colour. Cycles on the
CPU, 1280x540 at 32 samples: about 45 s on 2 cores (import 6 s, render 34 s). The PNG is
reduced to 256 colours (Pillow, in Debian's Blender) to keep it small (365 kB).
"""

import argparse
import math
import os
import sys
import time

import bpy
from mathutils import Vector

REPO_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--surface", required=True,
                        help="shine map's surface.vdb, with a coloured mesh.ply beside it")
    parser.add_argument("--output", required=True, help="PNG to write")
    parser.add_argument("--samples", type=int, default=32, help="Cycles samples per pixel")
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--height", type=int, default=540)
    parser.add_argument("--camera-m", type=float, nargs=3, default=(-5.0, -3.0, 7.5),
                        metavar=("X", "Y", "Z"), help="camera position in the map frame")
    parser.add_argument("--target-m", type=float, nargs=3, default=(18.0, -5.0, -2.0),
                        metavar=("X", "Y", "Z"), help="the point the camera looks at")
    parser.add_argument("--lens-mm", type=float, default=22.0, help="focal length (36 mm sensor)")
    parser.add_argument("--colours", type=int, default=256,
                        help="palette size of the PNG (0: keep 24-bit colour)")
    return parser.parse_args(sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else [])


def import_surface(surface_path: str) -> bpy.types.Object:
    """Imports the surface with the add-on's operator; the mesh must come out coloured."""
    if not hasattr(bpy.types, "IMPORT_SCENE_OT_shinevdb_level_set"):  # not installed + enabled
        sys.path.insert(0, os.path.join(REPO_ROOT, "blender_addon"))
        import shinevdb

        shinevdb.register()
    try:
        bpy.ops.import_scene.shinevdb_level_set(filepath=os.path.abspath(surface_path))
    except RuntimeError as error:  # the operator's error report
        sys.exit(f"render_blender_picture: {str(error).strip()}")
    mesh_object = bpy.context.view_layer.objects.active
    if "Col" not in mesh_object.data.attributes:
        sys.exit(f"render_blender_picture: '{surface_path}' imported without colours: is there "
                 "a mesh.ply with red/green/blue beside it (a map made with camera images)?")
    return mesh_object


def add_camera(location_m, target_m, lens_mm: float) -> None:
    scene = bpy.context.scene
    camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    camera.data.lens = lens_mm
    camera.data.clip_end = 500.0
    camera.location = Vector(location_m)
    camera.rotation_euler = (Vector(target_m) - camera.location).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(camera)
    scene.camera = camera


def add_light() -> None:
    """White light from a uniform sky (shows the albedo as it is) and a weak sun for relief;
    camera rays see a grey-blue backdrop instead of the white."""
    scene = bpy.context.scene
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.data.energy = 0.8
    sun.data.angle = math.radians(3.0)
    sun.rotation_euler = (math.radians(40.0), 0.0, math.radians(-30.0))
    scene.collection.objects.link(sun)

    world = bpy.data.worlds.new("white sky")
    world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    light = nodes["Background"]
    light.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    light.inputs["Strength"].default_value = 1.0
    backdrop = nodes.new("ShaderNodeBackground")
    backdrop.inputs["Color"].default_value = (0.42, 0.50, 0.62, 1.0)
    path = nodes.new("ShaderNodeLightPath")
    mix = nodes.new("ShaderNodeMixShader")
    links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
    links.new(light.outputs["Background"], mix.inputs[1])
    links.new(backdrop.outputs["Background"], mix.inputs[2])
    links.new(mix.outputs["Shader"], nodes["World Output"].inputs["Surface"])
    scene.world = world


def configure_cycles(args: argparse.Namespace, png: str) -> None:
    """Cycles on the CPU (Debian's Blender has no denoiser); Standard view: no Filmic curve."""
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = args.samples
    scene.cycles.use_adaptive_sampling = True
    scene.cycles.adaptive_threshold = 0.02
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 3
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.render.resolution_x = args.width
    scene.render.resolution_y = args.height
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.compression = 90
    scene.render.filepath = png


def reduce_colours(png: str, colours: int) -> None:
    """Rewrites the PNG with a palette of ``colours`` entries (Pillow's median cut, dithered)."""
    try:
        from PIL import Image
    except ImportError:
        print("render_blender_picture: no Pillow in Blender's Python, the PNG keeps 24-bit colour")
        return
    with Image.open(png) as image:
        reduced = image.convert("RGB").quantize(colours, method=Image.Quantize.MEDIANCUT)
    reduced.save(png, optimize=True)


def main() -> None:
    args = parse_args()
    output = os.path.abspath(args.output)
    started = time.monotonic()
    bpy.data.batch_remove(list(bpy.data.objects))  # the factory scene's cube, camera and light
    import_surface(args.surface)
    imported = time.monotonic()
    add_camera(args.camera_m, args.target_m, args.lens_mm)
    add_light()
    configure_cycles(args, output)
    bpy.ops.render.render(write_still=True)
    rendered = time.monotonic()
    if args.colours > 0:
        reduce_colours(output, args.colours)
    print(f"render_blender_picture: wrote {args.output} ({args.width}x{args.height}, "
          f"{args.samples} samples, {os.path.getsize(output) / 1e3:.0f} kB): import "
          f"{imported - started:.0f} s, render {rendered - imported:.0f} s")


main()
