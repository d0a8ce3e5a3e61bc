"""ShineVDB for Blender: import ShineVDB level sets and run ``shine map`` from the 3D view.

Modules, one concern each:
    level_set_import  File › Import › ShineVDB level set (.vdb)
    vdb_header        pure-Python check of a .vdb file's structure (grids, truncation)
    vdb_probe         crash-isolated check of a grid's voxel data in a child Blender
                      (whose script is vdb_probe_child.py)
    map_colours       a map's colours and intensity (from mesh.ply) on the imported mesh
    ply_vertices      pure-Python reader of a binary PLY file's vertices
    map_job           a ``shine map`` child process and its progress lines (no Blender API)
    map_run           this session's mapping run: timer, completion, import
    map_panel         the 3D view sidebar panel and its operators
    preferences       the path of the ``shine`` executable
"""

bl_info = {
    "name": "ShineVDB",
    "author": "ShineVDB developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "File › Import › ShineVDB level set (.vdb); 3D View › Sidebar › ShineVDB",
    "description": "Import ShineVDB / OpenVDB level sets as meshes and map LiDAR scans with shine",
    "category": "Import-Export",
}

from . import level_set_import, map_panel, map_run, preferences  # noqa: E402

_MODULES = (preferences, level_set_import, map_run, map_panel)


def register():
    for module in _MODULES:
        module.register()


def unregister():
    for module in reversed(_MODULES):
        module.unregister()
