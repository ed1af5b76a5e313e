"""`osmap synth`: a texture like the exemplar, for one exemplar (-o) or a batch (--out-dir).

The command checks every option and plans every output (names, formats, collisions, inputs never
overwritten) before any work, then runs one osmap_cli.synth.job.SynthJob per exemplar.
"""

from __future__ import annotations

import os

import click

from osmap_cli.commands.common import (
    CONTEXT_SETTINGS,
    SizeType,
    batch_options,
    check_destination,
    cluster_spec,
    expand_inputs,
    image_outputs,
    input_fields,
    load_preset,
    parse_withs,
    real_paths,
    refusal,
    resolve_options,
    run_batch,
    show_progress,
    tuning_flags,
)
from osmap_cli.options import option_spec
from osmap_cli.synth.options import METHODS, QUALITIES, SynthOptions

__all__ = ["NAME_FIELDS", "synth_command"]

_DEFAULTS = SynthOptions()

SYNTH_HELP = """Synthesize a texture like EXEMPLAR and write it to OUTPUT.

\b
EXEMPLAR is a PNG, EXR, TIFF or JPEG image with any number of channels
(alpha is synthesized with the colour). The output format follows the
extension of OUTPUT: .png (8/16-bit), .exr (16 = half, 32 = float),
.tif/.tiff (8/16/32-bit), .jpg/.jpeg (8-bit, no alpha). The output keeps
the exemplar's channels and their names.

\b
Batches: give several exemplars (or "-" to read paths from stdin, one per
line) with --out-dir DIR; each output is named by --name TEMPLATE
(default "{stem}.{ext}"). Template fields: {stem} exemplar name without
extension, {name} with extension, {ext} its extension (no dot), {parent}
name of its folder, {index} 1-based position in the list, {width},
{height}, {seed}, {preset}, {quality}; Python format specs work
({index:03d}). A failing exemplar does not stop the others: one error line
each, a summary at the end, exit 1. In --out-dir mode an existing output
is kept (the job is reported "skipped", not a failure) unless --overwrite;
-o always replaces the one file it names. An output that would replace an
input (exemplar, --with map or field) is always refused.

\b
Option precedence, lowest to highest: built-in defaults, the --preset,
tuning flags given here (--levels, --sweeps, ...); --quality then scales
the work (fast: about half the sweeps; high: more sweeps and candidates).

\b
--uv-out writes, for every output pixel, the exemplar position it was
copied from: a 2-channel float EXR, channel "u" = exemplar column (x) and
"v" = exemplar row (y), in exemplar pixels, (0, 0) = centre of the
top-left exemplar pixel. 'osmap apply' renders it on any aligned map.

\b
Control fields (docs/fields.md): --orientation-field is added to
--orientation per pixel: a gray image (8/16-bit: 0..1 = 0..360 degrees
counter-clockwise; float EXR/TIFF: degrees) or a vector image (R = x
right, G = y up; 8/16-bit: 2v-1). --scale-field multiplies --scale per
pixel: a gray image (8/16-bit: 0..1 = 0.5..2 as 2^(2v-1), mid gray = 1;
float: the factor itself). Fields of any size are resized to the output.

\b
Guided synthesis (docs/guide.md): --target-guide GUIDE makes the output
follow GUIDE where the exemplar follows its --guide (a painted mask, a
gradient, a height map; same size as the exemplar). Without --guide the
exemplar's blurred luminance is its guide, so --target-guide photo.png
lays the texture out along the photo's shapes (faintly at the default
weight; --guide-weight 2 to 3 shows them, with some smeared patches).
Guides are gray images (RGB(A): their luminance), values as stored
(8/16-bit: 0..1); GUIDE of any size is resized to the output.
--guide-weight (default 1) sets how strongly the output follows it.

Same inputs, options and seed give the same output, whatever the number of
threads (NUMBA_NUM_THREADS) or -j, byte for byte in every format. Outputs
are written atomically: on any error nothing is written for that job.
Every output records its provenance; 'osmap info FILE' prints it with the
command line that writes the same bytes again.

\b
Exit codes: 0 every job written or skipped, 1 a job failed (bad input,
unwritable output, runtime failure), 2 usage error, 130 interrupted.
"""

SYNTH_EPILOG = """\b
Examples:
  osmap synth samples/cells.png -o out/cells.png
  osmap synth samples/cells.png -o out/cells_512x256.png --size 512x256 --seed 7
  osmap synth samples/gravel.png -o out/gravel.png --preset stochastic --quality high
  osmap synth samples/weave.png -o out/weave.png --scale 2 --orientation 30 --anisotropy 1.5
  osmap synth samples/cells.png -o out/cells_tile.png --tileable
  osmap synth samples/cells_rgba.png -o out/cells.exr --bit-depth 32 --uv-out out/cells_uv.exr
  osmap synth samples/brick.png -o out/brick_paper.png --method paper --size 128
  osmap synth samples/cells.png -o out/cells.png --preset my_preset.toml --levels 3
  osmap synth samples/*.png --out-dir out/batch --name '{stem}_{width}x{height}.png' -j 2
  ls samples/*.png | osmap synth - --out-dir out/batch --json --size 128 > jobs.jsonl
  osmap synth rock.png -o out/rock.png --with normal=rock_normal.png --with rock_rough.png
  osmap synth samples/weave.png -o out/weave_knot.png --orientation-field knot.png
  osmap synth rock_a.png --also rock_b.png --also rock_c.png -o out/rock.png
  osmap synth moss_rock.png --guide moss_mask.png --target-guide letters.png -o out/m.png
  osmap synth samples/cells.png --target-guide photo.jpg -o out/cells_photo.png
"""



@click.command("synth", help=SYNTH_HELP, epilog=SYNTH_EPILOG, short_help="Synthesize a texture.",
               context_settings=CONTEXT_SETTINGS)
@click.argument("exemplars", nargs=-1, required=True, type=click.Path(path_type=str),
                metavar="EXEMPLAR...")
@click.option(
    "-o",
    "--output",
    "output",
    default=None,
    type=click.Path(path_type=str),
    metavar="OUTPUT",
    help="Output image (one exemplar); the extension (.png .exr .tif .tiff .jpg .jpeg) picks "
    "the format. An existing file is replaced (atomically).",
)
@click.option("--out-dir", type=click.Path(path_type=str), default=None, metavar="DIR",
              help="Write each exemplar's output into DIR (created if missing), named by "
              "--name; an existing output is kept unless --overwrite.")
@click.option("--name", "name_template", default=None, metavar="TEMPLATE",
              help="Output file name in --out-dir (fields above). [default: {stem}.{ext}]")
@batch_options
@click.option("--size", type=SizeType(), default=str(_DEFAULTS.width), show_default=True,
              help="Output size in pixels: WxH (e.g. 512x256) or N for NxN.")
@click.option("--seed", type=int, default=_DEFAULTS.seed, show_default=True,
              help="Random seed (a whole number >= 0); the same seed gives the same output.")
@click.option(
    "--preset",
    default="default",
    show_default=True,
    metavar="NAME|FILE.toml",
    help="Tuning preset: a built-in name (see 'osmap presets') or a TOML file.",
)
@click.option("--scale", type=float, default=_DEFAULTS.scale, show_default=True,
              help="Feature size relative to the exemplar (2 = features twice as large).")
@click.option("--orientation", type=float, default=_DEFAULTS.orientation, show_default=True,
              metavar="DEG", help="Rotate the texture counter-clockwise by DEG degrees.")
@click.option("--anisotropy", type=float, default=_DEFAULTS.anisotropy, show_default=True,
              metavar="R", help="Stretch features by R along the (rotated) exemplar x axis.")
@click.option("--orientation-field", type=click.Path(path_type=str), default=None,
              metavar="FIELD", help="Image of the texture's direction per output pixel, added "
              "to --orientation (encoding above).")
@click.option("--scale-field", type=click.Path(path_type=str), default=None, metavar="FIELD",
              help="Image of the feature size per output pixel, times --scale (encoding "
              "above).")
@click.option("--tileable", is_flag=True,
              help="Make the output wrap around seamlessly (tiles without visible seams).")
@click.option("--quality", type=click.Choice(QUALITIES), default="default", show_default=True,
              help="Speed / quality trade-off applied on top of the preset.")
@click.option(
    "--method",
    type=click.Choice(METHODS),
    default="osmap",
    show_default=True,
    help="osmap: the full pipeline (OS-Map layout + coherence refinement); "
    "paper: the published OS-Map unchanged, one node per output pixel.",
)
@click.option(
    "--bit-depth",
    type=click.Choice(["8", "16", "32"]),
    default=None,
    help="Bits per sample of OUTPUT: PNG 8/16, EXR 16 (half) / 32 (float), TIFF 8/16/32, "
    "JPEG 8. [default: the format's default (EXR: 16), but 16 for PNG/TIFF when the "
    "exemplar has 16 bits or more, 32 for TIFF from a float exemplar]",
)
@click.option("--with", "with_maps", multiple=True, metavar="[NAME=]MAP",
              help="An extra map aligned with the exemplar (normal, roughness, ...), rendered "
              "with the same positions and written as <output stem>_NAME<ext>; NAME defaults "
              "to MAP's stem, a NAME containing 'normal' keeps unit normals. Repeatable; "
              "{stem} {name} {dir} in MAP refer to each exemplar.")
@click.option(
    "--uv-out",
    type=click.Path(path_type=str),
    default=None,
    metavar="FILE.exr",
    help='Also write the exemplar position of every output pixel: float EXR, channels "u" '
    '(column, x) and "v" (row, y) in exemplar pixels. With --out-dir: a name template '
    "(e.g. '{stem}_uv.exr') in DIR.",
)
@click.option("--also", "also", multiple=True, type=click.Path(path_type=str), metavar="EX",
              help="Another exemplar of the same material (same channels): the output draws "
              "from all of them. Repeatable; {stem} {name} {dir} refer to each EXEMPLAR. Not "
              "with --with, --uv-out, control fields or --method paper.")
@click.option("--target-guide", type=click.Path(path_type=str), default=None, metavar="GUIDE",
              help="Guided synthesis: the output follows this image (gray, or RGB(A) as its "
              "luminance; any size, resized to the output) where the exemplar follows its "
              "--guide; --guide-weight sets how strongly. Not with --also or --method paper.")
@click.option("--guide", type=click.Path(path_type=str), default=None, metavar="GUIDE",
              help="The exemplar's guide for --target-guide (one exemplar; same size as it). "
              "[default: the exemplar's own luminance, blurred and stretched to 0..1]")
@click.option("-q", "--quiet", is_flag=True,
              help="No progress bar, no summary line, no warnings (errors are still shown).")
@click.option("--verbose", is_flag=True,
              help="The summary line also says what the exemplar's analysis found: the "
              "lattice the output keeps (--lattice).")
@tuning_flags(SynthOptions)
def synth_command(exemplars: tuple[str, ...], output: str | None, out_dir: str | None,
                  name_template: str | None, jobs: int, fail_fast: bool, json_lines: bool,
                  overwrite: bool, scheduler: str | None, scheduler_file: str | None,
                  threads: int | None, size: tuple[int, int], seed: int, preset: str,
                  scale: float, orientation: float, anisotropy: float,
                  orientation_field: str | None, scale_field: str | None, tileable: bool,
                  quality: str, method: str, bit_depth: str | None,
                  with_maps: tuple[str, ...], uv_out: str | None, also: tuple[str, ...],
                  target_guide: str | None, guide: str | None, quiet: bool, verbose: bool,
                  **tuning) -> int:
    # 1. preset and options (no image work yet)
    cluster = cluster_spec(scheduler, scheduler_file, threads, jobs)
    loaded = load_preset(preset, "synth")
    _check_size(size)
    options = resolve_options(
        SynthOptions, loaded.values,
        {"width": size[0], "height": size[1], "seed": seed, "scale": scale,
         "orientation": orientation, "anisotropy": anisotropy, "tileable": tileable,
         "quality": quality, "method": method},
        tuning,
    )
    if (orientation_field or scale_field) and method != "osmap":
        raise click.UsageError("--orientation-field and --scale-field need --method osmap")
    _check_also(also, with_maps, uv_out, orientation_field or scale_field, method)
    _check_lattice(options.lattice, orientation_field or scale_field, method)
    _check_guides(guide, target_guide, also, method, exemplars)

    # 2. the inputs and where their outputs go
    inputs = expand_inputs(exemplars)
    withs = parse_withs(with_maps)

    from osmap_cli.presets import is_preset_path
    from osmap_cli.synth.job import SynthJob

    preset_name = os.path.basename(preset) if is_preset_path(preset) else preset
    preset_values = None if is_preset_path(preset) else dict(loaded.values)
    plans = _plan_outputs(inputs, output, out_dir, name_template, uv_out, withs, options,
                          preset_name, bit_depth, overwrite)
    from osmap_cli.materials import expand_path

    extra = {exemplar: tuple(expand_path(a, exemplar) for a in also) for exemplar in inputs}
    input_paths = real_paths([*inputs, *(spec.path for _, _, ws, _ in plans for spec, _ in ws),
                              orientation_field, scale_field, guide, target_guide,
                              *(p for paths in extra.values() for p in paths)])
    job_list = []
    for index, (exemplar, main, maps, uv) in enumerate(plans, 1):
        refused = refusal([main, *(o for _, o in maps), *([uv] if uv else [])], input_paths)
        job_list.append(SynthJob(
            index=index, exemplar=exemplar, output=main, options=options, preset=preset_name,
            preset_values=preset_values, bit_depth=bit_depth, uv_out=uv,
            withs=tuple(maps),
            orientation_field=orientation_field, scale_field=scale_field,
            guide=guide, target_guide=target_guide,
            also=extra[exemplar], replace=output is not None or overwrite, refused=refused,
            progress=show_progress(quiet, jobs), quiet=quiet, verbose=verbose,
            label="osmap synth" if len(plans) == 1 else os.path.basename(exemplar),
        ))
    return run_batch(job_list, jobs, fail_fast, json_lines, quiet, cluster)


def _check_guides(guide, target_guide, also, method, exemplars) -> None:
    """--guide needs --target-guide and one exemplar; neither goes with --also or paper."""
    if guide and not target_guide:
        raise click.UsageError("--guide needs --target-guide (the output's guide)")
    if not target_guide:
        return
    if also:
        raise click.UsageError("--target-guide does not combine with --also")
    if method != "osmap":
        raise click.UsageError("--target-guide needs --method osmap")
    if guide and (len(exemplars) != 1 or exemplars[0] == "-"):
        raise click.UsageError("--guide belongs to one exemplar: give exactly one EXEMPLAR "
                               "(without --guide each exemplar's luminance is its guide)")


def _check_lattice(lattice: str, fields, method: str) -> None:
    """Lattice vectors given by hand need one orientation and scale over the output."""
    if lattice in ("auto", "off"):
        return
    for given, flag in ((fields, "--orientation-field/--scale-field"),
                        (method != "osmap", "--method paper")):
        if given:
            raise click.UsageError(f"--lattice {lattice} does not combine with {flag} (a "
                                   "lattice needs one orientation and scale for the whole "
                                   "output; auto finds none there)")


def _check_also(also, with_maps, uv_out, fields, method) -> None:
    """--also combines with neither --with, --uv-out, control fields nor --method paper."""
    if not also:
        return
    for given, flag in ((with_maps, "--with"), (uv_out, "--uv-out"),
                        (fields, "--orientation-field/--scale-field"),
                        (method != "osmap", "--method paper")):
        if given:
            raise click.UsageError(f"--also does not combine with {flag} (the positions of "
                                   "several exemplars have no single exemplar to refer to)")


def _check_size(size: tuple[int, int]) -> None:
    width, height = size
    for name in ("width", "height"):
        spec = option_spec(SynthOptions, name)
        if not spec.lo <= (width if name == "width" else height) <= spec.hi:
            raise click.BadParameter(
                f"{width}x{height}: width and height must be between {spec.lo} and {spec.hi}",
                param_hint="'--size'",
            )


NAME_FIELDS = ("stem", "name", "ext", "parent", "index", "width", "height", "seed", "preset",
               "quality")


def _name_fields(exemplar: str, index: int, options, preset_name: str) -> dict:
    fields = input_fields(exemplar, index)
    ext = os.path.splitext(fields["name"])[1].lstrip(".").lower()
    return {"stem": fields["stem"], "name": fields["name"], "ext": ext,
            "parent": fields["parent"], "index": index, "width": options.width,
            "height": options.height, "seed": options.seed, "preset": preset_name,
            "quality": options.quality}


def _plan_outputs(inputs, output, out_dir, name_template, uv_out, withs, options, preset_name,
                  bit_depth, overwrite):
    """[(exemplar, output, [(WithMap, map output)], uv output)] for every input, checked
    before any work: output paths, formats, bit depths, collisions."""
    if uv_out is not None and os.path.splitext(uv_out)[1].lower() != ".exr":
        raise click.BadParameter(f"{uv_out}: must be an .exr file", param_hint="'--uv-out'")
    check_destination(output, out_dir, len(inputs), name_template, overwrite)

    plans = []
    owners: dict[str, str] = {}
    for index, exemplar in enumerate(inputs, 1):
        fields = _name_fields(exemplar, index, options, preset_name)
        main, maps, uv = image_outputs(exemplar, fields, output, out_dir, name_template,
                                       uv_out, withs, bit_depth, owners)
        plans.append((exemplar, main, maps, uv))
    return plans
