"""`osmap solid`: a solid (3D) texture whose slices along x, y and z look like the exemplar.

Only click and the standard library are imported at module level; numpy, Numba and the pipeline
load when the command runs, so `osmap --help` stays fast.
"""

from __future__ import annotations

import os
import re
import sys
import time

import click

from osmap_cli.errors import OsmapError

FORMAT_CHOICES = ("npy", "png", "exr", "atlas", "nrrd")

HELP = """Synthesize a solid texture like EXEMPLAR and write it to OUT.

\b
Every voxel holds three exemplar positions, one per slice family (slices
normal to x, y and z), organised by an OS-Map on the coarsest volume and
then optimised level by level so that the slices along all three axes
match the exemplar; each voxel takes the colour most of its neighbours'
matches agree on.

\b
--x/--y/--z give one exemplar per slice family (Kopf et al. 2007): slices
normal to x (rows z, cols y), y (rows z, cols x), z (rows y, cols x) look
like that exemplar; axes not given use EXEMPLAR (which may be omitted
when all three are given). All need the same number of channels.
Anisotropic materials (wood grain along the exemplar's x): pass the grain
exemplar for two axes and an end-grain or rotated view for the third.

\b
Output (--format, else by OUT's extension):
  .npy       float32 array (Z, Y, X, C); no metadata (NumPy has none)
  folder     no extension: PNG slices slice_0000.png ... (one per z)
  exr        (--format exr) a folder of 32-bit float EXR slices
  .png       a flipbook atlas: the z slices in a grid, row-major; name it
             NAME_COLSxROWS.png to choose the grid (else near-square);
             the grid is recorded in the metadata
  .nrrd      NRRD (sizes C X Y Z, float32), --nrrd-encoding raw|gzip
PNG is 8-bit (16-bit for a 16-bit or float exemplar). PNG, EXR and NRRD
carry the provenance (osmap version, exemplar, preset, seed, options).

\b
--uv-out FILE.npy writes float32 (Z, Y, X, 3): exemplar column u, row v
and the index (0, 1, 2 = x, y, z exemplar) each voxel was copied from;
osmap_cli.solid.render_volume(uv, maps) re-renders it on aligned maps.

\b
Presets (--preset): built-in "default", "structured", "fast", or a TOML
file with a [solid] table of tunables (osmap solid does not read the
[synth] presets). --quality fast|high scales the search on top.
Memory: the working set is estimated first; a size that does not fit in
the available memory (or in OSMAP_MEMORY_LIMIT, e.g. 2G) is refused.
Same inputs, options and seed give the same bytes with any thread count.
"""

EPILOG = """\b
Examples:
  osmap solid marble.png -o marble.npy --size 128
  osmap solid marble.png -o marble_slices --size 96x64x128 --preview marble.png
  osmap solid granite.png -o granite_8x16.png --size 128 --tileable
  osmap solid --x end.png --y side.png --z side.png -o wood.nrrd --size 64
  osmap solid gravel.png -o gravel.npy --size 64 --uv-out gravel_uv.npy --seed 3
"""


class VolumeSize(click.ParamType):
    """N (a cube) or XxYxZ."""

    name = "N|XxYxZ"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        text = str(value).strip()
        match = (re.fullmatch(r"(\d{1,9})\s*[xX]\s*(\d{1,9})\s*[xX]\s*(\d{1,9})", text)
                 or re.fullmatch(r"(\d{1,9})", text))
        if match is None:
            self.fail(f"{value!r} is not N or XxYxZ (examples: 128, 128x64x32)", param, ctx)
        digits = [int(d) for d in match.groups()]
        x, y, z = digits if len(digits) == 3 else digits * 3
        from osmap_cli.solid.options import MAX_SIDE

        if min(x, y, z) < 8 or max(x, y, z) > MAX_SIDE:
            self.fail(f"{value!r}: every side must be between 8 and {MAX_SIDE}", param, ctx)
        return (x, y, z)


@click.command("solid", help=HELP, epilog=EPILOG,
               short_help="Synthesize a solid (3D) texture.",
               context_settings={"help_option_names": ["-h", "--help"],
                                 "max_content_width": 100})
@click.argument("exemplar", required=False, type=click.Path(path_type=str), metavar="[EXEMPLAR]")
@click.option("-o", "--output", "output", required=True, type=click.Path(path_type=str),
              metavar="OUT", help="Output volume: .npy, .nrrd, .png (atlas) or a folder "
              "(slices). Replaced atomically if it exists.")
@click.option("--size", type=VolumeSize(), default="128", show_default=True,
              help="Volume size in voxels: N for NxNxN, or XxYxZ.")
@click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=0, show_default=True,
              help="Random seed; the same seed gives the same volume.")
@click.option("--preset", default="default", show_default=True, metavar="NAME|FILE.toml",
              help="Solid preset: default, structured, fast, or a TOML file with [solid].")
@click.option("--quality", type=click.Choice(("fast", "default", "high")), default="default",
              show_default=True, help="Speed / quality trade-off on top of the preset.")
@click.option("--tileable", is_flag=True, help="The volume wraps around in x, y and z.")
@click.option("--x", "ex_x", type=click.Path(path_type=str), default=None, metavar="FILE",
              help="Exemplar for the slices normal to x (rows z, cols y).")
@click.option("--y", "ex_y", type=click.Path(path_type=str), default=None, metavar="FILE",
              help="Exemplar for the slices normal to y (rows z, cols x).")
@click.option("--z", "ex_z", type=click.Path(path_type=str), default=None, metavar="FILE",
              help="Exemplar for the slices normal to z (rows y, cols x).")
@click.option("--format", "fmt", type=click.Choice(FORMAT_CHOICES), default=None,
              help="Output format [default: from OUT's extension; a folder: png slices].")
@click.option("--nrrd-encoding", type=click.Choice(("raw", "gzip")), default="raw",
              show_default=True, help="Data encoding of a NRRD output.")
@click.option("--preview", type=click.Path(path_type=str), default=None, metavar="FILE.png",
              help="Also write a preview: the cube in isometric view and its centre slices.")
@click.option("--uv-out", type=click.Path(path_type=str), default=None, metavar="FILE.npy",
              help="Also write float32 (Z, Y, X, 3): exemplar u (column), v (row), index.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
def solid_command(exemplar, output, size, seed, preset, quality, tileable, ex_x, ex_y, ex_z,
                  fmt, nrrd_encoding, preview, uv_out, quiet):
    started = time.monotonic()
    from osmap_cli.solid.options import SolidOptions, load_solid_preset

    try:
        loaded = load_solid_preset(preset)
    except OsmapError as exc:
        if preset.lower().endswith(".toml") or os.sep in preset:
            raise
        raise click.BadParameter(str(exc).removeprefix("--preset: "),
                                 param_hint="'--preset'") from None
    x, y, z = size
    options = SolidOptions().replace(**loaded.values).replace(
        width=x, height=y, depth=z, seed=seed, quality=quality, tileable=tileable).validated()

    # inputs
    axis_files = [ex_x, ex_y, ex_z]
    if exemplar is None and None in axis_files:
        raise click.UsageError("give EXEMPLAR, or all three of --x, --y and --z")
    from osmap_cli.imageio import read_image

    if all(f is None for f in axis_files):
        images = [read_image(exemplar)]
        names = [exemplar]
    else:
        files = [f if f is not None else exemplar for f in axis_files]
        cache = {}
        for f in files:
            if f not in cache:
                cache[f] = read_image(f)
        images = [cache[f] for f in files]
        names = files
        channels = {im.pixels.shape[2] for im in images}
        if len(channels) != 1:
            counts = ", ".join(f"{n}: {im.pixels.shape[2]}" for n, im in zip(names, images))
            raise OsmapError(f"per-axis exemplars need the same number of channels ({counts})")
    for name, im in zip(names, images):
        if min(im.pixels.shape[:2]) < 8:
            raise OsmapError(f"{name}: exemplar is smaller than 8x8 pixels")

    # outputs, checked before any work
    from osmap_cli.solid import volumeio

    kind = volumeio.format_for(output, fmt)
    volumeio.check_target(output, kind)
    channels = images[0].pixels.shape[2]
    depth = 16 if max(im.bit_depth for im in images) >= 16 else 8
    if kind in ("png", "atlas") and channels > 4:
        raise OsmapError(f"{output}: PNG stores at most 4 channels, the exemplar has {channels}; "
                         "use --format exr, npy or nrrd")
    if kind == "atlas":
        volumeio.atlas_grid(output, z)
    targets = [os.path.abspath(output.rstrip("/" + os.sep))]
    for flag, path, ext in (("--preview", preview, ".png"), ("--uv-out", uv_out, ".npy")):
        if path is None:
            continue
        if os.path.splitext(path)[1].lower() != ext:
            raise click.BadParameter(f"{path}: must be a {ext} file", param_hint=f"'{flag}'")
        if os.path.abspath(path) in targets:
            raise click.BadParameter(f"{path}: is the same file as another output",
                                     param_hint=f"'{flag}'")
        targets.append(os.path.abspath(path))
        volumeio.check_target(path, "npy")

    from osmap_cli.solid.memory import check_memory

    check_memory(options.shape, channels, options.feature_dims)

    # the work
    from osmap_cli.progress import ProgressBar
    from osmap_cli.solid.pipeline import synthesize_solid

    show_bar = not quiet and sys.stderr.isatty()
    with ProgressBar(enabled=show_bar, desc="osmap solid") as progress:
        result = synthesize_solid([im.pixels for im in images], options, progress=progress)

    # the outputs, all or nothing
    metadata = provenance(options, loaded.name, names)
    staged = []
    try:
        staged.append(volumeio.stage_volume(
            output, result.voxels, kind, depth=depth, channel_names=images[0].channel_names,
            metadata=metadata, encoding=nrrd_encoding))
        if uv_out is not None:
            staged.append(volumeio.stage_npy(uv_out, result.uv()))
        if preview is not None:
            staged.append(_stage_preview(preview, result.voxels, metadata))
        volumeio.commit(staged)
        staged = []
    finally:
        volumeio.discard(staged)

    if not quiet:
        line = f"wrote {output}: {x}x{y}x{z} voxels, {channels} channel" \
               f"{'s' * (channels != 1)}, {kind}"
        if kind == "atlas":
            cols, rows = volumeio.atlas_grid(output, z)
            line += f" {cols}x{rows}"
        extras = [p for p in (uv_out, preview) if p is not None]
        if extras:
            line += "; also " + ", ".join(extras)
        click.echo(f"{line} ({time.monotonic() - started:.1f} s)")


def _stage_preview(path, voxels, metadata):
    from osmap_cli.imageio import write_image
    from osmap_cli.solid.preview import render_preview
    from osmap_cli.solid.volumeio import Staged, _temp_for

    temp = _temp_for(path) + ".png"
    try:
        write_image(temp, render_preview(voxels), 8, metadata=metadata)
    except OsmapError as exc:
        raise OsmapError(str(exc).replace(temp, path)) from None
    return Staged(temp, path)


def provenance(options, preset_name: str, exemplars) -> dict[str, str]:
    """The metadata every output carries (the keys of `osmap synth`)."""
    import dataclasses
    import json

    from osmap_cli import __version__

    names = [os.path.basename(n) for n in exemplars]
    return {
        "software": f"osmap {__version__}",
        "osmap_version": __version__,
        "command": "solid",
        "exemplar": names[0] if len(set(names)) == 1 else ",".join(names),
        "preset": preset_name,
        "seed": str(options.seed),
        "options": json.dumps(dataclasses.asdict(options), sort_keys=True),
    }
