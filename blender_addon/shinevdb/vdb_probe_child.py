"""Child side of :mod:`vdb_probe`: run by a background Blender, never imported by the add-on.

Usage: ``blender --background --factory-startup --python vdb_probe_child.py -- VDB GRID RESULT``

Loads grid GRID of VDB as a Volume, meshes it at iso 0 with the Volume to Mesh modifier (which
reads every voxel) and writes ``{"ok": true, "vertices": N}`` or ``{"error": "..."}`` to the JSON
file RESULT. If OpenVDB aborts Blender, RESULT is never written and the parent reads the reason
from this process's stderr.
"""

import json
import sys

import bpy


def probe(vdb_path: str, grid_name: str) -> dict:
    """Loads and meshes the grid in this (throw-away) Blender session."""
    volume = bpy.data.volumes.new("probe")
    volume.filepath = vdb_path
    if not volume.grids.load():
        return {"error": f"Blender cannot load it ({volume.grids.error_message})"}
    if volume.grids.get(grid_name) is None:
        return {"error": "Blender finds no such grid"}
    volume_object = bpy.data.objects.new("probe_volume", volume)
    mesh_object = bpy.data.objects.new("probe_mesh", bpy.data.meshes.new("probe_mesh"))
    scene = bpy.context.scene
    scene.collection.objects.link(volume_object)
    scene.collection.objects.link(mesh_object)
    modifier = mesh_object.modifiers.new("probe", "VOLUME_TO_MESH")
    modifier.object = volume_object
    modifier.grid_name = grid_name
    modifier.threshold = 0.0
    depsgraph = bpy.context.evaluated_depsgraph_get()
    vertices = len(mesh_object.evaluated_get(depsgraph).data.vertices)
    return {"ok": True, "vertices": vertices}


def main() -> None:
    vdb_path, grid_name, result_path = sys.argv[sys.argv.index("--") + 1 :][:3]
    result = probe(vdb_path, grid_name)
    with open(result_path, "w", encoding="utf-8") as result_file:
        json.dump(result, result_file)


main()
