"""A map's colours and intensity: imported onto the mesh, shown by the material and a render; a
missing or corrupt mesh.ply is a warning naming it, and a plain map imports as before.

Args (after ``--``): --addon-zip ZIP --fixture DIR (``surface.vdb`` and ``mesh.ply`` of a plain
map made by ``shine``, see make_fixture.cmake) --work-dir DIR.

The coloured map is made here, independently of shine's colour code: the fixture's surface.vdb
with an (empty) Vec3s grid ``color`` and float grid ``intensity`` appended, and its mesh.ply
rewritten with uchar red, green, blue and float intensity set from each vertex's position by the
functions below. The render (Cycles, CPU) is saved as ``WORK_DIR/colours.png``.
"""

import json
import os
import shutil
import stat
import struct
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import shinevdb_test_support as support  # noqa: E402
from shinevdb_test_support import expect  # noqa: E402

RENDER_SIZE_PX = (192, 128)
RENDER_SAMPLES = 4
# How much redder (greener) than green (red) the left (right) third of the rendered mesh must be,
# in 8-bit sRGB / 255: the albedos differ by 0.8 and 0.6 there, lighting only scales them.
MIN_CHANNEL_MARGIN = 0.15
MATCH_LIMIT_VOXELS = 1e-3  # Blender's vertices and mesh.ply's coincide up to float rounding


def colour_function(vertices: np.ndarray, x_split_m: float, z_range_m: tuple):
    """The fixture's colours and intensity of vertices at ``vertices`` (N x 3, metres):
    red 230 left of x_split (smaller x) else 25, green 25 left else 180, blue from 25 at the
    lowest to 125 at the highest z; intensity = z."""
    left = vertices[:, 0] < x_split_m
    red = np.where(left, 230, 25).astype(np.uint8)
    green = np.where(left, 25, 180).astype(np.uint8)
    z_low, z_high = z_range_m
    blue = np.round(25 + 100 * np.clip((vertices[:, 2] - z_low) / (z_high - z_low), 0, 1))
    return red, green, blue.astype(np.uint8), vertices[:, 2].astype(np.float32)


class ColouredMap:
    """A map folder with colour grids in surface.vdb and a coloured mesh.ply."""

    def __init__(self, fixture: str, folder: str):
        self.folder = folder
        self.surface = os.path.join(folder, "surface.vdb")
        self.ply = os.path.join(folder, "mesh.ply")
        os.makedirs(folder)
        shutil.copyfile(os.path.join(fixture, "surface.vdb"), self.surface)
        support.append_empty_grid(self.surface, "color", "Tree_vec3s_5_4_3",
                                  struct.pack("<3f", 0, 0, 0))
        support.append_empty_grid(self.surface, "intensity", "Tree_float_5_4_3",
                                  struct.pack("<f", 0))
        self.vertices, self.triangles = support.read_ply(os.path.join(fixture, "mesh.ply"))
        self.x_split_m = float(np.median(self.vertices[:, 0]))
        self.z_range_m = (float(self.vertices[:, 2].min()), float(self.vertices[:, 2].max()))
        red, green, blue, intensity = self.expected(self.vertices)
        support.write_ply(self.ply, self.vertices, self.triangles,
                          (("red", red), ("green", green), ("blue", blue),
                           ("intensity", intensity)))

    def expected(self, vertices: np.ndarray):
        return colour_function(vertices, self.x_split_m, self.z_range_m)


def import_with_messages(surface: str, **options):
    """Imports through the add-on's function (as the operator and the panel do) on an empty
    scene; returns the mesh object and the messages for the user."""
    from shinevdb import level_set_import

    support.clear_scene()
    messages = []
    started = time.monotonic()
    mesh_object = level_set_import.import_level_set(
        surface, bpy.context.collection, bpy.context.view_layer, messages=messages, **options)
    print(f"imported {os.path.basename(os.path.dirname(surface))}/{os.path.basename(surface)} "
          f"{options or ''} in {time.monotonic() - started:.2f} s: {messages}")
    return mesh_object, messages


def warnings_of(messages) -> list:
    return [text for level, text in messages if level == "WARNING"]


def expect_no_colours(mesh_object: bpy.types.Object, label: str) -> None:
    """No colour or intensity attribute and no material: the import as before colours."""
    mesh = mesh_object.data
    expect("Col" not in mesh.attributes and "intensity" not in mesh.attributes,
           f"{label}: unexpected attributes {list(mesh.attributes.keys())}")
    expect(len(mesh.materials) == 0, f"{label}: unexpected materials {list(mesh.materials)}")


def check_colours(mesh_object: bpy.types.Object, coloured: ColouredMap, voxel_size_m: float,
                  label: str) -> None:
    """Every vertex used by a face has exactly the bytes and intensity the fixture's functions
    give its mesh.ply vertex, which lies within float rounding of it; the material reads Col."""
    mesh = mesh_object.data
    colour = mesh.attributes.get("Col")
    expect(colour is not None and colour.domain == "POINT" and colour.data_type == "BYTE_COLOR",
           f"{label}: no point byte-colour attribute 'Col': {list(mesh.attributes.keys())}")
    intensity = mesh.attributes.get("intensity")
    expect(intensity is not None and intensity.domain == "POINT"
           and intensity.data_type == "FLOAT", f"{label}: no point float attribute 'intensity'")

    vertices, triangles = support.evaluated_mesh(mesh_object)
    used = np.zeros(len(vertices), bool)
    used[triangles.ravel()] = True
    srgb = np.empty(4 * len(vertices), np.float32)
    colour.data.foreach_get("color_srgb", srgb)
    rgb = np.round(255 * srgb.reshape(-1, 4)[:, :3]).astype(np.int64)
    values = np.empty(len(vertices), np.float32)
    intensity.data.foreach_get("value", values)

    matched = support.nearest_vertices(vertices[used], coloured.vertices)
    distance = np.linalg.norm(vertices[used] - matched, axis=1).max()
    expect(distance < MATCH_LIMIT_VOXELS * voxel_size_m,
           f"{label}: a vertex is {distance} m from every mesh.ply vertex")
    red, green, blue, expected_intensity = coloured.expected(matched)
    expected_rgb = np.stack([red, green, blue], axis=1).astype(np.int64)
    wrong = np.any(rgb[used] != expected_rgb, axis=1)
    print(f"{label}: {used.sum()} vertices: {wrong.sum()} colours differ from the function's; "
          f"max |intensity - z| {np.abs(values[used] - vertices[used][:, 2]).max():.2e} m")
    expect(not wrong.any(), f"{label}: {wrong.sum()} vertices have other colours, e.g. "
           f"{rgb[used][wrong][:3]} instead of {expected_rgb[wrong][:3]}")
    expect(np.array_equal(values[used], expected_intensity),
           f"{label}: intensity differs from the PLY's")
    expect(np.abs(values[used] - vertices[used][:, 2]).max() < MATCH_LIMIT_VOXELS * voxel_size_m,
           f"{label}: intensity is not the vertex's z")
    expect(set(red) == {230, 25} and len(set(blue)) > 50, f"{label}: a degenerate fixture")

    support.check_colour_material(mesh, label)


def render_top_view(mesh_object: bpy.types.Object, coloured: ColouredMap, png: str) -> None:
    """Renders the mesh from above (x to the right) with Cycles; the left third, red in the
    fixture, must look red and the right third green."""
    scene = bpy.context.scene
    vertices, _ = support.evaluated_mesh(mesh_object)
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    scene.collection.objects.link(camera)
    camera.data.type = "ORTHO"
    width, height = RENDER_SIZE_PX
    camera.data.ortho_scale = 1.05 * max(high[0] - low[0], (high[1] - low[1]) * width / height)
    camera.data.clip_end = 10 * (high[2] - low[2] + 10)
    camera.location = ((low[0] + high[0]) / 2, (low[1] + high[1]) / 2, high[2] + 10)
    scene.camera = camera  # looks down -z with x to the right, as unrotated cameras do
    scene.world = bpy.data.worlds.new("white")
    scene.world.color = (1.0, 1.0, 1.0)  # uniform white light from the sky, no nodes
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = RENDER_SAMPLES
    scene.cycles.use_denoising = False
    scene.render.film_transparent = True
    scene.render.resolution_x, scene.render.resolution_y = RENDER_SIZE_PX
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = png
    started = time.monotonic()
    bpy.ops.render.render(write_still=True)
    print(f"rendered {png} in {time.monotonic() - started:.1f} s")

    image = bpy.data.images.load(png)
    pixels = np.array(image.pixels[:]).reshape(height, width, 4)
    split_px = int(round((coloured.x_split_m - camera.location.x) / camera.data.ortho_scale
                         * width + width / 2))
    for label, columns, channel, other in (("left", slice(0, split_px * 2 // 3), 0, 1),
                                           ("right", slice(split_px + (width - split_px) // 3,
                                                           width), 1, 0)):
        part = pixels[:, columns]
        covered = part[..., 3] > 0.5
        expect(covered.sum() > 50, f"the render shows little of the mesh's {label} part")
        mean = part[covered][:, :3].mean(axis=0)
        print(f"render, {label} part: mean sRGB {np.round(mean, 3)} over {covered.sum()} pixels")
        expect(mean[channel] > mean[other] + MIN_CHANNEL_MARGIN,
               f"the {label} part of the render is not {('red', 'green')[channel]}: {mean}")


def check_operator_import(coloured: ColouredMap, voxel_size_m: float, png: str) -> None:
    """File › Import (the operator, defaults) gives the colours; a render shows them."""
    support.clear_scene()
    result = bpy.ops.import_scene.shinevdb_level_set(filepath=coloured.surface)
    expect(result == {"FINISHED"}, f"the import returned {result}")
    mesh_object = bpy.context.view_layer.objects.active
    check_colours(mesh_object, coloured, voxel_size_m, "operator")
    render_top_view(mesh_object, coloured, png)


def check_function_import(coloured: ColouredMap, voxel_size_m: float) -> None:
    """The function's messages: what came from mesh.ply, and no warning for a good map."""
    mesh_object, messages = import_with_messages(coloured.surface, verify=False)
    expect(not warnings_of(messages), f"warnings for a good coloured map: {messages}")
    expect(any(coloured.ply in text and "colours and intensity" in text
               for _, text in messages), f"no message naming {coloured.ply}: {messages}")
    check_colours(mesh_object, coloured, voxel_size_m, "function")
    # A second import re-uses the material rather than making 'ShineVDB colour.001'.
    from shinevdb import level_set_import

    material = mesh_object.data.materials[0]
    again = level_set_import.import_level_set(coloured.surface, bpy.context.collection,
                                              bpy.context.view_layer, verify=False)
    ours = [m.name for m in bpy.data.materials if m.name.startswith("ShineVDB colour")]
    expect(again.data.materials[0] == material and ours == ["ShineVDB colour"],
           f"a second import made another material: {ours}")

    # Adaptivity moves and merges vertices: the nearest values anyway, and a warning counting
    # the vertices that do not coincide with mesh.ply's.
    mesh_object, messages = import_with_messages(coloured.surface, verify=False, adaptivity=0.5)
    expect(any("farther than 0.1 voxel" in text for text in warnings_of(messages))
           and "Col" in mesh_object.data.attributes,
           f"adaptivity 0.5: expected colours and a warning about far vertices: {messages}")

    # A live modifier cannot hold attributes: a warning, and the mesh as before.
    mesh_object, messages = import_with_messages(coloured.surface, verify=False,
                                                 apply_modifier=False)
    expect(any("Apply Modifier" in text for text in warnings_of(messages)),
           f"no warning that colours need Apply Modifier: {messages}")
    expect_no_colours(mesh_object, "live modifier")


def check_unusable_mesh_ply(coloured: ColouredMap, fixture: str, work_dir: str) -> None:
    """Colour grids but no usable mesh.ply: each a warning naming the file; imported, uncoloured.
    A coloured mesh.ply beside a .vdb without the grids is used (the PLY alone is enough)."""
    with open(coloured.ply, "rb") as ply_file:
        good = ply_file.read()
    header_bytes = good.index(b"end_header\n") + len(b"end_header\n")
    cases = {
        "no_ply": (None, "there is no"),
        "truncated_ply": (good[: header_bytes + (len(good) - header_bytes) // 3], "truncated"),
        "garbage_ply": (np.random.default_rng(5).integers(0, 256, 4096, np.uint8).tobytes(),
                        "does not start with 'ply'"),
        "ascii_ply": (good[:header_bytes].replace(b"binary_little_endian", b"ascii"),
                      "is not supported"),
        "uncoloured_ply": (open(os.path.join(fixture, "mesh.ply"), "rb").read(),
                           "no uchar red/green/blue"),
    }
    for name, (contents, phrase) in cases.items():
        folder = os.path.join(work_dir, name)
        os.makedirs(folder)
        surface = os.path.join(folder, "surface.vdb")
        shutil.copyfile(coloured.surface, surface)
        ply = os.path.join(folder, "mesh.ply")
        if contents is not None:
            with open(ply, "wb") as ply_file:
                ply_file.write(contents)
        mesh_object, messages = import_with_messages(surface, verify=False)
        warnings = warnings_of(messages)
        expect(len(warnings) == 1 and ply in warnings[0] and phrase in warnings[0]
               and "without colours" in warnings[0],
               f"{name}: expected one warning naming {ply} and saying '{phrase}': {messages}")
        expect_no_colours(mesh_object, name)

    # The operator finishes (the warning is a report, not a failure).
    support.clear_scene()
    result = bpy.ops.import_scene.shinevdb_level_set(
        filepath=os.path.join(work_dir, "truncated_ply", "surface.vdb"))
    expect(result == {"FINISHED"} and len(bpy.data.objects) == 1,
           f"the import beside a truncated mesh.ply returned {result}")

    # A truncated coloured mesh.ply next to a .vdb without colour grids: its header announced
    # colours, so it is still a warning.
    folder = os.path.join(work_dir, "truncated_ply_plain_vdb")
    os.makedirs(folder)
    shutil.copyfile(os.path.join(fixture, "surface.vdb"), os.path.join(folder, "surface.vdb"))
    with open(os.path.join(folder, "mesh.ply"), "wb") as ply_file:
        ply_file.write(cases["truncated_ply"][0])
    mesh_object, messages = import_with_messages(os.path.join(folder, "surface.vdb"),
                                                 verify=False)
    expect(len(warnings_of(messages)) == 1 and "truncated" in warnings_of(messages)[0],
           f"no warning for a truncated coloured mesh.ply: {messages}")
    expect_no_colours(mesh_object, "truncated beside a plain .vdb")

    # Intensity alone: the attribute, no colour attribute or material, no warning.
    folder = os.path.join(work_dir, "intensity_only")
    os.makedirs(folder)
    shutil.copyfile(os.path.join(fixture, "surface.vdb"), os.path.join(folder, "surface.vdb"))
    support.write_ply(os.path.join(folder, "mesh.ply"), coloured.vertices, coloured.triangles,
                      (("intensity", coloured.expected(coloured.vertices)[3]),))
    mesh_object, messages = import_with_messages(os.path.join(folder, "surface.vdb"),
                                                 verify=False)
    attributes = mesh_object.data.attributes
    expect(not warnings_of(messages) and "intensity" in attributes and "Col" not in attributes
           and len(mesh_object.data.materials) == 0,
           f"intensity only: {list(attributes.keys())}, {messages}")

    folder = os.path.join(work_dir, "coloured_ply_plain_vdb")
    os.makedirs(folder)
    shutil.copyfile(os.path.join(fixture, "surface.vdb"), os.path.join(folder, "surface.vdb"))
    shutil.copyfile(coloured.ply, os.path.join(folder, "mesh.ply"))
    mesh_object, messages = import_with_messages(os.path.join(folder, "surface.vdb"),
                                                 verify=False)
    expect(not warnings_of(messages) and "Col" in mesh_object.data.attributes,
           f"a coloured mesh.ply beside a .vdb without colour grids was not used: {messages}")


def check_plain_map(fixture: str) -> None:
    """The fixture's plain map (no colour grids, mesh.ply without colours): no message, no
    attribute, no material, as before colours existed."""
    mesh_object, messages = import_with_messages(os.path.join(fixture, "surface.vdb"),
                                                 verify=False)
    expect(messages == [], f"messages for a plain map: {messages}")
    expect_no_colours(mesh_object, "plain map")


def check_map_panel_import(coloured: ColouredMap, voxel_size_m: float, work_dir: str) -> None:
    """The sidebar's run imports the colours too: a stand-in 'shine' writes the coloured map
    into the output folder and exits 0, and the run's import is coloured."""
    from shinevdb import map_run

    fake_shine = os.path.join(work_dir, "fake_shine")
    with open(fake_shine, "w", encoding="utf-8") as script:
        script.write(f"""#!/usr/bin/env python3
# Stands in for `shine map SCANS --output OUT ...`: copies a coloured map into OUT.
import os, shutil, sys
out = sys.argv[sys.argv.index("--output") + 1]
os.makedirs(out, exist_ok=True)
for name in ("surface.vdb", "mesh.ply"):
    shutil.copyfile(os.path.join({coloured.folder!r}, name), os.path.join(out, name))
print("wrote " + out)
""")
    os.chmod(fake_shine, os.stat(fake_shine).st_mode | stat.S_IXUSR)
    support.clear_scene()
    scans = os.path.join(work_dir, "scans")
    os.makedirs(scans)
    request = map_run.MapRequest(scan_dir=scans, output_dir=os.path.join(work_dir, "run_out"),
                                 leaf_size_m=0.2, mode="batch", iterations=0, extra_args="")
    map_run.start(fake_shine, request, bpy.context.scene, bpy.context.view_layer)
    run = map_run.wait_until_done(timeout_s=60)
    print("map run summary: " + " | ".join(run.summary))
    expect(run.state == "done", f"the run ended '{run.state}': {run.error}")
    expect(any("colours and intensity" in line for line in run.summary)
           and not any(line.startswith("warning") for line in run.summary),
           f"the run's summary does not say where the colours came from: {run.summary}")
    check_colours(bpy.data.objects[run.imported_object], coloured, voxel_size_m, "map panel")


def main() -> None:
    started = time.monotonic()
    args = support.parse_args("addon-zip", "fixture", "work-dir")
    work_dir = support.fresh_dir(args.work_dir)
    support.install_addon(args.addon_zip, args.work_dir)
    with open(os.path.join(args.fixture, "stats.json"), encoding="utf-8") as stats_file:
        voxel_size_m = json.load(stats_file)["surface"]["voxel_size_m"]
    coloured = ColouredMap(args.fixture, os.path.join(work_dir, "coloured"))

    check_plain_map(args.fixture)
    check_function_import(coloured, voxel_size_m)
    check_unusable_mesh_ply(coloured, args.fixture, work_dir)
    check_map_panel_import(coloured, voxel_size_m, work_dir)
    check_operator_import(coloured, voxel_size_m, os.path.join(work_dir, "colours.png"))
    print(f"test_colour_import: all checks passed in {time.monotonic() - started:.1f} s")


main()
