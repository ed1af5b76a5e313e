"""`osmap tileable IMAGE -o OUT [--border N]`: the same image, made to tile seamlessly by
re-synthesizing bands along its edges (osmap_cli.synth.fill); the centre is kept bit for bit."""

from __future__ import annotations

import click

from osmap_cli.commands.common import CONTEXT_SETTINGS
from osmap_cli.commands.fill_common import FILL_COMMON_HELP, fill_options, plan_fill
from osmap_cli.options import option_spec
from osmap_cli.synth.options import FillOptions

__all__ = ["tileable_command"]

TILEABLE_HELP = """Make IMAGE tile seamlessly: re-synthesize bands along its edges.

\b
The pixels closer than --border to an edge are synthesized again, from
the whole image, with the output wrapping around (its right edge
continues into its left, its bottom into its top), while every pixel
farther in is kept bit for bit. The result has IMAGE's size and tiles
without seams. A wider border gives the synthesis more room to hide the
transition; it must leave a centre (at most half the shorter side).
--occupancy penalises the bands' repeated use of one part of IMAGE (the
kept centre is not counted); --occupancy 0 lets them repeat it.

""" + FILL_COMMON_HELP

TILEABLE_EPILOG = """\b
Examples:
  osmap tileable photo.png -o out/photo_tile.png
  osmap tileable photo.png -o out/photo_tile.png --border 24 --seed 2
  osmap tileable rock.png -o out/rock_tile.png --with normal=rock_normal.png
  osmap tileable photos/*.jpg --out-dir out/tiles --name '{stem}_tile.png' -j 2
"""

_BORDER = option_spec(FillOptions, "border")


@click.command("tileable", help=TILEABLE_HELP, epilog=TILEABLE_EPILOG,
               short_help="Make a photo tile seamlessly.", context_settings=CONTEXT_SETTINGS)
@click.option("--border", type=click.IntRange(int(_BORDER.lo), int(_BORDER.hi)),
              default=_BORDER.default, show_default=True, metavar="N",
              help="Width of the re-synthesized bands, pixels (0: an eighth of the shorter "
              "side, at least 8).")
@fill_options
def tileable_command(border: int, **params) -> int:
    return plan_fill("tileable", border=border, **params)
