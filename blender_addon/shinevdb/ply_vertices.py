"""Reads the vertices of a binary little-endian PLY file (``shine``'s ``mesh.ply``) in pure Python.

Blender 3.4's PLY importer makes a new object and reads colours only as ``uchar`` red/green/blue
into a face-corner attribute; the importer needs the vertex records themselves (positions,
colours, intensity) to move them onto the mesh it made from the level set. So this module parses
the header and reads the vertex element with :mod:`struct`; nothing else of the file is decoded.

What ``shine`` writes, and what is accepted::

    ply
    format binary_little_endian 1.0
    comment ...                                  (any number, e.g. shine_origin_world_m x y z)
    element vertex N
    property float x / y / z                     (then, when the map has them:)
    property uchar red / green / blue            (sRGB, 0-255)
    property float intensity                     (the LiDAR's reflectance as the sensor gives it)
    element face M
    property list uchar int vertex_indices
    end_header

Vertex properties may be any PLY scalar type and in any order; the vertex element must be the
first element (as every PLY writer puts it). A file whose header is malformed or that is not
binary little endian raises :class:`PlyFileError` in :func:`read_header`, one shorter than its
header announces in :func:`read_vertex_columns` (so a caller knows what a truncated file was
meant to hold); each message names the file and the problem.
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from typing import Dict, List, Sequence, Tuple

# PLY scalar type names (both spellings of the spec) -> struct format character.
_SCALAR_FORMATS = {
    "char": "b", "int8": "b", "uchar": "B", "uint8": "B",
    "short": "h", "int16": "h", "ushort": "H", "uint16": "H",
    "int": "i", "int32": "i", "uint": "I", "uint32": "I",
    "float": "f", "float32": "f", "double": "d", "float64": "d",
}  # fmt: skip
_MAX_HEADER_BYTES = 1 << 16  # shine's header is about 300 bytes; a longer one is not a PLY header
_MIN_POLYGON_CORNERS = 3

COLOUR_PROPERTIES = ("red", "green", "blue")
INTENSITY_PROPERTY = "intensity"


class PlyFileError(Exception):
    """A PLY file that cannot be read; the message names the file and the problem."""


@dataclass(frozen=True)
class PlyHeader:
    """What a PLY header says about the file's vertices."""

    path: str
    vertex_count: int
    vertex_properties: Tuple[Tuple[str, str], ...]  # (name, struct format character), in order
    vertex_offset_bytes: int  # where the vertex records start (the end of the header)
    min_size_bytes: int  # the smallest file size the header allows (lists at their shortest)
    size_bytes: int  # the file's size when the header was read
    elements: str  # e.g. "204435 vertex, 376234 face" for messages

    def has(self, name: str) -> bool:
        """True if the vertices have a property ``name``."""
        return any(prop == name for prop, _ in self.vertex_properties)

    @property
    def has_colour(self) -> bool:
        """True if the vertices have uchar red, green and blue properties."""
        types = dict(self.vertex_properties)
        return all(types.get(name) == "B" for name in COLOUR_PROPERTIES)

    @property
    def has_intensity(self) -> bool:
        return self.has(INTENSITY_PROPERTY)


def read_header(path: str) -> PlyHeader:
    """Parses the header of the PLY file ``path`` (the data is not checked).

    Raises:
        PlyFileError: the file is missing, not a binary little-endian PLY file, or its header is
            malformed.
    """
    if not os.path.isfile(path):
        raise PlyFileError(f"'{path}' does not exist or is not a file")
    size_bytes = os.path.getsize(path)
    with open(path, "rb") as ply:
        head = ply.read(_MAX_HEADER_BYTES)
    end = head.find(b"end_header\n")
    if not head.startswith(b"ply\n") and not head.startswith(b"ply\r\n"):
        raise _fail(path, "it does not start with 'ply'")
    if end < 0:
        raise _fail(path, f"no 'end_header' line in its first {_MAX_HEADER_BYTES} bytes "
                          "(truncated, or not a PLY file)")
    try:
        lines = head[:end].decode("ascii").splitlines()[1:]
    except UnicodeDecodeError:
        raise _fail(path, "its header is not ASCII text") from None

    elements: List[Tuple[str, int, List[Tuple[str, str, str]]]] = []  # name, count, properties
    format_seen = False
    for number, line in enumerate(lines, start=2):
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format":
            if words[1:2] != ["binary_little_endian"]:
                raise _fail(path, f"format '{' '.join(words[1:])}' is not supported; "
                                  "re-save it as binary_little_endian")
            format_seen = True
        elif words[0] == "element" and len(words) == 3 and words[2].isdigit():
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements and _valid_property(words):
            name = words[-1]
            if words[1] == "list":
                elements[-1][2].append((name, _SCALAR_FORMATS[words[2]], _SCALAR_FORMATS[words[3]]))
            else:
                elements[-1][2].append((name, _SCALAR_FORMATS[words[1]], ""))
        else:
            raise _fail(path, f"header line {number} is malformed: '{line}'")
    if not format_seen:
        raise _fail(path, "its header has no 'format' line")
    if not elements or elements[0][0] != "vertex":
        raise _fail(path, "its first element is not 'vertex'")
    _, vertex_count, vertex_props = elements[0]
    if any(list_format for _, _, list_format in vertex_props):
        raise _fail(path, "a vertex property is a list; only scalar vertex properties are read")
    for axis in "xyz":
        if not any(name == axis for name, _, _ in vertex_props):
            raise _fail(path, f"its vertices have no '{axis}' property")

    vertex_offset = end + len(b"end_header\n")
    min_size = vertex_offset
    for name, count, props in elements:
        min_size += count * _min_record_bytes(name, props)
    return PlyHeader(path=path, vertex_count=vertex_count,
                     vertex_properties=tuple((name, fmt) for name, fmt, _ in vertex_props),
                     vertex_offset_bytes=vertex_offset, min_size_bytes=min_size,
                     size_bytes=size_bytes,
                     elements=", ".join(f"{count} {name}" for name, count, _ in elements))


def read_vertex_columns(header: PlyHeader, names: Sequence[str]) -> Dict[str, tuple]:
    """Reads the vertex properties ``names`` of the file ``header`` describes, one tuple each.

    Raises:
        PlyFileError: a property is missing, or the file is shorter than its header announces.
    """
    for name in names:
        if not header.has(name):
            raise _fail(header.path, f"its vertices have no '{name}' property")
    if header.size_bytes < header.min_size_bytes:
        raise _fail(header.path, f"the file is truncated: it has {header.size_bytes} bytes, its "
                                 f"header announces at least {header.min_size_bytes} "
                                 f"({header.elements})")
    record = struct.Struct("<" + "".join(fmt for _, fmt in header.vertex_properties))
    size = header.vertex_count * record.size
    with open(header.path, "rb") as ply:
        ply.seek(header.vertex_offset_bytes)
        data = ply.read(size)
    if len(data) != size:
        raise _fail(header.path, f"the file is truncated: {len(data)} bytes of vertices, "
                                 f"its header announces {size}")
    columns = list(zip(*record.iter_unpack(data))) if header.vertex_count else []
    index = {name: position for position, (name, _) in enumerate(header.vertex_properties)}
    return {name: columns[index[name]] if columns else () for name in names}


def _valid_property(words: List[str]) -> bool:
    """True for 'property <scalar> <name>' and 'property list <scalar> <scalar> <name>'."""
    if len(words) == 3:
        return words[1] in _SCALAR_FORMATS
    return (len(words) == 5 and words[1] == "list" and words[2] in _SCALAR_FORMATS
            and words[3] in _SCALAR_FORMATS)


def _min_record_bytes(element: str, props: List[Tuple[str, str, str]]) -> int:
    """The fewest bytes one record of ``element`` can take (a polygon has at least 3 corners)."""
    size = 0
    for name, fmt, list_format in props:
        size += struct.calcsize("<" + fmt)
        if list_format and element == "face" and name in ("vertex_indices", "vertex_index"):
            size += _MIN_POLYGON_CORNERS * struct.calcsize("<" + list_format)
    return size


def _fail(path: str, problem: str) -> PlyFileError:
    return PlyFileError(f"'{path}' is not a readable binary PLY file: {problem}")
