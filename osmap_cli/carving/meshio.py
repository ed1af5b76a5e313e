"""Mesh files through trimesh: reading (OBJ + MTL, PLY, glTF / GLB, STL) into a carve Mesh, and
writing the carved mesh (GLB / glTF with the texture embedded, OBJ + MTL + texture, PLY with
vertex colours) with osmap's provenance, as bytes for an output transaction.

Provenance: glTF keeps it in the asset's `extras` (key "osmap"), OBJ and MTL in `# osmap:KEY=VALUE`
comment lines, PLY in `comment osmap:KEY=VALUE` header lines; `read_mesh_provenance` reads
them back (`osmap info`).
"""

from __future__ import annotations

import base64
import contextlib
import json
import logging
import os

import numpy as np

from osmap_cli.carving.mesh import Mesh
from osmap_cli.errors import OsmapError

__all__ = ["MESH_INPUTS", "MESH_OUTPUTS", "mesh_files", "read_mesh", "read_mesh_provenance"]

MESH_INPUTS = (".obj", ".ply", ".glb", ".gltf", ".stl")
MESH_OUTPUTS = (".glb", ".gltf", ".obj", ".ply")
META_KEY = "osmap"


@contextlib.contextmanager
def _quiet_trimesh():
    """trimesh reports what it skips through `logging`; carve reports problems itself."""
    logger = logging.getLogger("trimesh")
    level, propagate = logger.level, logger.propagate
    logger.setLevel(logging.CRITICAL)
    logger.propagate = False
    try:
        yield
    finally:
        logger.setLevel(level)
        logger.propagate = propagate


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text[:200]


def read_geometry(path: str, extensions=MESH_INPUTS):
    """(vertices float64 (n, 3), triangles int64 (m, 3), uv float64 (n, 2) or None) of every mesh
    and point cloud in the file, scene transforms applied (m is 0 for a point cloud); UVs when
    every mesh has them. OsmapError for a file that cannot be read."""
    name = os.fsdecode(path)
    ext = os.path.splitext(name)[1].lower()
    if ext not in extensions:
        raise OsmapError(f"{name}: unsupported mesh format {ext or '(no extension)'!r} (use "
                         f"{', '.join(extensions)})")
    if not os.path.exists(name):
        raise OsmapError(f"{name}: no such file")
    if not os.path.isfile(name):
        raise OsmapError(f"{name}: not a regular file")
    if os.path.getsize(name) == 0:
        raise OsmapError(f"{name}: the file is empty")
    import trimesh

    try:
        with _quiet_trimesh(), np.errstate(all="ignore"):
            scene = trimesh.load(name, force="scene", process=False)
            parts = _placed_parts(scene, (trimesh.Trimesh, trimesh.PointCloud))
    except OSError as exc:
        raise OsmapError(f"{name}: cannot read ({exc.strerror or exc})") from None
    except Exception as exc:  # noqa: BLE001 - any parser failure is a bad input file
        raise OsmapError(f"{name}: not a mesh trimesh can read ({_one_line(exc)})") from None
    vertices, faces, uvs = [np.zeros((0, 3))], [np.zeros((0, 3), np.int64)], []
    start = 0
    for part, matrix in parts:
        v = np.asarray(part.vertices, np.float64)
        if v.ndim != 2 or v.shape[1] != 3:
            raise OsmapError(f"{name}: vertices need three coordinates x y z")
        vertices.append(v @ matrix[:3, :3].T + matrix[:3, 3])
        if isinstance(part, trimesh.Trimesh):
            faces.append(np.asarray(part.faces, np.int64).reshape(-1, 3) + start)
            uv = getattr(part.visual, "uv", None) if part.visual.kind == "texture" else None
            uvs.append(None if uv is None or len(uv) != len(v) else np.asarray(uv, np.float64))
        else:
            uvs.append(None)
        start += len(v)
    uv = np.concatenate(uvs) if uvs and all(u is not None for u in uvs) else None
    return np.concatenate(vertices), np.concatenate(faces), uv


def read_mesh(path: str) -> Mesh:
    """The triangles of every mesh in the file (see read_geometry) as a carve Mesh."""
    vertices, faces, uv = read_geometry(path)
    return Mesh(vertices, faces, uv, os.fsdecode(path))


def _placed_parts(scene, kind) -> list:
    """[(geometry, 4x4 transform)] of every instance of a KIND geometry in the scene (read from
    the scene graph: Scene.dump copies materials, which needs Pillow for textured files)."""
    parts = []
    for node in scene.graph.nodes_geometry:
        matrix, geometry = scene.graph[node]
        part = scene.geometry.get(geometry)
        if isinstance(part, kind):
            parts.append((part, np.asarray(matrix, np.float64)))
    return parts


# ---------------------------------------------------------------------------------------------
# writing


def _trimesh(vertices, faces, normals, uv=None, colours=None):
    import trimesh
    from trimesh.visual import ColorVisuals, TextureVisuals
    from trimesh.visual.material import PBRMaterial

    if colours is not None:
        visual = ColorVisuals(vertex_colors=colours)
    elif uv is not None:
        visual = TextureVisuals(uv=uv, material=PBRMaterial(
            name="osmap_carved", baseColorFactor=[255, 255, 255, 255], metallicFactor=0.0,
            roughnessFactor=1.0))
    else:
        visual = None
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, vertex_normals=normals,
                           visual=visual, process=False, validate=False)
    return mesh


def _texture_to_tree(tree: dict, image: dict) -> None:
    """Point the material at texture 0 made of IMAGE (a glTF image record)."""
    tree.setdefault("images", []).append(image)
    tree.setdefault("samplers", []).append({"magFilter": 9729, "minFilter": 9987,
                                            "wrapS": 33071, "wrapT": 33071})
    tree.setdefault("textures", []).append({"source": len(tree["images"]) - 1,
                                            "sampler": len(tree["samplers"]) - 1})
    for material in tree.get("materials", []):
        material.setdefault("pbrMetallicRoughness", {})["baseColorTexture"] = {
            "index": len(tree["textures"]) - 1}


def _clean_tree(tree: dict, metadata: dict) -> None:
    tree["asset"]["generator"] = metadata.get("software", "osmap")
    tree["asset"]["extras"] = {META_KEY: dict(metadata)}
    for key in ("images", "textures", "samplers"):
        if key in tree and not tree[key]:
            del tree[key]
    for mesh in tree.get("meshes", []):
        if mesh.get("extras") == {}:
            del mesh["extras"]


def gltf_bytes(binary: bool, vertices, faces, normals, uv, colours, png: bytes | None,
               metadata: dict) -> bytes:
    """A GLB (BINARY) or a self-contained glTF (buffers and texture as data URIs): UVs when
    given, the texture PNG as the base colour when given, else vertex COLOURS when given."""
    from trimesh.exchange import gltf

    mesh = _trimesh(vertices, faces, normals, uv=uv,
                    colours=None if colours is None else _rgba(colours))

    def add_texture_glb(buffer_items, tree):
        if png is not None:
            pad = (-len(png)) % 4
            buffer_items["osmap-texture"] = png + b"\0" * pad
            _texture_to_tree(tree, {"bufferView": len(buffer_items) - 1,
                                    "mimeType": "image/png"})

    def finish(tree):
        if not binary and png is not None:
            uri = "data:image/png;base64," + base64.b64encode(png).decode("ascii")
            _texture_to_tree(tree, {"uri": uri, "mimeType": "image/png"})
        _clean_tree(tree, metadata)

    with _quiet_trimesh():
        if binary:
            return gltf.export_glb(mesh, include_normals=True, tree_postprocessor=finish,
                                   buffer_postprocessor=add_texture_glb)
        files = gltf.export_gltf(mesh, include_normals=True, merge_buffers=True,
                                 embed_buffers=True, tree_postprocessor=finish)
    return files["model.gltf"]


def _rgba(colours) -> np.ndarray:
    """uint8 (n, 4): float colours rounded to 8 bits; grey as RGB, alpha 255 when absent."""
    colours = np.asarray(colours, np.float32)
    if colours.shape[1] <= 2:
        grey = np.repeat(colours[:, :1], 3, axis=1)
        colours = np.concatenate([grey, colours[:, 1:]], axis=1)
    rgba = np.full((len(colours), 4), 255, np.uint8)
    rgba[:, :colours.shape[1]] = np.rint(np.clip(colours, 0.0, 1.0) * 255.0).astype(np.uint8)
    return rgba


def _comment_lines(metadata: dict, prefix: str) -> str:
    return "".join(f"{prefix}{META_KEY}:{k}={' '.join(str(v).split())}\n"
                   for k, v in metadata.items())


def obj_bytes(vertices, faces, normals, uv, mtl_name: str, texture_name: str,
              metadata: dict) -> tuple[bytes, bytes]:
    """(OBJ, MTL): the MTL's material maps the texture file TEXTURE_NAME (relative to it)."""
    from trimesh.exchange import obj

    mesh = _trimesh(vertices, faces, normals, uv=uv)
    with _quiet_trimesh():
        text, files = obj.export_obj(mesh, include_normals=True, include_texture=True,
                                     return_texture=True, write_texture=False,
                                     mtl_name=mtl_name, header=None)
    mtl = files[mtl_name].decode("utf-8").rstrip("\n") + f"\nmap_Kd {texture_name}\n"
    header = _comment_lines(metadata, "# ")
    return (header + text).encode("utf-8"), (header + mtl).encode("utf-8")


def ply_bytes(vertices, faces, normals, colours, metadata: dict) -> bytes:
    """A binary PLY with per-vertex colours (RGBA, 8 bits a channel), normals and the provenance
    as header comments."""
    from trimesh.exchange import ply

    mesh = _trimesh(vertices, faces, normals, colours=_rgba(colours))
    with _quiet_trimesh():
        data = ply.export_ply(mesh, encoding="binary", vertex_normal=True)
    head, sep, body = data.partition(b"end_header\n")
    lines = [ln for ln in head.decode("ascii").splitlines(keepends=True)
             if not ln.startswith("comment ")]
    comments = _comment_lines(metadata, "comment ").encode("utf-8", "replace")
    return "".join(lines[:2]).encode("ascii") + comments + \
        "".join(lines[2:]).encode("ascii") + sep + body


def mesh_files(path: str, vertices, faces, normals, uv, colours, png, texture_path,
               metadata: dict) -> list[tuple[str, bytes]]:
    """[(target, bytes)]: the mesh file at PATH (and the MTL beside an OBJ)."""
    ext = os.path.splitext(path)[1].lower()
    if ext in (".glb", ".gltf"):
        return [(path, gltf_bytes(ext == ".glb", vertices, faces, normals, uv, colours, png,
                                  metadata))]
    if ext == ".ply":
        return [(path, ply_bytes(vertices, faces, normals, colours, metadata))]
    mtl = mtl_path(path)
    texture_name = os.path.relpath(os.path.abspath(texture_path),
                                   os.path.dirname(os.path.abspath(mtl))).replace(os.sep, "/")
    obj_data, mtl_data = obj_bytes(vertices, faces, normals, uv, os.path.basename(mtl),
                                   texture_name, metadata)
    return [(path, obj_data), (mtl, mtl_data)]


def mtl_path(obj_path: str) -> str:
    """The MTL written beside an OBJ: same folder and stem."""
    return os.path.splitext(obj_path)[0] + ".mtl"


# ---------------------------------------------------------------------------------------------
# provenance


def read_mesh_provenance(path: str) -> dict[str, str]:
    """The osmap key/value pairs of a mesh file carve wrote ({} when there are none)."""
    ext = os.path.splitext(path)[1].lower()
    with open(path, "rb") as handle:
        data = handle.read()
    if ext in (".glb", ".gltf"):
        try:
            if data[:4] == b"glTF":
                length = int.from_bytes(data[12:16], "little")
                tree = json.loads(data[20:20 + length])
            else:
                tree = json.loads(data)
            found = tree.get("asset", {}).get("extras", {}).get(META_KEY, {})
        except (ValueError, AttributeError):
            return {}
        return {str(k): str(v) for k, v in found.items()} if isinstance(found, dict) else {}
    prefix = {".ply": "comment ", ".obj": "# ", ".mtl": "# "}.get(ext)
    if prefix is None:
        return {}
    if ext == ".ply":
        data = data.partition(b"end_header")[0]
    meta = {}
    for line in data.decode("utf-8", "replace").splitlines():
        if line.startswith(prefix + META_KEY + ":"):
            key, _, value = line[len(prefix) + len(META_KEY) + 1:].partition("=")
            meta[key] = value
        elif ext != ".ply" and line and not line.startswith("#"):
            break  # past the OBJ's comment header
    return meta
