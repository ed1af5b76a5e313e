"""`osmap info FILE`: print the provenance osmap stored in an output, and how to remake it."""

from __future__ import annotations

import json

import click

from osmap_cli.commands.common import CONTEXT_SETTINGS
from osmap_cli.errors import OsmapError

__all__ = ["info_command"]

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
    from osmap_cli.provenance import read_provenance, reproduce_command

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
