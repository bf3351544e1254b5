"""A small binary PLY reader for the meshes in a vtgen dataset's ``models/`` folder.

The header is parsed generically: any number of elements with scalar properties (read as one
numpy structured array each) and a ``face`` element whose single list property holds the vertex
indices of triangles (``list uchar int vertex_indices`` in vtgen files).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np

_SCALAR_TYPES: Dict[str, str] = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}

_FORMATS = {"binary_little_endian": "<", "binary_big_endian": ">"}


class PlyError(ValueError):
    """A PLY file is malformed or uses a feature this reader does not support."""


class _Property:
    __slots__ = ("name", "dtype", "count_dtype")

    def __init__(self, name: str, dtype: str, count_dtype: Optional[str] = None) -> None:
        self.name = name
        self.dtype = dtype
        self.count_dtype = count_dtype  # set for list properties

    @property
    def is_list(self) -> bool:
        return self.count_dtype is not None


class _Element:
    __slots__ = ("name", "count", "properties")

    def __init__(self, name: str, count: int) -> None:
        self.name = name
        self.count = count
        self.properties: List[_Property] = []


def _scalar(type_name: str, order: str, path: Path) -> str:
    try:
        return order + _SCALAR_TYPES[type_name]
    except KeyError:
        raise PlyError(f"{path}: unknown PLY property type {type_name!r}") from None


def _parse_header(data: bytes, path: Path) -> Tuple[str, List[_Element], int]:
    """Return (byte-order char, elements, offset of the body)."""
    if not data.startswith(b"ply"):
        raise PlyError(f"{path}: not a PLY file (no 'ply' magic)")
    end = data.find(b"\nend_header")
    if end < 0:
        raise PlyError(f"{path}: PLY header has no end_header line")
    body = data.find(b"\n", end + 1)
    if body < 0:
        raise PlyError(f"{path}: PLY header is not terminated by a newline")
    lines = data[:end].decode("ascii", errors="strict").splitlines()
    order: Optional[str] = None
    elements: List[_Element] = []
    for line in lines[1:]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format":
            if len(words) != 3 or words[1] not in _FORMATS:
                raise PlyError(
                    f"{path}: unsupported PLY format {' '.join(words[1:])!r} "
                    "(binary_little_endian or binary_big_endian only)"
                )
            order = _FORMATS[words[1]]
        elif words[0] == "element":
            if len(words) != 3:
                raise PlyError(f"{path}: malformed PLY line {line!r}")
            elements.append(_Element(words[1], int(words[2])))
        elif words[0] == "property":
            if not elements or order is None:
                raise PlyError(f"{path}: PLY property before format/element: {line!r}")
            if len(words) == 5 and words[1] == "list":
                prop = _Property(
                    words[4], _scalar(words[3], order, path), _scalar(words[2], order, path)
                )
            elif len(words) == 3:
                prop = _Property(words[2], _scalar(words[1], order, path))
            else:
                raise PlyError(f"{path}: malformed PLY line {line!r}")
            elements[-1].properties.append(prop)
        else:
            raise PlyError(f"{path}: unexpected PLY header line {line!r}")
    if order is None:
        raise PlyError(f"{path}: PLY header has no format line")
    return order, elements, body + 1


def _read_element(
    data: bytes, offset: int, element: _Element, path: Path
) -> Tuple[np.ndarray, int]:
    """Read one element into a structured array; return it and the offset after it."""
    lists = [p for p in element.properties if p.is_list]
    fields: List[Tuple[Any, ...]] = []
    for prop in element.properties:
        if prop.is_list:
            # Only fixed-length lists (triangles) are supported: read them as count + 3 items and
            # check every count below.
            fields.append((prop.name + "#count", prop.count_dtype))
            fields.append((prop.name, prop.dtype, (3,)))
        else:
            fields.append((prop.name, prop.dtype))
    dtype = np.dtype(fields)
    size = dtype.itemsize * element.count
    if offset + size > len(data):
        raise PlyError(
            f"{path}: PLY body too short for {element.count} {element.name!r} elements"
        )
    array = np.frombuffer(data, dtype=dtype, count=element.count, offset=offset)
    for prop in lists:
        counts = array[prop.name + "#count"]
        if counts.size and not np.all(counts == 3):
            bad = int(np.argmax(counts != 3))
            raise PlyError(
                f"{path}: {element.name!r} element {bad} has {int(counts[bad])} vertex indices; "
                "only triangles are supported"
            )
    return array, offset + size


def load_ply(path: Union[str, "os.PathLike[str]"]) -> Dict[str, Optional[np.ndarray]]:
    """Read a binary PLY triangle mesh.

    Returns ``{"vertices": (N, 3) float32, "normals": (N, 3) float32 or None if the vertices have
    no ``nx ny nz``, "faces": (M, 3) int32}``. Every array is C-contiguous and owns its memory.
    """
    path = Path(path)
    data = path.read_bytes()
    order, elements, offset = _parse_header(data, path)
    arrays: Dict[str, np.ndarray] = {}
    for element in elements:
        array, offset = _read_element(data, offset, element, path)
        arrays[element.name] = array
    if "vertex" not in arrays:
        raise PlyError(f"{path}: PLY file has no vertex element")
    vertex = arrays["vertex"]
    names = vertex.dtype.names or ()

    def columns(keys: Tuple[str, str, str]) -> Optional[np.ndarray]:
        if not all(k in names for k in keys):
            return None
        return np.stack([vertex[k].astype(np.float32) for k in keys], axis=1)

    vertices = columns(("x", "y", "z"))
    if vertices is None:
        raise PlyError(f"{path}: PLY vertices have no x y z properties")
    normals = columns(("nx", "ny", "nz"))

    faces = np.zeros((0, 3), dtype=np.int32)
    if "face" in arrays:
        face_lists = [p for e in elements if e.name == "face" for p in e.properties if p.is_list]
        if len(face_lists) != 1:
            raise PlyError(f"{path}: PLY face element must have exactly one list property")
        faces = np.array(arrays["face"][face_lists[0].name], dtype=np.int32, order="C")
        n = vertices.shape[0]
        if faces.size and (faces.min() < 0 or faces.max() >= n):
            raise PlyError(f"{path}: face vertex index out of range for {n} vertices")
    return {"vertices": vertices, "normals": normals, "faces": faces}
