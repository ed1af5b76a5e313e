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
--exemplar EX (repeatable) fills the region from EX instead of from
the rest of IMAGE (EX needs IMAGE's channels; an EX without alpha is
taken as opaque when IMAGE has alpha); the kept pixels around the region
still steer the fill. Not with --with or --uv-out (the exemplars have
no aligned maps, and positions in several images have no single image
to refer to). In batches, {stem} {name} {dir} in MASK and EX refer to
each image.

""" + FILL_COMMON_HELP

INPAINT_EPILOG = """\b
Examples:
  osmap inpaint photo.png --mask hole.png -o out/photo_filled.png
  osmap inpaint cutout.png --mask alpha -o out/cutout_filled.png
  osmap inpaint rock.png --mask hole.png -o out/rock.png --with normal=rock_normal.png
  osmap inpaint wall.png --mask hole.png --exemplar bricks.png -o out/wall.png
  osmap inpaint wall.png --mask alpha --exemplar b1.png --exemplar b2.png -o out/w.png
  osmap inpaint photo.png --mask hole.png -o out/photo.png --uv-out out/photo_uv.exr --seed 3
  osmap inpaint shots/*.png --mask '{dir}/{stem}_mask.png' --out-dir out/filled -j 2 --json
"""


@click.command("inpaint", help=INPAINT_HELP, epilog=INPAINT_EPILOG,
               short_help="Fill a masked region of an image.", context_settings=CONTEXT_SETTINGS)
@click.option("--mask", required=True, metavar="MASK|alpha",
              help="The region to fill: an image of IMAGE's size (white = fill), or 'alpha' "
              "(IMAGE's transparent pixels).")
@click.option("--exemplar", "exemplars", multiple=True, type=click.Path(path_type=str),
              metavar="EX", help="Fill the region from this image instead of from the rest of "
              "IMAGE (same channels). Repeatable: the fill draws from all of them. Not with "
              "--with or --uv-out.")
@fill_options
def inpaint_command(mask: str, exemplars: tuple[str, ...], **params) -> int:
    return plan_fill("inpaint", mask=mask, exemplars=exemplars, **params)
