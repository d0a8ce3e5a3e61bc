"""Reads the structure of an OpenVDB file (header, grid descriptors, grid metadata) in pure Python.

Blender 3.4 aborts (``terminate called after throwing ...``) on a truncated or corrupt ``.vdb``
instead of reporting an error, so the importer checks a file's structure here before Blender sees
it: the magic number, the format version, every grid descriptor, and that every grid's byte range
lies inside the file. Nothing is decompressed; damage inside the voxel data is caught by
:mod:`.vdb_probe`.

Layout read here (OpenVDB file format 222 and later, i.e. OpenVDB 3 onwards; little endian)::

    int64 magic 0x56444220 ("VDB "), uint32 format version, uint32 library major, uint32 minor,
    uint8 has_grid_offsets, char[36] uuid, file metadata (MetaMap), int32 grid count,
    per grid: string unique name, string type, string instance parent,
              int64 grid position, int64 block position, int64 end position
    at each grid position: uint32 compression flags, grid metadata (MetaMap, "class" among it)

A string is a uint32 length and that many bytes; a MetaMap is an int32 count and per entry a
name, a type name, a uint32 byte count and the value bytes.
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from typing import BinaryIO, Dict, List, Optional, Tuple

_MAGIC = 0x56444220
_MIN_FORMAT_VERSION = 222  # per-grid compression flags; written by OpenVDB 3.0 and later
_UUID_CHARS = 36
_UNIQUE_NAME_SEPARATOR = "\x1e"  # OpenVDB appends "\x1e<n>" to repeated grid names
_HALF_FLOAT_SUFFIX = "_HalfFloat"


class VdbFileError(Exception):
    """A file that is not a readable OpenVDB file; the message names the file and the problem."""


@dataclass(frozen=True)
class GridInfo:
    """What the file says about one grid, without reading its voxels."""

    name: str
    tree_type: str  # e.g. "Tree_float_5_4_3"
    grid_class: str  # "level set", "fog volume", "staggered" or "unknown"
    # World position of the grid's frame (metadata "shine_origin_world_m", vec3d), if present:
    # ShineVDB keeps far-away (UTM) maps in a local frame, world = origin + local.
    origin_world_m: Optional[Tuple[float, float, float]] = None

    @property
    def value_type(self) -> str:
        """The voxel type, e.g. "float" for "Tree_float_5_4_3"."""
        parts = self.tree_type.split("_")
        return parts[1] if len(parts) > 1 and parts[0] == "Tree" else self.tree_type

    def describe(self) -> str:
        """A short description for messages, e.g. "'surface' (float, level set)"."""
        return f"'{self.name}' ({self.value_type}, {self.grid_class})"


class _Reader:
    """Bounded little-endian reads that turn running off the end into a VdbFileError."""

    def __init__(self, stream: BinaryIO, path: str, size_bytes: int):
        self._stream = stream
        self._path = path
        self.size_bytes = size_bytes

    def fail(self, problem: str) -> VdbFileError:
        return VdbFileError(f"'{self._path}' is not a valid OpenVDB file: {problem}")

    def seek(self, offset: int) -> None:
        self._stream.seek(offset)

    def read(self, count: int, what: str) -> bytes:
        offset = self._stream.tell()
        if count < 0 or offset + count > self.size_bytes:
            raise self.fail(
                f"the file is truncated or corrupt ({what} at byte {offset} needs {count} bytes, "
                f"the file has {self.size_bytes})"
            )
        return self._stream.read(count)

    def unpack(self, fmt: str, what: str):
        values = struct.unpack("<" + fmt, self.read(struct.calcsize("<" + fmt), what))
        return values[0] if len(values) == 1 else values

    def string(self, what: str) -> str:
        length = self.unpack("I", what + " length")
        return self.read(length, what).decode("utf-8", errors="replace")

    def metadata(self, what: str) -> Dict[str, bytes]:
        """Reads a MetaMap and returns the raw value bytes by name."""
        count = self.unpack("i", what + " count")
        if count < 0:
            raise self.fail(f"negative {what} count {count}")
        entries = {}
        for _ in range(count):
            name = self.string(what + " name")
            self.string(what + " type")
            entries[name] = self.read(self.unpack("I", what + " size"), f"{what} '{name}'")
        return entries


def read_grids(path: str) -> List[GridInfo]:
    """Returns the grids of the OpenVDB file at ``path``.

    Raises:
        VdbFileError: the file is missing, not an OpenVDB file, of an unsupported format version,
            truncated, or has no grids. The message names the file and the problem.
    """
    if not os.path.isfile(path):
        raise VdbFileError(f"'{path}' does not exist or is not a file")
    size_bytes = os.path.getsize(path)
    with open(path, "rb") as stream:
        reader = _Reader(stream, path, size_bytes)
        magic = reader.unpack("q", "magic number") if size_bytes >= 8 else None
        if magic != _MAGIC:
            raise reader.fail("it does not start with the OpenVDB magic number")
        version = reader.unpack("I", "format version")
        if version < _MIN_FORMAT_VERSION:
            raise reader.fail(
                f"format version {version} is older than {_MIN_FORMAT_VERSION} (OpenVDB 3.0); "
                "re-save it with a current OpenVDB"
            )
        reader.unpack("II", "library version")
        if reader.unpack("B", "grid-offset flag") == 0:
            raise reader.fail("it was written as a stream, without grid offsets; save it as a file")
        reader.read(_UUID_CHARS, "UUID")
        reader.metadata("file metadata")
        grid_count = reader.unpack("i", "grid count")
        if grid_count <= 0:
            raise reader.fail("it contains no grids")

        grids = []
        for _ in range(grid_count):
            unique_name = reader.string("grid name")
            tree_type = reader.string("grid type")
            if tree_type.endswith(_HALF_FLOAT_SUFFIX):
                tree_type = tree_type[: -len(_HALF_FLOAT_SUFFIX)]
            reader.string("instance parent name")
            grid_pos, block_pos, end_pos = reader.unpack("qqq", "grid offsets")
            name = unique_name.split(_UNIQUE_NAME_SEPARATOR)[0]
            if not 0 < grid_pos <= block_pos <= end_pos:
                raise reader.fail(f"grid '{name}' has inconsistent offsets")
            if end_pos > size_bytes:
                raise reader.fail(
                    f"the file is truncated: grid '{name}' ends at byte {end_pos}, "
                    f"the file has {size_bytes} bytes"
                )
            reader.seek(grid_pos)
            reader.unpack("I", f"compression flags of grid '{name}'")
            grid_meta = reader.metadata(f"metadata of grid '{name}'")
            grid_class = grid_meta.get("class", b"unknown").decode("utf-8", errors="replace")
            origin = grid_meta.get("shine_origin_world_m")
            origin_world_m = struct.unpack("<3d", origin) if origin and len(origin) == 24 else None
            grids.append(GridInfo(name=name, tree_type=tree_type, grid_class=grid_class,
                                  origin_world_m=origin_world_m))
            reader.seek(end_pos)
    return grids
