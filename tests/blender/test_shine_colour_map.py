"""A real ``shine map`` output with camera colours, imported with the add-on: the mesh's ``Col``
bytes are mesh.ply's, the material shows them, and a small Cycles render is colourful.

Args (after ``--``): --addon-zip ZIP --map DIR (``shine map`` of simulated scans with their front
camera's images, see make_fixture.cmake -DKIND=colour) --scans DIR (those scans: poses.txt places
the render's camera) --work-dir DIR.

test_colour_import.py checks the import rule and its warnings on colours made by a function; this
test checks the same path on what shine itself writes (its mesh.ply layout, its ``color`` grid in
surface.vdb, colours fused from images). The render (Cycles, CPU) is saved as
``WORK_DIR/shine_colour_map.png``, and the same view with every vertex set to the mesh's mean
colour as ``WORK_DIR/mean_colour.png``: the control that the colourfulness check can fail.
"""

import json
import os
import sys
import time

import bpy
import numpy as np
from mathutils import Vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import shinevdb_test_support as support  # noqa: E402
from shinevdb_test_support import expect  # noqa: E402

MATCH_LIMIT_VOXELS = 1e-3  # Blender's vertices and mesh.ply's coincide up to float rounding
RENDER_SIZE_PX = (160, 90)
RENDER_SAMPLES = 16
# A pixel is "saturated" when its sRGB channels spread by more than this (max - min, of 1): the
# simulated street's cars, façades and trees; asphalt, pavements and a mean colour stay below.
SATURATED_CHROMA = 0.25
# Measured at 160 x 90 px, 16 samples (the fixture's seed-3 street, 6 frames): 10.4 % of the
# mesh's pixels are saturated with the fused colours, 0.0 % with the mean colour (chroma p95
# 0.024); the bound is half the measurement.
MIN_SATURATED_FRACTION = 0.05
MIN_DISTINCT_COLOURS = 1000  # in mesh.ply (6439 measured); an all-mean-coloured map has one


def check_shine_output(map_dir: str) -> np.ndarray:
    """shine wrote the colours twice: a ``color`` grid in surface.vdb and uchar red/green/blue in
    mesh.ply, varied (fused from images, not a fallback). Returns mesh.ply's vertex records."""
    from shinevdb import vdb_header

    surface = os.path.join(map_dir, "surface.vdb")
    grids = {grid.name: grid for grid in vdb_header.read_grids(surface)}
    print("surface.vdb grids: " + ", ".join(grid.describe() for grid in grids.values()))
    expect("color" in grids and "surface" in grids,
           f"{surface} has no 'color' grid next to 'surface': {list(grids)}")
    records, _ = support.read_ply_records(os.path.join(map_dir, "mesh.ply"))
    names = records.dtype.names
    expect(all(name in names and records.dtype[name] == np.uint8
               for name in ("red", "green", "blue")),
           f"mesh.ply has no uchar red/green/blue: {records.dtype}")
    rgb = np.stack([records[name] for name in ("red", "green", "blue")], axis=1)
    distinct = len(np.unique(rgb, axis=0))
    chroma = (rgb.max(axis=1).astype(int) - rgb.min(axis=1)) / 255.0
    print(f"mesh.ply: {len(records)} vertices, {distinct} distinct colours, "
          f"{100 * np.mean(chroma > SATURATED_CHROMA):.1f} % saturated; properties {names}")
    expect(distinct >= MIN_DISTINCT_COLOURS,
           f"mesh.ply has only {distinct} distinct colours: not colours fused from images")
    return records


def import_map(map_dir: str) -> bpy.types.Object:
    """Imports surface.vdb as the operator does (checked in a separate Blender first): colours
    from mesh.ply, said in an info message, and no warning."""
    from shinevdb import level_set_import

    support.clear_scene()
    messages = []
    started = time.monotonic()
    mesh_object = level_set_import.import_level_set(
        os.path.join(map_dir, "surface.vdb"), bpy.context.collection, bpy.context.view_layer,
        messages=messages)
    print(f"imported in {time.monotonic() - started:.2f} s: {messages}")
    ply = os.path.join(map_dir, "mesh.ply")
    expect(not [text for level, text in messages if level != "INFO"],
           f"warnings for shine's coloured map: {messages}")
    expect(any(ply in text and "colours" in text for _, text in messages),
           f"no message naming {ply} as the colours' source: {messages}")
    return mesh_object


def check_attributes(mesh_object: bpy.types.Object, records: np.ndarray,
                     voxel_size_m: float) -> np.ndarray:
    """Each vertex used by a face has exactly the bytes (and intensity, if mesh.ply has it) of
    the mesh.ply vertex it coincides with. Returns the used vertices' mask."""
    mesh = mesh_object.data
    colour = mesh.attributes.get("Col")
    expect(colour is not None and colour.domain == "POINT" and colour.data_type == "BYTE_COLOR",
           f"no point byte-colour attribute 'Col': {list(mesh.attributes.keys())}")
    vertices, triangles = support.evaluated_mesh(mesh_object)
    used = np.zeros(len(vertices), bool)
    used[triangles.ravel()] = True
    srgb = np.empty(4 * len(vertices), np.float32)
    colour.data.foreach_get("color_srgb", srgb)
    rgb = np.round(255 * srgb.reshape(-1, 4)[used, :3]).astype(np.int64)

    ply_vertices = np.stack([records[axis] for axis in "xyz"], axis=1).astype(np.float64)
    nearest = support.nearest_vertex_indices(vertices[used], ply_vertices)
    distance = np.linalg.norm(vertices[used] - ply_vertices[nearest], axis=1).max()
    print(f"{used.sum()} used vertices of {len(vertices)}; farthest from its mesh.ply vertex: "
          f"{1000 * distance:.4f} mm ({distance / voxel_size_m:.1e} voxel)")
    expect(distance < MATCH_LIMIT_VOXELS * voxel_size_m,
           f"a vertex is {distance} m from every mesh.ply vertex")
    expected = np.stack([records[name][nearest] for name in ("red", "green", "blue")],
                        axis=1).astype(np.int64)
    wrong = np.any(rgb != expected, axis=1)
    print(f"'Col': {wrong.sum()} of {used.sum()} vertices differ from mesh.ply's bytes")
    expect(not wrong.any(), f"{wrong.sum()} vertices have other colours than mesh.ply's, e.g. "
           f"{rgb[wrong][:3]} instead of {expected[wrong][:3]}")

    if "intensity" in records.dtype.names:
        values = np.empty(len(vertices), np.float32)
        mesh.attributes["intensity"].data.foreach_get("value", values)
        expect(np.array_equal(values[used], records["intensity"][nearest]),
               "'intensity' differs from mesh.ply's")
    else:
        expect("intensity" not in mesh.attributes,
               "an 'intensity' attribute although mesh.ply has no intensity")
    support.check_colour_material(mesh, "shine map")
    return used


def read_positions(poses_path: str) -> np.ndarray:
    """The scans' positions from a KITTI poses.txt (3 x 4 row-major T_world_sensor per line)."""
    poses = np.loadtxt(poses_path).reshape(-1, 3, 4)
    return poses[:, :, 3]


def set_up_render(scans_dir: str) -> None:
    """A camera behind and above the first scan, looking along the drive (the front camera's
    view, where the colours are); uniform white light; Standard view: the sRGB as stored."""
    scene = bpy.context.scene
    positions = read_positions(os.path.join(scans_dir, "poses.txt"))
    along = positions[-1] - positions[0]
    along[2] = 0.0
    along /= np.linalg.norm(along)
    start = Vector(positions[0])
    camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    scene.collection.objects.link(camera)
    camera.data.lens = 20.0
    camera.location = start - 4.0 * Vector(along) + Vector((0.0, 0.0, 3.0))
    target = start + 15.0 * Vector(along) - Vector((0.0, 0.0, 1.0))
    camera.rotation_euler = (target - camera.location).to_track_quat("-Z", "Y").to_euler()
    scene.camera = camera
    scene.world = bpy.data.worlds.new("white")
    scene.world.color = (1.0, 1.0, 1.0)
    scene.view_settings.view_transform = "Standard"
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = RENDER_SAMPLES
    scene.cycles.use_denoising = False
    scene.render.film_transparent = True
    scene.render.resolution_x, scene.render.resolution_y = RENDER_SIZE_PX
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"


def saturated_fraction(png: str) -> float:
    """Renders the scene to ``png``; returns the fraction of the mesh's pixels whose sRGB
    channels spread by more than SATURATED_CHROMA."""
    scene = bpy.context.scene
    scene.render.filepath = png
    started = time.monotonic()
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(png)
    width, height = RENDER_SIZE_PX
    pixels = np.array(image.pixels[:]).reshape(height, width, 4)
    bpy.data.images.remove(image)
    covered = pixels[..., 3] > 0.5
    rgb = pixels[covered][:, :3]
    chroma = rgb.max(axis=1) - rgb.min(axis=1)
    fraction = float(np.mean(chroma > SATURATED_CHROMA))
    print(f"rendered {png} in {time.monotonic() - started:.1f} s: the mesh covers "
          f"{covered.sum()} px, {100 * fraction:.1f} % saturated, chroma p50 "
          f"{np.percentile(chroma, 50):.3f}, p95 {np.percentile(chroma, 95):.3f}")
    expect(covered.sum() > 0.3 * width * height,
           f"the render shows little of the map: {covered.sum()} px")
    return fraction


def check_render(mesh_object: bpy.types.Object, used: np.ndarray, scans_dir: str,
                 work_dir: str) -> None:
    """The render has the street's saturated colours; with every vertex at the mean colour, the
    same view does not (so the check can fail: a grey or mean-coloured import is caught)."""
    set_up_render(scans_dir)
    fraction = saturated_fraction(os.path.join(work_dir, "shine_colour_map.png"))
    expect(fraction > MIN_SATURATED_FRACTION,
           f"the render is greyish: {100 * fraction:.1f} % of the mesh's pixels are saturated, "
           f"expected more than {100 * MIN_SATURATED_FRACTION:.0f} %")

    colour = mesh_object.data.attributes["Col"]
    srgb = np.empty(4 * len(colour.data), np.float32)
    colour.data.foreach_get("color_srgb", srgb)
    srgb = srgb.reshape(-1, 4)
    srgb[:] = srgb[used].mean(axis=0)
    colour.data.foreach_set("color_srgb", srgb.ravel())
    mesh_object.data.update()
    control = saturated_fraction(os.path.join(work_dir, "mean_colour.png"))
    expect(control < MIN_SATURATED_FRACTION,
           f"the mean-coloured control passes the colour check ({100 * control:.1f} %): the "
           "threshold does not tell colours from none")


def main() -> None:
    started = time.monotonic()
    args = support.parse_args("addon-zip", "map", "scans", "work-dir")
    work_dir = support.fresh_dir(args.work_dir)
    support.install_addon(args.addon_zip, args.work_dir)
    with open(os.path.join(args.map, "stats.json"), encoding="utf-8") as stats_file:
        voxel_size_m = json.load(stats_file)["surface"]["voxel_size_m"]
    records = check_shine_output(args.map)
    mesh_object = import_map(args.map)
    used = check_attributes(mesh_object, records, voxel_size_m)
    check_render(mesh_object, used, args.scans, work_dir)
    print(f"test_shine_colour_map: all checks passed in {time.monotonic() - started:.1f} s")


main()
