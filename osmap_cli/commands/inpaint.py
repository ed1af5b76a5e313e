"""`osmap inpaint IMAGE --mask MASK -o OUT`: fill the masked region of IMAGE from the rest of it
(osmap_cli.synth.fill), keeping every other pixel bit for bit."""

from __future__ import annotations

import click

from osmap_cli.commands.common import CONTEXT_SETTINGS
from osmap_cli.commands.fill_common import FILL_COMMON_HELP, fill_options, plan_fill

__all__ = ["inpaint_command"]

INPAINT_HELP = """Fill the region of IMAGE that MASK marks, from the rest of IMAGE.

\b
MASK is an image of IMAGE's size: white (>= 0.5 in any colour channel)
= fill, black = keep. --mask alpha takes the region from IMAGE's own
alpha channel instead: transparent (alpha < 0.5) = fill. Every pixel
outside the region is written back bit for bit; the region is
synthesized coarse to fine, its matching windows including the kept
pixels around it, so it continues the surrounding structure. The fill
copies only pixels outside the region (never the hole's old content).
In batches, {stem} {name} {dir} in MASK refer to each image.

""" + FILL_COMMON_HELP

INPAINT_EPILOG = """\b
Examples:
  osmap inpaint photo.png --mask hole.png -o out/photo_filled.png
  osmap inpaint cutout.png --mask alpha -o out/cutout_filled.png
  osmap inpaint rock.png --mask hole.png -o out/rock.png --with normal=rock_normal.png
  osmap inpaint photo.png --mask hole.png -o out/photo.png --uv-out out/photo_uv.exr --seed 3
  osmap inpaint shots/*.png --mask '{dir}/{stem}_mask.png' --out-dir out/filled -j 2 --json
"""


@click.command("inpaint", help=INPAINT_HELP, epilog=INPAINT_EPILOG,
               short_help="Fill a masked region of an image.", context_settings=CONTEXT_SETTINGS)
@click.option("--mask", required=True, metavar="MASK|alpha",
              help="The region to fill: an image of IMAGE's size (white = fill), or 'alpha' "
              "(IMAGE's transparent pixels).")
@fill_options
def inpaint_command(mask: str, **params) -> int:
    return plan_fill("inpaint", mask=mask, **params)
