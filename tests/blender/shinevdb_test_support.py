"""Shared helpers of the Blender tests (run inside ``blender --background``).

Each test script is started by ctest as
``blender --background --factory-startup --python-exit-code 1 --python test_X.py -- ARGS``
with ``BLENDER_USER_SCRIPTS`` pointing into the test's own work directory, so the add-on is
installed from its zip exactly as a user would, without touching the user's Blender.
"""

from __future__ import annotations

import argparse
import os
import shutil
import struct
import sys
from dataclasses import dataclass
from typing import Tuple

import bpy
import numpy as np
from mathutils import Vector
from mathutils.bvhtree import BVHTree
from mathutils.kdtree import KDTree

ADDON_MODULE = "shinevdb"
SURFACE_TOLERANCE_VOXELS = 0.1  # the bound: vertex-to-surface distance < 1/10 voxel
# Quads split along the other diagonal can make a sliver's nearest PLY triangle a neighbour
# around a sharp crease; a flipped winding would give about 0.
MIN_ORIENTATION_AGREEMENT = 0.99


def parse_args(*names: str) -> argparse.Namespace:
    """Parses the ``--name value`` arguments after Blender's ``--``."""
    parser = argparse.ArgumentParser()
    for name in names:
        parser.add_argument(f"--{name}", required=True)
    return parser.parse_args(sys.argv[sys.argv.index("--") + 1 :])


def expect(condition: bool, message: str) -> None:
    """Fails the test (Blender exits with 1 through --python-exit-code) unless ``condition``."""
    if not condition:
        raise AssertionError(message)


def fresh_dir(path: str) -> str:
    """Empties (or creates) a test's work directory and returns it."""
    shutil.rmtree(path, ignore_errors=True)
    os.makedirs(path)
    return path


def install_addon(zip_path: str, work_dir: str) -> None:
    """Installs and enables the add-on from its zip into the user-scripts directory, which must
    be inside the test's (freshly emptied) work directory, never the user's own."""
    user_scripts = os.environ.get("BLENDER_USER_SCRIPTS", "")
    expect(user_scripts != "" and os.path.realpath(user_scripts).startswith(
        os.path.realpath(work_dir) + os.sep),
        f"BLENDER_USER_SCRIPTS ({user_scripts!r}) must be a directory inside {work_dir}")
    expect(bpy.ops.preferences.addon_install(filepath=zip_path) == {"FINISHED"},
           f"installing {zip_path} failed")
    expect(bpy.ops.preferences.addon_enable(module=ADDON_MODULE) == {"FINISHED"},
           "enabling the add-on failed")
    module = sys.modules[ADDON_MODULE]
    expect(os.path.realpath(module.__file__).startswith(os.path.realpath(user_scripts)),
           f"the enabled add-on is {module.__file__}, not the copy installed in {user_scripts}")


def clear_scene() -> None:
    """Deletes every object, mesh and volume (the factory scene's cube, camera and light too)."""
    bpy.data.batch_remove(list(bpy.data.objects) + list(bpy.data.meshes) + list(bpy.data.volumes))


def read_ply(path: str) -> Tuple[np.ndarray, np.ndarray]:
    """Reads a binary little-endian triangle PLY as written by ``shine``: (vertices, triangles).

    Vertex properties may be any scalar types (x, y, z are used); faces must be one
    ``list uchar int|uint vertex_indices`` property with three indices each.
    """
    records, triangles = read_ply_records(path)
    return np.stack([records[axis] for axis in "xyz"], axis=1).astype(np.float64), triangles


def read_ply_records(path: str) -> Tuple[np.ndarray, np.ndarray]:
    """As :func:`read_ply`, but the vertices as a structured array of all their properties, as
    stored (e.g. ``records["red"]`` uint8 for ``shine map``'s colours)."""
    scalar = {"char": "i1", "uchar": "u1", "short": "<i2", "ushort": "<u2", "int": "<i4",
              "uint": "<u4", "float": "<f4", "double": "<f8"}
    with open(path, "rb") as ply:
        expect(ply.readline().strip() == b"ply", f"{path} is not a PLY file")
        vertex_fields, face_count, vertex_count, element = [], 0, 0, None
        while True:
            words = ply.readline().decode("ascii").split()
            if words == ["end_header"]:
                break
            if words[0] == "format":
                expect(words[1] == "binary_little_endian", f"{path}: format {words[1]}")
            elif words[0] == "element":
                element = words[1]
                if element == "vertex":
                    vertex_count = int(words[2])
                elif element == "face":
                    face_count = int(words[2])
            elif words[0] == "property" and element == "vertex":
                vertex_fields.append((words[2], scalar[words[1]]))
            elif words[0] == "property" and element == "face":
                expect(words[1:3] == ["list", "uchar"] and words[3] in ("int", "uint"),
                       f"{path}: unsupported face property {' '.join(words)}")
        vertex_dtype = np.dtype(vertex_fields)
        vertex_data = np.frombuffer(ply.read(vertex_dtype.itemsize * vertex_count), vertex_dtype)
        face_dtype = np.dtype([("count", "u1"), ("indices", "<i4", 3)])
        faces = np.frombuffer(ply.read(face_dtype.itemsize * face_count), face_dtype)
    expect(bool(np.all(faces["count"] == 3)), f"{path}: only triangles are supported")
    return vertex_data, faces["indices"].astype(np.int64)


def evaluated_mesh(obj: bpy.types.Object) -> Tuple[np.ndarray, np.ndarray]:
    """World-space vertices and fan-triangulated faces of ``obj`` after its modifiers."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        local = np.empty(3 * len(mesh.vertices))
        mesh.vertices.foreach_get("co", local)
        local = local.reshape(-1, 3)
        loops = np.empty(len(mesh.loops), np.int64)
        mesh.loops.foreach_get("vertex_index", loops)
        starts = np.empty(len(mesh.polygons), np.int64)
        sizes = np.empty(len(mesh.polygons), np.int64)
        mesh.polygons.foreach_get("loop_start", starts)
        mesh.polygons.foreach_get("loop_total", sizes)
    finally:
        evaluated.to_mesh_clear()
    triangles = [np.stack([loops[starts[sizes > k]], loops[starts[sizes > k] + k - 1],
                           loops[starts[sizes > k] + k]], axis=1) for k in range(2, sizes.max())]
    matrix = np.array(obj.matrix_world)
    world = local @ matrix[:3, :3].T + matrix[:3, 3]
    return world, np.concatenate(triangles)


def used_vertices(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The vertices some triangle uses (OpenVDB's mesher also returns a few unused points)."""
    used = np.zeros(len(vertices), bool)
    used[triangles.ravel()] = True
    return vertices[used]


def nearest_vertices(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """For each point, the nearest of ``vertices`` (the PLY's vertex order is shine's own: it
    meshes in columns, so vertices are matched by position, not by index)."""
    return vertices[nearest_vertex_indices(points, vertices)]


def nearest_vertex_indices(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """For each point, the index of the nearest of ``vertices``."""
    tree = KDTree(len(vertices))
    for index, vertex in enumerate(vertices.tolist()):
        tree.insert(vertex, index)
    tree.balance()
    return np.array([tree.find(point)[1] for point in points.tolist()], np.int64)


def check_colour_material(mesh: bpy.types.Mesh, label: str) -> None:
    """The mesh's only material is the add-on's ``ShineVDB colour``, whose Principled BSDF takes
    its Base Color from an Attribute node reading ``Col``."""
    expect([m.name for m in mesh.materials] == ["ShineVDB colour"],
           f"{label}: materials {[m.name for m in mesh.materials]}")
    nodes = mesh.materials[0].node_tree
    base_colour = next(node for node in nodes.nodes
                       if node.type == "BSDF_PRINCIPLED").inputs["Base Color"]
    sources = [link.from_node for link in nodes.links if link.to_socket == base_colour]
    expect(len(sources) == 1 and sources[0].type == "ATTRIBUTE"
           and sources[0].attribute_name == "Col" and sources[0].name == "Col",
           f"{label}: Base Color does not come from an Attribute node 'Col': {sources}")


@dataclass
class SurfaceDistance:
    """Point-to-surface distances and the mean nearest-point offset per axis."""

    distances: np.ndarray
    mean_offset: np.ndarray  # mean of (point - nearest surface point), per world axis

    def max(self) -> float:
        return float(self.distances.max())

    def describe(self, voxel_size_m: float) -> str:
        """E.g. "max 0.4100 mm (0.0041 voxel); mean ...; p99 ...; mean offset x, y, z (...) mm"."""
        parts = []
        for label, value in (("max", self.distances.max()), ("mean", self.distances.mean()),
                             ("p99", np.percentile(self.distances, 99))):
            parts.append(f"{label} {1000 * value:.4f} mm ({value / voxel_size_m:.2g} voxel)")
        offset = ", ".join(f"{1000 * value:+.4f}" for value in self.mean_offset)
        return "; ".join(parts) + f"; mean offset x, y, z ({offset}) mm"


def surface_distance(points: np.ndarray, vertices: np.ndarray,
                     triangles: np.ndarray) -> SurfaceDistance:
    """Distance from each point to the nearest triangle of (vertices, triangles)."""
    tree = BVHTree.FromPolygons(vertices.tolist(), triangles.tolist(), all_triangles=True)
    distances = np.empty(len(points))
    offsets = np.empty((len(points), 3))
    for index, point in enumerate(points.tolist()):
        nearest, _normal, _face, distance = tree.find_nearest(Vector(point))
        expect(nearest is not None, f"no surface near {point}")
        distances[index] = distance
        offsets[index] = (point[0] - nearest[0], point[1] - nearest[1], point[2] - nearest[2])
    return SurfaceDistance(distances=distances, mean_offset=offsets.mean(axis=0))


def orientation_agreement(vertices: np.ndarray, triangles: np.ndarray, ply_vertices: np.ndarray,
                          ply_triangles: np.ndarray) -> float:
    """Fraction of triangles whose normal points the same way as the nearest PLY triangle's."""
    corners = vertices[triangles]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    tree = BVHTree.FromPolygons(ply_vertices.tolist(), ply_triangles.tolist(), all_triangles=True)
    agreeing = 0
    for centre, normal in zip(corners.mean(axis=1).tolist(), normals.tolist()):
        _nearest, ply_normal, _face, _distance = tree.find_nearest(Vector(centre))
        agreeing += ply_normal.dot(Vector(normal)) > 0.0
    return agreeing / len(triangles)


def check_coincides(obj: bpy.types.Object, ply_path: str, voxel_size_m: float,
                    label: str) -> None:
    """Checks that ``obj``'s evaluated mesh and the PLY lie within a tenth of a voxel of each other
    and face the same way.

    Both directions are measured (every used vertex of one to the other's triangles), so a
    missing or extra piece of surface fails as well as an offset.
    """
    ply_vertices, ply_triangles = read_ply(ply_path)
    vertices, triangles = evaluated_mesh(obj)
    to_ply = surface_distance(used_vertices(vertices, triangles), ply_vertices, ply_triangles)
    to_blender = surface_distance(used_vertices(ply_vertices, ply_triangles), vertices, triangles)
    print(f"{label}: Blender vertices to {os.path.basename(ply_path)}: "
          f"{to_ply.describe(voxel_size_m)}")
    print(f"{label}: {os.path.basename(ply_path)} vertices to Blender's mesh: "
          f"{to_blender.describe(voxel_size_m)}")
    agreement = orientation_agreement(vertices, triangles, ply_vertices, ply_triangles)
    print(f"{label}: {100 * agreement:.3f} % of the triangles face the same way as the PLY's")
    expect(agreement > MIN_ORIENTATION_AGREEMENT,
           f"{label}: only {100 * agreement:.2f} % of the triangles face as in the PLY")
    limit_m = SURFACE_TOLERANCE_VOXELS * voxel_size_m
    expect(to_ply.max() < limit_m,
           f"{label}: a Blender vertex is {to_ply.max():.5f} m from the PLY (limit {limit_m} m)")
    expect(to_blender.max() < limit_m,
           f"{label}: a PLY vertex is {to_blender.max():.5f} m from Blender's mesh "
           f"(limit {limit_m} m)")


def _read_string(data: bytes, offset: int) -> Tuple[str, int]:
    (length,) = struct.unpack_from("<I", data, offset)
    return data[offset + 4 : offset + 4 + length].decode(), offset + 4 + length


def _skip_metadata(data: bytes, offset: int) -> int:
    """Returns the offset after the OpenVDB MetaMap at ``offset``."""
    (count,) = struct.unpack_from("<i", data, offset)
    offset += 4
    for _ in range(count):
        _, offset = _read_string(data, offset)  # name
        _, offset = _read_string(data, offset)  # type name
        (size,) = struct.unpack_from("<I", data, offset)
        offset += 4 + size
    return offset


def _string_bytes(text: str) -> bytes:
    return struct.pack("<I", len(text)) + text.encode()


# Bytes of the maps shine's grids use (openvdb/math/Maps.h, write()): 5 or 6 Vec3d.
_MAP_BYTES = {"UniformScaleMap": 120, "ScaleMap": 120, "UniformScaleTranslateMap": 144,
              "ScaleTranslateMap": 144}


def append_empty_grid(path: str, name: str, tree_type: str, background: bytes) -> None:
    """Appends a grid without voxels to the OpenVDB file ``path``, with the first grid's transform.

    OpenVDB's Python module is not in Debian's Blender, so this writes the file format directly
    (openvdb/io/Archive.cc writeGrid): a descriptor (name, type, parent, grid/block/end offsets),
    the compression flags, a MetaMap with the class and name, the transform, and an empty tree's
    topology (buffer count 1, the background value, no tiles, no children; no buffers follow).
    Used to give a map the ``color`` / ``intensity`` grids the importer looks for; it reads only
    their descriptors, never their voxels.
    """
    with open(path, "rb") as vdb:
        data = bytearray(vdb.read())
    count_offset = _skip_metadata(data, 8 + 4 + 8 + 1 + 36)  # magic, version, library, flag, uuid
    (grid_count,) = struct.unpack_from("<i", data, count_offset)
    offset = count_offset + 4
    for _ in range(3):  # the first grid's unique name, type and instance parent
        _, offset = _read_string(data, offset)
    (grid_pos,) = struct.unpack_from("<q", data, offset)
    transform_start = _skip_metadata(data, grid_pos + 4)  # after the compression flags
    map_type, map_start = _read_string(data, transform_start)
    expect(map_type in _MAP_BYTES, f"{path}: transform '{map_type}' is not supported here")
    transform = bytes(data[transform_start : map_start + _MAP_BYTES[map_type]])

    descriptor = _string_bytes(name) + _string_bytes(tree_type) + _string_bytes("")
    new_grid_pos = len(data) + len(descriptor) + 3 * 8
    metadata = struct.pack("<i", 2)
    for key, value in (("class", "unknown"), ("name", name)):  # Blender looks grids up by "name"
        metadata += _string_bytes(key) + _string_bytes("string") + _string_bytes(value)
    body = struct.pack("<I", 0) + metadata + transform
    topology = struct.pack("<i", 1) + background + struct.pack("<II", 0, 0)
    block_pos = new_grid_pos + len(body) + len(topology)
    data += descriptor + struct.pack("<qqq", new_grid_pos, block_pos, block_pos) + body + topology
    struct.pack_into("<i", data, count_offset, grid_count + 1)
    with open(path, "wb") as vdb:
        vdb.write(data)


def write_ply(path: str, vertices: np.ndarray, triangles: np.ndarray,
              extra: Tuple[Tuple[str, np.ndarray], ...] = ()) -> None:
    """Writes a binary little-endian triangle PLY as shine does, with more vertex properties
    ``extra`` ((name, values), uint8 values as uchar, float32 as float) after x, y, z."""
    ply_types = {np.dtype("u1"): "uchar", np.dtype("<f4"): "float"}
    fields = [(axis, "<f4") for axis in "xyz"] + [(name, values.dtype.str)
                                                  for name, values in extra]
    records = np.empty(len(vertices), np.dtype(fields))
    for axis, column in zip("xyz", vertices.T):
        records[axis] = column
    for name, values in extra:
        records[name] = values
    header = ["ply", "format binary_little_endian 1.0", "comment written by the Blender tests",
              f"element vertex {len(vertices)}"]
    header += [f"property float {axis}" for axis in "xyz"]
    header += [f"property {ply_types[values.dtype]} {name}" for name, values in extra]
    header += [f"element face {len(triangles)}", "property list uchar int vertex_indices",
               "end_header"]
    faces = np.empty(len(triangles), np.dtype([("count", "u1"), ("indices", "<i4", 3)]))
    faces["count"] = 3
    faces["indices"] = triangles
    with open(path, "wb") as ply:
        ply.write(("\n".join(header) + "\n").encode("ascii"))
        ply.write(records.tobytes())
        ply.write(faces.tobytes())
