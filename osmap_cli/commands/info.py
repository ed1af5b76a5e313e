"""`osmap info FILE`: read back the provenance osmap stored in an output (osmap_cli.provenance
writes it), and the command line that makes it again."""

from __future__ import annotations

import json
import os
import shlex

import click

from osmap_cli.commands.common import CONTEXT_SETTINGS
from osmap_cli.errors import OsmapError

__all__ = ["info_command", "read_provenance", "reproduce_command"]

INFO_EPILOG = """\b
Examples:
  osmap info out/cells.png
  osmap info out/cells.exr --json | jq -r .seed
  osmap info out/marble.nrrd
  eval "$(osmap info out/cells.png --command)"    # writes out/cells.png again, same bytes
"""

# printed first, in this order; other keys follow sorted
_ORDER = ("software", "command", "role", "exemplar", "exemplar_size", "preset", "seed", "args")


@click.command("info", epilog=INFO_EPILOG, context_settings=CONTEXT_SETTINGS,
               short_help="Print the provenance stored in an osmap output.")
@click.argument("path", type=click.Path(path_type=str), metavar="FILE")
@click.option("--json", "as_json", is_flag=True,
              help="Print the stored key/value pairs as one JSON object (plus \"reproduce\").")
@click.option("--command", "command_only", is_flag=True,
              help="Print only the command line that writes FILE again.")
def info_command(path: str, as_json: bool, command_only: bool) -> None:
    """Print the provenance stored in FILE by osmap, and the command line that
    writes the same bytes again.

    \b
    FILE is an image osmap wrote (PNG text chunks, EXR header, TIFF/JPEG
    description), a NRRD volume ("osmap:KEY:=VALUE" fields) or a mesh osmap
    carve wrote (glTF asset extras, OBJ/MTL/PLY comments). The command
    names the input files as they were named (no folders): run it where they
    are. A file without osmap metadata is an error (exit 1).
    """
    meta = read_provenance(path)
    if not meta:
        raise OsmapError(f"{path}: no osmap provenance in this file")
    command = reproduce_command(meta, path)
    if command_only:
        if command is None:
            raise OsmapError(f"{path}: the provenance does not say how to remake this file")
        click.echo(command)
        return
    if as_json:
        click.echo(json.dumps({**meta, "reproduce": command}, sort_keys=True))
        return
    keys = [k for k in _ORDER if k in meta] + sorted(k for k in meta if k not in _ORDER)
    width = max(len(k) for k in keys)
    click.echo(f"{'file':<{width}}  {path}")
    for key in keys:
        value = meta[key]
        if key == "options":
            value = json.dumps(json.loads(value), sort_keys=True) if _is_json(value) else value
        click.echo(f"{key:<{width}}  {value}")
    if command is not None:
        click.echo(f"{'reproduce':<{width}}  {command}")


def _is_json(text: str) -> bool:
    try:
        json.loads(text)
    except ValueError:
        return False
    return True


def read_provenance(path: str) -> dict[str, str]:
    """The osmap key/value pairs stored in an image, a NRRD volume or a carved mesh."""
    if os.path.isdir(path):
        raise OsmapError(f"{path}: is a directory (give one slice file)")
    if not os.path.isfile(path):
        raise OsmapError(f"{path}: no such file")
    with open(path, "rb") as handle:
        if handle.read(4) == b"NRRD":
            from osmap_cli.solid.volumeio import read_nrrd_header

            handle.seek(0)
            return read_nrrd_header(handle, path)[1]
    if path.lower().endswith((".glb", ".gltf", ".obj", ".mtl", ".ply")):
        from osmap_cli.carving.meshio import read_mesh_provenance

        return read_mesh_provenance(path)
    if path.lower().endswith(".npy"):
        raise OsmapError(f"{path}: .npy files cannot store metadata (no provenance)")
    from osmap_cli.imageio import read_metadata

    return read_metadata(path)


def reproduce_command(meta: dict[str, str], path: str) -> str | None:
    """The command line that writes `path` again (None when the metadata cannot tell)."""
    command = meta.get("command")
    args = shlex.split(meta.get("args", ""))
    if command == "carve" and "args" in meta:
        from osmap_cli.carving.job import reproduce

        return reproduce(meta, path)
    if command == "apply" and meta.get("uv") and meta.get("map"):
        return shlex.join(["osmap", "apply", meta["uv"], meta["map"], "-o", path, *args])
    if command not in ("synth", "solid", "inpaint", "tileable") or "args" not in meta:
        return None
    inputs = shlex.split(meta["inputs"]) if "inputs" in meta else [meta.get("exemplar", "")]
    role = meta.get("role", "image")
    output = path
    stem, ext = os.path.splitext(path)
    if command == "solid":
        output, args = _volume_output(path, meta, args)
    elif role.startswith("with:") and stem.endswith("_" + role[5:]):
        output = stem[: -len(role[5:]) - 1] + ext
    elif role == "uv":
        output = stem + "_image" + meta.get("image_ext", ".png")
        args += ["--uv-out", path]
    return shlex.join(["osmap", command, *inputs, "-o", output, *args])


def _volume_output(path: str, meta: dict[str, str], args: list[str]) -> tuple[str, list[str]]:
    """(-o, flags) of `osmap solid` for one of its files: a slice names its folder, a preview
    (a PNG that is neither a slice nor an atlas) is written beside a volume, a NRRD keeps its
    encoding."""
    ext = os.path.splitext(path)[1].lower()
    if "slice" in meta:
        folder = os.path.dirname(path) or "."
        return folder, args + (["--format", "exr"] if ext == ".exr" else [])
    if ext == ".png" and "atlas_grid" not in meta:
        return os.path.splitext(path)[0] + "_volume.npy", args + ["--preview", path]
    if ext == ".nrrd":
        from osmap_cli.solid.volumeio import read_nrrd_header

        with open(path, "rb") as handle:
            encoding = read_nrrd_header(handle, path)[0].get("encoding", "raw")
        if encoding != "raw":
            args = args + ["--nrrd-encoding", encoding]
    return path, args
