"""Reading surface samples: point clouds (PLY, XYZ, NPY, OBJ without faces) and meshes (OBJ or
PLY with faces, sampled uniformly by area), with the checks that make a bad input a one-line
OsmapError naming the file.

- .ply: ascii, binary_little_endian or binary_big_endian; a `vertex` element with x, y, z (other
  properties and elements are skipped); a `face` element with a list property vertex_indices
  (or vertex_index) makes it a mesh.
- .xyz / .txt / .pts / .csv: one point per line, the first three numbers (space or comma
  separated); blank lines and lines starting with # are skipped.
- .npy: an (n, 3) array of numbers.
- .obj: `v x y z` lines; `f` lines (v, v/vt, v/vt/vn or v//vn, negative indices allowed) make it
  a mesh; everything else is skipped.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass

import numpy as np

from osmap_cli.errors import OsmapError

POINT_EXTENSIONS = (".ply", ".xyz", ".txt", ".pts", ".csv", ".npy", ".obj")


@dataclass
class Surface:
    """What was read: vertices (n, 3) and, for a mesh, triangles (m, 3) into them."""

    vertices: np.ndarray
    triangles: np.ndarray | None = None

    @property
    def is_mesh(self) -> bool:
        return self.triangles is not None and len(self.triangles) > 0


def _name(path) -> str:
    return os.fsdecode(os.fspath(path))


# ------------------------------------------------------------------------------------------ PLY
_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


@dataclass
class _Element:
    name: str
    count: int
    props: list  # (name, type) or (name, ("list", count_type, item_type))


def _ply_header(name: str, raw: bytes) -> tuple[str, list[_Element], int]:
    end = raw.find(b"end_header")
    if not raw.startswith(b"ply") or end < 0:
        raise OsmapError(f"{name}: not a PLY file (no 'ply' magic or no end_header)")
    nl = raw.find(b"\n", end)
    body_start = len(raw) if nl < 0 else nl + 1
    try:
        header = raw[:end].decode("ascii")
    except UnicodeDecodeError:
        raise OsmapError(f"{name}: PLY header is not ASCII text") from None
    fmt = None
    elements: list[_Element] = []
    for lineno, line in enumerate(header.splitlines(), 1):
        parts = line.split()
        if not parts or parts[0] in ("ply", "comment", "obj_info"):
            continue
        try:
            if parts[0] == "format":
                fmt = parts[1]
                if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
                    raise OsmapError(f"{name}: unsupported PLY format {fmt!r}")
            elif parts[0] == "element":
                count = int(parts[2])
                if count < 0:
                    raise ValueError
                elements.append(_Element(parts[1], count, []))
            elif parts[0] == "property":
                if not elements:
                    raise ValueError
                if parts[1] == "list":
                    ct, it = _PLY_TYPES[parts[2]], _PLY_TYPES[parts[3]]
                    elements[-1].props.append((parts[4], ("list", ct, it)))
                else:
                    elements[-1].props.append((parts[2], _PLY_TYPES[parts[1]]))
            else:
                raise ValueError
        except (IndexError, KeyError, ValueError):
            raise OsmapError(f"{name}: malformed PLY header line {lineno}: {line.strip()!r}") \
                from None
    if fmt is None:
        raise OsmapError(f"{name}: PLY header has no format line")
    return fmt, elements, body_start


def _read_ply(path) -> Surface:
    name = _name(path)
    with open(path, "rb") as f:
        raw = f.read()
    fmt, elements, pos = _ply_header(name, raw)
    data: dict[str, dict[str, np.ndarray | list]] = {}
    if fmt == "ascii":
        lines = raw[pos:].decode("ascii", errors="replace").splitlines()
        lines = [ln for ln in lines if ln.strip() and not ln.startswith("comment")]
        cursor = 0
        for el in elements:
            chunk = lines[cursor:cursor + el.count]
            if len(chunk) < el.count:
                raise OsmapError(f"{name}: PLY file ends inside element '{el.name}' "
                                 f"({len(chunk)} of {el.count} lines)")
            cursor += el.count
            data[el.name] = _parse_ascii_element(name, el, chunk)
    else:
        order = "<" if fmt == "binary_little_endian" else ">"
        for el in elements:
            values, pos = _parse_binary_element(name, el, raw, pos, order)
            data[el.name] = values
    if "vertex" not in data:
        raise OsmapError(f"{name}: PLY file has no 'vertex' element")
    vert = data["vertex"]
    missing = [c for c in "xyz" if c not in vert]
    if missing:
        raise OsmapError(f"{name}: PLY vertex element lacks property {', '.join(missing)}")
    vertices = np.stack([np.asarray(vert[c], np.float64) for c in "xyz"], 1)
    faces = None
    if "face" in data:
        for key in ("vertex_indices", "vertex_index"):
            if key in data["face"]:
                faces = data["face"][key]
                break
    return Surface(vertices, _triangulate(name, faces, len(vertices)) if faces else None)


def _parse_ascii_element(name, el, lines):
    out: dict[str, list] = {p[0]: [] for p in el.props}
    simple = all(not isinstance(t, tuple) for _, t in el.props)
    if simple and lines:
        try:
            arr = np.array([ln.split()[:len(el.props)] for ln in lines], np.float64)
        except ValueError:
            arr = None
        if arr is not None and arr.ndim == 2 and arr.shape[1] == len(el.props):
            return {p[0]: arr[:, i] for i, p in enumerate(el.props)}
    for ln in lines:
        tok = ln.split()
        k = 0
        try:
            for pname, ptype in el.props:
                if isinstance(ptype, tuple):
                    n = int(tok[k])
                    if n < 0 or k + 1 + n > len(tok):
                        raise ValueError
                    out[pname].append([int(t) for t in tok[k + 1:k + 1 + n]])
                    k += 1 + n
                else:
                    out[pname].append(float(tok[k]))
                    k += 1
        except (IndexError, ValueError):
            raise OsmapError(f"{name}: malformed PLY {el.name} line {ln.strip()[:60]!r}") \
                from None
    return out


def _parse_binary_element(name, el, raw, pos, order):
    if all(not isinstance(t, tuple) for _, t in el.props):
        dtype = np.dtype([(p, order + t) for p, t in el.props])
        size = dtype.itemsize * el.count
        if pos + size > len(raw):
            raise OsmapError(f"{name}: PLY file is truncated in element '{el.name}'")
        arr = np.frombuffer(raw, dtype, el.count, pos)
        return {p: arr[p] for p, _ in el.props}, pos + size
    # elements with lists: fast path for a single list of constant length, else one by one
    if len(el.props) == 1 and el.count > 0:
        pname, (_, ct, it) = el.props[0]
        cdt, idt = np.dtype(order + ct), np.dtype(order + it)
        if pos + cdt.itemsize > len(raw):
            raise OsmapError(f"{name}: PLY file is truncated in element '{el.name}'")
        n0 = int(np.frombuffer(raw, cdt, 1, pos)[0])
        rec = np.dtype([("n", cdt), ("v", idt, (n0,))])
        if n0 > 0 and pos + rec.itemsize * el.count <= len(raw):
            arr = np.frombuffer(raw, rec, el.count, pos)
            if np.all(arr["n"] == n0):
                return {pname: arr["v"].astype(np.int64)}, pos + rec.itemsize * el.count
    out: dict[str, list] = {p[0]: [] for p in el.props}
    try:
        for _ in range(el.count):
            for pname, ptype in el.props:
                if isinstance(ptype, tuple):
                    cdt, idt = np.dtype(order + ptype[1]), np.dtype(order + ptype[2])
                    n = int(np.frombuffer(raw, cdt, 1, pos)[0])
                    pos += cdt.itemsize
                    out[pname].append(np.frombuffer(raw, idt, n, pos).tolist())
                    pos += idt.itemsize * n
                else:
                    dt = np.dtype(order + ptype)
                    out[pname].append(float(np.frombuffer(raw, dt, 1, pos)[0]))
                    pos += dt.itemsize
    except ValueError:
        raise OsmapError(f"{name}: PLY file is truncated in element '{el.name}'") from None
    return out, pos


# ------------------------------------------------------------------------------------ triangles
def _triangulate(name: str, faces, nverts: int) -> np.ndarray:
    """Fan-triangulate polygons (array (m, k) or list of lists) into (t, 3) int64."""
    if isinstance(faces, np.ndarray) and faces.ndim == 2:
        polys = [faces.astype(np.int64)]
    else:
        by_len: dict[int, list] = {}
        for f in faces:
            by_len.setdefault(len(f), []).append(f)
        polys = [np.asarray(v, np.int64) for v in by_len.values()]
    tris = []
    for p in polys:
        if p.shape[1] < 3:
            raise OsmapError(f"{name}: a face has fewer than 3 vertices")
        for k in range(1, p.shape[1] - 1):
            tris.append(np.stack([p[:, 0], p[:, k], p[:, k + 1]], 1))
    t = np.concatenate(tris) if tris else np.zeros((0, 3), np.int64)
    if len(t) and (t.min() < 0 or t.max() >= nverts):
        raise OsmapError(f"{name}: a face refers to a vertex that does not exist "
                         f"(index {int(t.max() if t.max() >= nverts else t.min())}, "
                         f"{nverts} vertices)")
    return t


# ------------------------------------------------------------------------------------ text, npy
_SPLIT = re.compile(r"[\s,;]+")


def _read_xyz(path) -> Surface:
    name = _name(path)
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except UnicodeDecodeError:
        raise OsmapError(f"{name}: not a text point file (it is not UTF-8 text)") from None
    rows = []
    for lineno, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if not s or s.startswith("#") or s.startswith("//"):
            continue
        tok = [t for t in _SPLIT.split(s) if t][:3]
        try:
            if len(tok) < 3:
                raise ValueError
            rows.append([float(t) for t in tok])
        except ValueError:
            raise OsmapError(f"{name}: line {lineno}: expected three numbers x y z, got "
                             f"{s[:60]!r}") from None
    return Surface(np.array(rows, np.float64).reshape(-1, 3))


def _read_npy(path) -> Surface:
    name = _name(path)
    try:
        arr = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError) as e:
        raise OsmapError(f"{name}: not a readable .npy array ({str(e).splitlines()[0]})") \
            from None
    if not isinstance(arr, np.ndarray) or arr.dtype.kind not in "iuf":
        raise OsmapError(f"{name}: expected a numeric (n, 3) array, got dtype "
                         f"{getattr(arr, 'dtype', type(arr))}")
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise OsmapError(f"{name}: expected an (n, 3) array of points, got shape {arr.shape}")
    return Surface(arr.astype(np.float64))


def _read_obj(path) -> Surface:
    name = _name(path)
    verts, faces = [], []
    try:
        with open(path, encoding="utf-8", errors="strict") as f:
            lines = f.read().splitlines()
    except UnicodeDecodeError:
        raise OsmapError(f"{name}: not an OBJ text file (it is not UTF-8 text)") from None
    for lineno, line in enumerate(lines, 1):
        tok = line.split()
        if not tok:
            continue
        try:
            if tok[0] == "v":
                if len(tok) < 4:
                    raise ValueError
                verts.append([float(t) for t in tok[1:4]])
            elif tok[0] == "f":
                if len(tok) < 4:
                    raise ValueError
                idx = []
                for t in tok[1:]:
                    i = int(t.split("/")[0])
                    if i == 0:
                        raise ValueError
                    idx.append(i - 1 if i > 0 else len(verts) + i)
                faces.append(idx)
        except ValueError:
            raise OsmapError(f"{name}: line {lineno}: malformed {tok[0]!r} line "
                             f"{line.strip()[:60]!r}") from None
    vertices = np.array(verts, np.float64).reshape(-1, 3)
    tris = _triangulate(name, faces, len(vertices)) if faces else None
    return Surface(vertices, tris)


READERS = {".ply": _read_ply, ".xyz": _read_xyz, ".txt": _read_xyz, ".pts": _read_xyz,
           ".csv": _read_xyz, ".npy": _read_npy, ".obj": _read_obj}


def read_surface(path) -> Surface:
    """Read a point cloud or mesh by extension; OsmapError for anything wrong with the file."""
    name = _name(path)
    ext = os.path.splitext(name)[1].lower()
    if ext not in READERS:
        raise OsmapError(f"{name}: unknown input extension {ext or '(none)'!r} "
                         f"(use {', '.join(POINT_EXTENSIONS)})")
    if not os.path.exists(name):
        raise OsmapError(f"{name}: no such file")
    if os.path.isdir(name):
        raise OsmapError(f"{name}: is a directory, not a point file")
    if os.path.getsize(name) == 0:
        raise OsmapError(f"{name}: the file is empty")
    try:
        surf = READERS[ext](path)
    except OSError as e:
        raise OsmapError(f"{name}: cannot read ({e.strerror or e})") from None
    bad = ~np.all(np.isfinite(surf.vertices), axis=1)
    if bad.any():
        first = int(np.argmax(bad))
        raise OsmapError(f"{name}: {int(bad.sum())} point(s) have NaN or infinite coordinates "
                         f"(first: point {first})")
    if len(surf.vertices) == 0:
        raise OsmapError(f"{name}: contains no points")
    return surf


# ------------------------------------------------------------------------------------- sampling
def triangle_areas(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def sample_mesh(name: str, vertices, triangles, n: int, rng: np.random.Generator) -> np.ndarray:
    """n points uniformly by area on the triangles."""
    areas = triangle_areas(vertices, triangles)
    total = areas.sum()
    if not np.isfinite(total) or total <= 1e-12 * max(1.0, np.ptp(vertices) ** 2):
        raise OsmapError(f"{name}: the mesh has zero area (all faces are degenerate)")
    tri = rng.choice(len(triangles), n, p=areas / total)
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    w = np.stack([1.0 - s, s * (1.0 - r2), s * r2], 1)
    corners = vertices[triangles[tri]]  # (n, 3, 3)
    return np.einsum("nk,nkd->nd", w, corners)


def check_points(name: str, points: np.ndarray, nodes: int) -> None:
    """Enough distinct points for the map, and not all coincident or collinear."""
    distinct = len(np.unique(points, axis=0)) if len(points) <= 2_000_000 else len(points)
    if distinct < nodes:
        raise OsmapError(f"{name}: {distinct} distinct points is fewer than the {nodes} map "
                         "nodes (use a smaller --grid or more points)")
    centred = points - points.mean(0)
    s = np.linalg.svd(centred[:: max(1, len(points) // 200_000)], compute_uv=False)
    scale = max(1.0, float(np.abs(points).max()))
    if s[0] <= 1e-9 * scale:
        raise OsmapError(f"{name}: all points coincide, there is no surface to fit")
    if s[1] <= 1e-6 * s[0]:
        raise OsmapError(f"{name}: the points are collinear, there is no surface to fit")
