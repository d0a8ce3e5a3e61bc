"""A map's colours and LiDAR intensity on the imported mesh, and a material that shows them.

``shine map`` stores per-surface colour (sRGB, fused from camera images) and intensity (the
LiDAR's reflectance) twice: as grids ``color`` (Vec3s) and ``intensity`` (float) in
``surface.vdb``, on the level set's active voxels, and as vertex properties ``uchar red, green,
blue`` and ``float intensity`` of ``mesh.ply`` beside it. Blender 3.4's Python cannot read a
grid's voxels (Debian's Blender has no ``pyopenvdb``), but the importer's mesh has the very
vertices of ``mesh.ply`` (see :mod:`.level_set_import`), so the values are taken from there.

The rule (:func:`find_vertex_colours`): colours are imported when the file ``mesh.ply`` in the
``.vdb``'s folder has ``uchar`` red/green/blue and/or an ``intensity`` vertex property, whether or
not the ``.vdb`` has the grids. When the ``.vdb`` has a ``color`` or ``intensity`` grid, or the PLY
header announces colours, but no usable ``mesh.ply`` is there (missing, unreadable, truncated,
without those properties) the import goes on without colours and says why in a warning. Without
either, the import is exactly what it was before colours existed.

On the mesh (:func:`apply_vertex_colours`): each vertex takes the values of the nearest
``mesh.ply`` vertex (a KD-tree; they coincide up to float rounding, about 1e-4 voxel), into the
point attributes ``Col`` (byte colour: Blender stores byte colours sRGB-encoded, as the data is,
so the bytes are exact) and ``intensity`` (float); a vertex farther than a tenth of a voxel from
every ``mesh.ply`` vertex (with adaptivity > 0, or a ``mesh.ply`` of another surface) is counted
and reported. The material ``ShineVDB colour`` reads ``Col`` with an Attribute node into the
Principled BSDF's Base Color, so a render shows the colours.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple

import bpy
from mathutils import Vector
from mathutils.kdtree import KDTree

from . import ply_vertices
from .ply_vertices import COLOUR_PROPERTIES, INTENSITY_PROPERTY, PlyFileError

MESH_FILE = "mesh.ply"  # what `shine map` writes beside surface.vdb
COLOUR_GRID = "color"
INTENSITY_GRID = "intensity"
COLOUR_ATTRIBUTE = "Col"
INTENSITY_ATTRIBUTE = "intensity"
MATERIAL_NAME = "ShineVDB colour"
MATCH_TOLERANCE_VOXELS = 0.1  # farther than this from every mesh.ply vertex: reported

Message = Tuple[str, str]  # (level for Operator.report: "INFO" or "WARNING", text)


@dataclass
class VertexColours:
    """Per-vertex values of a ``mesh.ply``; ``rgb`` and ``intensity`` are empty when absent."""

    path: str
    positions: List[Tuple[float, float, float]]
    rgb: Tuple[tuple, tuple, tuple] = ((), (), ())  # red, green, blue columns, 0-255 (sRGB)
    intensity: tuple = ()

    @property
    def has_colour(self) -> bool:
        return len(self.rgb[0]) > 0

    @property
    def has_intensity(self) -> bool:
        return len(self.intensity) > 0

    def describe(self) -> str:
        """E.g. "colours and intensity"."""
        return " and ".join(what for what, present in (("colours", self.has_colour),
                                                       ("intensity", self.has_intensity))
                            if present)


def find_vertex_colours(vdb_path: str, grid_names: Sequence[str],
                        messages: List[Message]) -> Optional[VertexColours]:
    """Reads the colours and intensity for the level set ``vdb_path`` from ``mesh.ply`` beside it.

    Returns None when there are none to import; appends a warning to ``messages`` when the
    ``.vdb``'s grids or the PLY's header announce them but they cannot be read.
    """
    announced = [name for name in (COLOUR_GRID, INTENSITY_GRID) if name in grid_names]
    ply_path = os.path.join(os.path.dirname(vdb_path), MESH_FILE)
    grids = ("grids " if len(announced) > 1 else "grid ") + " and ".join(
        f"'{name}'" for name in announced)
    without = "imported without colours or intensity"
    if not os.path.exists(ply_path):
        if announced:
            messages.append(("WARNING", f"'{vdb_path}' has {grids} but there is no "
                             f"'{ply_path}' to read the vertices' values from: {without}"))
        return None
    try:
        header = ply_vertices.read_header(ply_path)
    except PlyFileError as error:
        if announced:
            messages.append(("WARNING", f"{error}: {without} ({grids} of the .vdb)"))
        return None
    if not header.has_colour and not header.has_intensity:
        if announced:
            messages.append(("WARNING", f"'{ply_path}' has no uchar red/green/blue or "
                             f"intensity vertex properties although '{vdb_path}' has "
                             f"{grids}: {without}"))
        return None
    names = ["x", "y", "z"]
    names += list(COLOUR_PROPERTIES) if header.has_colour else []
    names += [INTENSITY_PROPERTY] if header.has_intensity else []
    try:
        columns: Dict[str, tuple] = ply_vertices.read_vertex_columns(header, names)
    except PlyFileError as error:
        messages.append(("WARNING", f"{error}: {without}"))
        return None
    return VertexColours(
        path=ply_path,
        positions=list(zip(columns["x"], columns["y"], columns["z"])),
        rgb=tuple(columns[name] for name in COLOUR_PROPERTIES) if header.has_colour
        else ((), (), ()),
        intensity=columns.get(INTENSITY_PROPERTY, ()),
    )


def apply_vertex_colours(mesh_object: bpy.types.Object, colours: VertexColours,
                         voxel_size_m: float, messages: List[Message],
                         created: List[bpy.types.ID]) -> None:
    """Gives each vertex of ``mesh_object``'s (plain) mesh the values of the nearest PLY vertex.

    Adds the point attributes ``Col`` and/or ``intensity``; with colours, makes the material
    ``ShineVDB colour`` (re-used if this file already has one) the object's only material. New
    data-blocks are appended to ``created``.
    """
    mesh = mesh_object.data
    tree = KDTree(len(colours.positions))
    for index, position in enumerate(colours.positions):
        tree.insert(position, index)
    tree.balance()

    vertex_count = len(mesh.vertices)
    coordinates = [0.0] * (3 * vertex_count)
    mesh.vertices.foreach_get("co", coordinates)
    loop_vertices = [0] * len(mesh.loops)
    mesh.loops.foreach_get("vertex_index", loop_vertices)
    used = [False] * vertex_count  # OpenVDB's mesher also emits a few vertices no face uses
    for index in loop_vertices:
        used[index] = True
    matrix = mesh_object.matrix_world
    sources = [0] * vertex_count
    limit_m = MATCH_TOLERANCE_VOXELS * voxel_size_m
    far, farthest_m = 0, 0.0
    for vertex in range(vertex_count):
        _, index, distance = tree.find(matrix @ Vector(coordinates[3 * vertex : 3 * vertex + 3]))
        sources[vertex] = index
        if used[vertex] and distance > limit_m:
            far += 1
            farthest_m = max(farthest_m, distance)

    if colours.has_colour:
        red, green, blue = colours.rgb
        attribute = mesh.color_attributes.new(COLOUR_ATTRIBUTE, "BYTE_COLOR", "POINT")
        values = []
        for index in sources:
            values += (red[index] / 255.0, green[index] / 255.0, blue[index] / 255.0, 1.0)
        attribute.data.foreach_set("color_srgb", values)  # stored as these very bytes
        mesh.color_attributes.active_color = attribute
        mesh.color_attributes.render_color_index = mesh.color_attributes.active_color_index
        mesh.materials.clear()
        mesh.materials.append(_colour_material(created))
    if colours.has_intensity:
        attribute = mesh.attributes.new(INTENSITY_ATTRIBUTE, "FLOAT", "POINT")
        attribute.data.foreach_set("value", [colours.intensity[index] for index in sources])

    used_count = sum(used)
    messages.append(("INFO", f"{colours.describe()} of {used_count} vertices from "
                     f"'{colours.path}' (attributes "
                     + ", ".join(name for name, present in (
                         (f"'{COLOUR_ATTRIBUTE}'", colours.has_colour),
                         (f"'{INTENSITY_ATTRIBUTE}'", colours.has_intensity)) if present)
                     + ")"))
    if far:
        messages.append(("WARNING", f"{far} of {used_count} vertices are farther than "
                         f"{MATCH_TOLERANCE_VOXELS:g} voxel ({limit_m:.4g} m) from every vertex "
                         f"of '{colours.path}' (up to {farthest_m:.4g} m): they took the nearest "
                         "one's values (adaptivity above 0, or a mesh.ply of another surface?)"))


def _colour_material(created: List[bpy.types.ID]) -> bpy.types.Material:
    """The material ``ShineVDB colour``: Attribute ``Col`` -> Principled BSDF Base Color."""
    material = bpy.data.materials.get(MATERIAL_NAME)
    if material is not None:
        return material
    material = bpy.data.materials.new(MATERIAL_NAME)
    created.append(material)
    material.use_nodes = True
    nodes, links = material.node_tree.nodes, material.node_tree.links
    shader = next(node for node in nodes if node.type == "BSDF_PRINCIPLED")
    attribute = nodes.new("ShaderNodeAttribute")
    attribute.name = attribute.label = COLOUR_ATTRIBUTE
    attribute.attribute_type = "GEOMETRY"
    attribute.attribute_name = COLOUR_ATTRIBUTE
    attribute.location = (shader.location.x - 300, shader.location.y)
    links.new(attribute.outputs["Color"], shader.inputs["Base Color"])
    return material
