"""`osmap apply UV MAP -o OUT`: render a saved position map on another aligned map (the work is
in osmap_cli.apply)."""

from __future__ import annotations

import os
import time

import click

from osmap_cli.commands.common import CONTEXT_SETTINGS
from osmap_cli.errors import OsmapError

__all__ = ["apply_command"]

APPLY_EPILOG = """\b
Examples:
  osmap synth rock.png -o out/rock.png --uv-out out/rock_uv.exr
  osmap apply out/rock_uv.exr rock_normal.png -o out/rock_normal.png
  osmap apply out/rock_uv.exr rock_rough.exr -o out/rock_rough.exr --bit-depth 32
  osmap apply out/marble_uv.npy marble_normal.png -o out/marble_normal.nrrd
"""


@click.command("apply", epilog=APPLY_EPILOG, context_settings=CONTEXT_SETTINGS,
               short_help="Render a saved position map (--uv-out) on another aligned map.")
@click.argument("uv", type=click.Path(path_type=str), metavar="UV")
@click.argument("maps", nargs=-1, required=True, type=click.Path(path_type=str),
                metavar="MAP...")
@click.option("-o", "--output", required=True, type=click.Path(path_type=str),
              metavar="OUTPUT", help="Output file; the extension picks the format (images: "
              ".png .exr .tif .tiff .jpg .jpeg; volumes: .npy .nrrd). An existing file is "
              "replaced (atomically).")
@click.option("--normal/--not-normal", "normal", default=None,
              help="Treat MAP as a tangent-space normal map (decoded, turned with the texture, "
              "renormalised). [default: when MAP's file name contains 'normal']")
@click.option("--bit-depth", type=click.Choice(["8", "16", "32"]), default=None,
              help="Bits per sample of OUTPUT (images). [default: as for osmap synth: the "
              "format's default, 16 for PNG/TIFF from a 16-bit or float MAP]")
@click.option("-q", "--quiet", is_flag=True, help="No summary line.")
def apply_command(uv: str, maps: tuple[str, ...], output: str, normal: bool | None,
                  bit_depth: str | None, quiet: bool) -> None:
    """Render the position map UV on MAP and write OUTPUT.

    \b
    UV is a position map written by 'osmap synth --uv-out' (.exr) or
    'osmap solid --uv-out' (.npy volume). MAP must be aligned with the
    exemplar UV was made from (same size); for a volume made from three
    exemplars give three maps, in the order of the exemplars. OUTPUT is
    pixel-aligned with the synthesized texture, and records its provenance
    (see 'osmap info').
    """
    from osmap_cli.apply import apply_image, apply_volume

    started = time.monotonic()
    for path in (uv, *maps):
        if os.path.exists(output) and os.path.exists(path) and os.path.samefile(output, path):
            raise OsmapError(f"{output}: refusing to write over an input file")
    if uv.lower().endswith(".npy"):
        apply_volume(uv, maps, output, normal)
        if not quiet:
            click.echo(f"wrote {output} ({time.monotonic() - started:.1f} s)")
        return
    if len(maps) != 1:
        raise click.UsageError(f"a 2D position map takes one MAP, got {len(maps)}")
    line = apply_image(uv, maps[0], output, normal, bit_depth)
    if not quiet:
        click.echo(f"{line} ({time.monotonic() - started:.1f} s)")
