"""File › Import › ShineVDB level set (.vdb): a level-set grid as a Volume and its surface mesh.

The mesh comes from Blender's Volume to Mesh modifier at iso 0 on the level-set grid (not the
``density`` grid the modifier reads by default). Blender 3.4's modifier returns OpenVDB's
``volumeToMesh`` vertices moved by half a voxel along +x, +y and +z (measured: the used vertices of
the ``mesh.ply`` of ``shine map`` / ``shine mesh`` plus that shift). The modifier
places its output where the Volume object is, so the importer moves the Volume object by minus half
a voxel: the mesh then lies exactly where ``mesh.ply`` lies, in the same world frame (numbers in
docs/blender.md; checked by tests/blender/test_import.py).

Far-away maps (UTM coordinates) are stored in a local frame, with the frame's world position in
the grid's ``shine_origin_world_m`` metadata; Blender's float32 coordinates would be 0.5 m coarse
at 5e6 m. The importer keeps the mesh in the local frame and stores that origin on the object as
the custom property ``shine_origin_world_m`` (x, y, z in metres), as ``mesh.ply`` carries it in
its header.

Colours and LiDAR intensity: when ``mesh.ply`` beside the ``.vdb`` has them as vertex properties
(``shine map`` also writes grids ``color`` and ``intensity``), the applied mesh gets the point
attributes ``Col`` and ``intensity`` and the material ``ShineVDB colour``; the rule and its
warnings are in :mod:`.map_colours`.
"""

import os
from typing import List, Optional

import bpy
from bpy.props import BoolProperty, FloatProperty, StringProperty
from bpy_extras.io_utils import ImportHelper
from mathutils import Matrix, Vector

from . import map_colours, vdb_header, vdb_probe
from .map_colours import Message
from .vdb_header import GridInfo, VdbFileError

DEFAULT_GRID_NAME = "surface"  # the grid `shine map` and `shine bake` write


class LevelSetImportError(Exception):
    """The file cannot be imported; the message names the file and the problem."""


def import_level_set(
    filepath: str,
    collection: bpy.types.Collection,
    view_layer: bpy.types.ViewLayer,
    grid_name: str = DEFAULT_GRID_NAME,
    keep_volume: bool = False,
    apply_modifier: bool = True,
    adaptivity: float = 0.0,
    smooth_shading: bool = True,
    verify: bool = True,
    messages: Optional[List[Message]] = None,
) -> bpy.types.Object:
    """Imports grid ``grid_name`` of the level set ``filepath`` and returns the new mesh object.

    Args:
        filepath: the ``.vdb`` file (Blender-relative ``//`` paths are resolved).
        collection: where the new objects are linked; it must be in ``view_layer``.
        view_layer: used to evaluate the modifier and to select the new mesh object.
        grid_name: the level-set grid to mesh.
        keep_volume: keep the Volume object visible; otherwise it is deleted (modifier applied)
            or hidden (the live modifier still reads it).
        apply_modifier: turn the Volume to Mesh result into plain mesh data.
        adaptivity: the modifier's adaptivity in [0, 1]; 0 keeps every voxel's polygons.
        smooth_shading: shade the mesh smooth.
        verify: first load and mesh the grid in a separate background Blender, so that a
            corrupt file fails with a message instead of aborting this Blender.
        messages: if given, receives ("INFO" | "WARNING", text) pairs for the user: what was
            imported from ``mesh.ply``, and why colours were not (the import still succeeds).

    Raises:
        LevelSetImportError: the file is missing, corrupt, has no such float level-set grid, or
            its zero level set is empty. Nothing is left behind in ``bpy.data``.
    """
    path = os.path.abspath(bpy.path.abspath(filepath))
    try:
        grids = vdb_header.read_grids(path)
        grid = _find_level_set_grid(path, grids, grid_name)
        if verify:
            vdb_probe.verify_grid_in_subprocess(path, grid.name)
    except VdbFileError as error:
        raise LevelSetImportError(str(error)) from None

    if messages is None:
        messages = []
    colours = map_colours.find_vertex_colours(path, [info.name for info in grids], messages)
    if colours is not None and not apply_modifier:
        messages.append(("WARNING", f"the {colours.describe()} of '{colours.path}' need Apply "
                         "Modifier (a live modifier's mesh cannot keep attributes): imported "
                         "without them"))
        colours = None
    created: List[bpy.types.ID] = []
    try:
        mesh_object, voxel_size_m = _build_objects(
            path, grid.name, collection, view_layer, created, keep_volume, apply_modifier,
            adaptivity, smooth_shading)
        if colours is not None:
            map_colours.apply_vertex_colours(mesh_object, colours, voxel_size_m, messages,
                                             created)
    except BaseException:
        bpy.data.batch_remove(created)  # leave nothing of a failed import behind
        raise
    if grid.origin_world_m is not None and any(grid.origin_world_m):
        mesh_object["shine_origin_world_m"] = list(grid.origin_world_m)
    for selected in view_layer.objects.selected:
        selected.select_set(False, view_layer=view_layer)
    mesh_object.select_set(True, view_layer=view_layer)
    view_layer.objects.active = mesh_object
    return mesh_object


def _find_level_set_grid(path: str, grids: List[GridInfo], grid_name: str) -> GridInfo:
    """Returns the grid named ``grid_name`` if it is a float level set, else raises."""
    listing = ", ".join(grid.describe() for grid in grids)
    grid = next((grid for grid in grids if grid.name == grid_name), None)
    if grid is None:
        raise LevelSetImportError(f"'{path}' has no grid named '{grid_name}'; its grids: {listing}")
    if grid.value_type not in ("float", "double") or grid.grid_class != "level set":
        raise LevelSetImportError(
            f"grid {grid.describe()} of '{path}' is not a float level set (signed distances, "
            f"negative inside), which this importer meshes at iso 0; its grids: {listing}"
        )
    return grid


def _build_objects(path, grid_name, collection, view_layer, created, keep_volume,
                   apply_modifier, adaptivity, smooth_shading):
    """Creates the Volume and mesh objects; appends every new data-block to ``created``.

    Returns the mesh object and the grid's voxel size in metres (the mean over its axes).
    """
    name = os.path.splitext(os.path.basename(path))[0]
    volume = bpy.data.volumes.new(name)
    created.append(volume)
    volume.filepath = path
    if not volume.grids.load():
        raise LevelSetImportError(
            f"Blender cannot load '{path}': {volume.grids.error_message}")
    grid = volume.grids.get(grid_name)
    if grid is None:
        raise LevelSetImportError(f"Blender finds no grid '{grid_name}' in '{path}'")
    volume_object = bpy.data.objects.new(f"{name}_volume", volume)
    created.append(volume_object)
    collection.objects.link(volume_object)
    half_voxel = _half_voxel_world(grid)
    voxel_size_m = 2.0 * sum(half_voxel) / 3.0
    volume_object.matrix_world = Matrix.Translation(-half_voxel)

    mesh_object = bpy.data.objects.new(name, bpy.data.meshes.new(name))
    created.extend((mesh_object, mesh_object.data))
    collection.objects.link(mesh_object)
    modifier = mesh_object.modifiers.new("Volume to Mesh", "VOLUME_TO_MESH")
    modifier.object = volume_object
    modifier.grid_name = grid_name
    modifier.threshold = 0.0  # the zero level set; Blender clamps negative thresholds to 0
    modifier.resolution_mode = "GRID"  # the half-voxel correction holds for the grid's own voxels
    modifier.adaptivity = adaptivity
    modifier.use_smooth_shade = smooth_shading

    depsgraph = view_layer.depsgraph
    depsgraph.update()
    evaluated = mesh_object.evaluated_get(depsgraph)
    if len(evaluated.data.vertices) == 0:
        raise LevelSetImportError(
            f"grid '{grid_name}' of '{path}' has no zero crossing: its mesh would be empty")
    if apply_modifier:
        applied = bpy.data.meshes.new_from_object(evaluated, depsgraph=depsgraph)
        created.append(applied)
        modifier_mesh = mesh_object.data
        mesh_object.modifiers.remove(modifier)
        mesh_object.data = applied
        created.remove(modifier_mesh)
        bpy.data.meshes.remove(modifier_mesh)
        applied.name = name
    if keep_volume:
        return mesh_object, voxel_size_m
    if apply_modifier:
        for block in (volume_object, volume):
            created.remove(block)
        bpy.data.batch_remove([volume_object, volume])
    else:
        volume_object.hide_set(True, view_layer=view_layer)
        volume_object.hide_render = True
    return mesh_object, voxel_size_m


def _half_voxel_world(grid: bpy.types.VolumeGrid) -> Vector:
    """Half the grid's voxel size along world x, y and z: the shift Blender 3.4 adds to its mesh.

    Like OpenVDB's ``voxelSize()``, the size along each axis is the length of the index-to-world
    matrix column for that index axis.
    """
    index_to_world = Matrix(grid.matrix_object).to_3x3()
    return Vector([0.5 * index_to_world.col[axis].length for axis in range(3)])


class IMPORT_SCENE_OT_shinevdb_level_set(bpy.types.Operator, ImportHelper):
    """Import a level-set grid (e.g. ShineVDB's surface.vdb) as a Volume and its surface mesh"""

    bl_idname = "import_scene.shinevdb_level_set"
    bl_label = "Import ShineVDB Level Set"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".vdb"
    filter_glob: StringProperty(default="*.vdb", options={"HIDDEN"})

    grid_name: StringProperty(
        name="Grid",
        description="Name of the level-set grid to mesh",
        default=DEFAULT_GRID_NAME,
    )
    keep_volume: BoolProperty(
        name="Keep Volume",
        description="Keep the Volume object visible (otherwise it is deleted, or hidden while an "
        "unapplied modifier still reads it)",
        default=False,
    )
    apply_modifier: BoolProperty(
        name="Apply Modifier",
        description="Turn the Volume to Mesh modifier's result into plain mesh data (needed "
        "for a map's colours and intensity from mesh.ply)",
        default=True,
    )
    adaptivity: FloatProperty(
        name="Adaptivity",
        description="Merge polygons on flat areas (0 keeps one polygon per surface voxel)",
        default=0.0,
        min=0.0,
        max=1.0,
    )
    smooth_shading: BoolProperty(name="Smooth Shading", default=True)
    verify: BoolProperty(
        name="Check in a Separate Blender",
        description="Load and mesh the grid in a background Blender first, so that a corrupt "
        "file gives an error instead of crashing this Blender (costs a few seconds)",
        default=True,
    )

    def execute(self, context):
        messages: List[Message] = []
        try:
            import_level_set(
                self.filepath,
                collection=context.collection,
                view_layer=context.view_layer,
                grid_name=self.grid_name,
                keep_volume=self.keep_volume,
                apply_modifier=self.apply_modifier,
                adaptivity=self.adaptivity,
                smooth_shading=self.smooth_shading,
                verify=self.verify,
                messages=messages,
            )
        except LevelSetImportError as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        for level, text in messages:
            self.report({level}, text)
        return {"FINISHED"}


def menu_func_import(self, context):
    """Adds the entry to File › Import."""
    self.layout.operator(IMPORT_SCENE_OT_shinevdb_level_set.bl_idname,
                         text="ShineVDB level set (.vdb)")


classes = (IMPORT_SCENE_OT_shinevdb_level_set,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.TOPBAR_MT_file_import.append(menu_func_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_func_import)
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
