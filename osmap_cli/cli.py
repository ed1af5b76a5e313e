"""The ``osmap`` command line.

``osmap synth EXEMPLAR -o OUT`` synthesizes a texture, ``osmap presets`` lists and shows the
tuning presets; ``osmap surface`` (in :mod:`osmap_cli.surface.command`) is registered lazily.

Start-up must stay fast (``osmap --help`` < 0.5 s): this module imports only click and the
standard library at import time. numpy, numba, OpenImageIO and tqdm are imported inside the
command functions; subcommands living in other modules are imported only when they run.

Errors: every failure prints exactly one line on stderr, ``osmap: error: <message>``, and exits
with 1 (bad input file, unwritable output, runtime failure) or 2 (usage: malformed or
out-of-range option values, including click's own parse errors). Ctrl-C prints
``osmap: interrupted`` and exits with 130. Anything unexpected prints
``osmap: internal error: ...`` and exits with 1; ``osmap --debug ...`` or ``OSMAP_DEBUG=1`` adds
the Python traceback.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import re
import sys

import click

from osmap_cli import __version__
from osmap_cli.batch import batch_options
from osmap_cli.errors import OsmapError

__all__ = ["EXIT_ERROR", "EXIT_INTERRUPTED", "EXIT_OK", "EXIT_USAGE", "cli", "main"]

EXIT_OK = 0
EXIT_ERROR = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130

# Copies of osmap_cli.synth.options values (importing that module loads numba); the tests check
# that they match.
QUALITIES = ("fast", "default", "high")
METHODS = ("osmap", "paper")
DEFAULT_SIZE = 256
DEFAULT_SEED = 0
DEFAULT_SCALE = 1.0
DEFAULT_ORIENTATION = 0.0
DEFAULT_ANISOTROPY = 1.0

# The preset tunables (SynthOptions.tunables()), each also a `osmap synth` flag that overrides the
# preset: (field name, type, help). The tests check this table against SynthOptions.
TUNING_FLAGS: tuple[tuple[str, type, str], ...] = (
    ("levels", int, "pyramid levels (0: from the exemplar size)"),
    ("patch_radius", int, "matching window half-size, in feature vectors"),
    ("sweeps", int, "coherence sweeps per pyramid level"),
    ("coarse_sweeps", int, "coherence sweeps at the coarsest level"),
    ("occupancy", float, "penalty on over-used exemplar regions"),
    ("seam", float, "penalty on positions that break their neighbours' copy"),
    ("max_copy", float, "copy regions wider than this, in output pixels, are broken up (0: off)"),
    ("align", int, "copies move whole by up to this many pixels to match at their borders "
     "(coarsest level; halved per finer level; 0: off)"),
    ("blend", int, "seam blending radius when rendering, pixels (0: hard copies)"),
    ("knn", int, "similar-position candidates per pixel (k-coherence)"),
    ("random_candidates", int, "PatchMatch random-search candidates per pixel"),
    ("feature_dims", int, "appearance-space (PCA) dimensions"),
    ("window_scale", float, "OS-Map winner-search window / exemplar extent"),
    ("som_steps_per_node", float, "OS-Map training steps per map node"),
    ("som_sigma_max", float, "OS-Map initial neighbourhood radius, in nodes"),
    ("som_sigma_min", float, "OS-Map final neighbourhood radius, in nodes"),
    ("som_alpha_max", float, "OS-Map initial learning rate"),
    ("som_alpha_min", float, "OS-Map final learning rate"),
    ("som_anisotropy", float, "OS-Map kernel weight across / along each component"),
    ("som_range", float, "OS-Map range kernel: tau = som_range * sigma + 1 (0: off)"),
)

# Subcommands defined in other modules, imported only when they are run (or their --help is
# shown): name -> (module, attribute, one-line help for `osmap --help`).
LAZY_COMMANDS: dict[str, tuple[str, str, str]] = {
    "surface": (
        "osmap_cli.surface.command",
        "surface_command",
        "Fit a quad grid (an OS-Map) to a point-sampled surface.",
    ),
    "solid": (
        "osmap_cli.solid.command",
        "solid_command",
        "Synthesize a solid (3D) texture from a 2D exemplar.",
    ),
}

LAZY_COMMANDS.update({
    "apply": (
        "osmap_cli.apply",
        "apply_command",
        "Render a saved position map (--uv-out) on another aligned map.",
    ),
    "info": (
        "osmap_cli.info",
        "info_command",
        "Print the provenance stored in an osmap output.",
    ),
})

# The order of `osmap --help`'s command list.
COMMAND_ORDER = ("synth", "solid", "apply", "info", "surface", "presets")

CONTEXT_SETTINGS = {"help_option_names": ["-h", "--help"], "max_content_width": 100}

_state = {"debug": False}


class _Interrupted(Exception):
    """Ctrl-C inside a command (keeps click from printing its own "Aborted!")."""


# ---------------------------------------------------------------------------------------------
# the group


class OsmapGroup(click.Group):
    """A click group whose LAZY_COMMANDS are imported only when used."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        names = set(super().list_commands(ctx)) | set(LAZY_COMMANDS)
        rank = {name: i for i, name in enumerate(COMMAND_ORDER)}
        return sorted(names, key=lambda n: (rank.get(n, len(rank)), n))

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name in LAZY_COMMANDS and cmd_name not in self.commands:
            module, attribute, _ = LAZY_COMMANDS[cmd_name]
            return getattr(importlib.import_module(module), attribute)
        return super().get_command(ctx, cmd_name)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        names = self.list_commands(ctx)
        if not names:
            return
        limit = formatter.width - 6 - max(len(n) for n in names)
        rows = []
        for name in names:
            if name in LAZY_COMMANDS and name not in self.commands:
                rows.append((name, LAZY_COMMANDS[name][2]))  # no import just for the listing
                continue
            command = self.commands.get(name)
            if command is not None and not command.hidden:
                rows.append((name, command.get_short_help_str(limit)))
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt:
            raise _Interrupted() from None


@click.group(
    cls=OsmapGroup,
    context_settings=CONTEXT_SETTINGS,
    invoke_without_command=True,
    epilog="""\b
Examples:
  osmap synth samples/cells.png -o out/cells.png
  osmap synth samples/brick.png -o out/brick.exr --size 512x256 --preset structured
  osmap synth samples/*.png --out-dir out/batch --size 128 -j 2
  osmap synth samples/cells.png -o out/cells.png --uv-out out/cells_uv.exr
  osmap apply out/cells_uv.exr samples/cells.png -o out/cells_again.png
  osmap info out/cells.png
  osmap presets
  osmap synth --help

Exit codes: 0 success, 1 error (input, output, runtime; a batch: a job failed),
2 usage error, 130 interrupted.
""",
)
@click.version_option(
    __version__, "--version", "-V", prog_name="osmap", message="%(prog)s %(version)s"
)
@click.option(
    "--debug",
    is_flag=True,
    help="Show the Python traceback when a command fails (same as OSMAP_DEBUG=1).",
)
@click.pass_context
def cli(ctx: click.Context, debug: bool) -> None:
    """osmap: texture synthesis with the Oriented and Scalable Map (OS-Map, Hua 2016).

    Give it a small exemplar image and it makes a new, larger image that looks like it.
    """
    if debug:
        _state["debug"] = True
    if ctx.invoked_subcommand is None:
        click.echo(ctx.get_help())


# ---------------------------------------------------------------------------------------------
# osmap synth


class SizeType(click.ParamType):
    """``WxH`` (e.g. 512x256) or a single number N for NxN."""

    name = "WxH|N"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        text = str(value).strip()
        match = re.fullmatch(r"(\d+)\s*[xX]\s*(\d+)", text) or re.fullmatch(r"(\d+)", text)
        if match is None:
            self.fail(f"{value!r} is not WxH or N (examples: 512x256, or 256 for 256x256)",
                      param, ctx)
        digits = match.groups()
        if any(len(d) > 9 for d in digits):
            self.fail(f"{value!r} is too large", param, ctx)
        width = int(digits[0])
        height = int(digits[-1])
        if width <= 0 or height <= 0:
            self.fail(f"{value!r}: width and height must be positive", param, ctx)
        return (width, height)


def _tuning_options(function):
    """Add one --flag per preset tunable (default: the preset's value)."""
    for name, kind, text in reversed(TUNING_FLAGS):
        function = click.option(
            "--" + name.replace("_", "-"),
            name,
            type=click.INT if kind is int else click.FLOAT,
            default=None,
            metavar="N" if kind is int else "X",
            help=f"Tuning: {text}. [default: from the preset]",
        )(function)
    return function


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
"""


@cli.command("synth", help=SYNTH_HELP, epilog=SYNTH_EPILOG, short_help="Synthesize a texture.")
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
@click.option("--size", type=SizeType(), default=str(DEFAULT_SIZE), show_default=True,
              help="Output size in pixels: WxH (e.g. 512x256) or N for NxN.")
@click.option("--seed", type=int, default=DEFAULT_SEED, show_default=True,
              help="Random seed (a whole number >= 0); the same seed gives the same output.")
@click.option(
    "--preset",
    default="default",
    show_default=True,
    metavar="NAME|FILE.toml",
    help="Tuning preset: a built-in name (see 'osmap presets') or a TOML file.",
)
@click.option("--scale", type=float, default=DEFAULT_SCALE, show_default=True,
              help="Feature size relative to the exemplar (2 = features twice as large).")
@click.option("--orientation", type=float, default=DEFAULT_ORIENTATION, show_default=True,
              metavar="DEG", help="Rotate the texture counter-clockwise by DEG degrees.")
@click.option("--anisotropy", type=float, default=DEFAULT_ANISOTROPY, show_default=True,
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
@click.option("-q", "--quiet", is_flag=True,
              help="No progress bar, no summary line, no warnings (errors are still shown).")
@_tuning_options
def synth_command(exemplars: tuple[str, ...], output: str | None, out_dir: str | None,
                  name_template: str | None, jobs: int, fail_fast: bool, json_lines: bool,
                  overwrite: bool, size: tuple[int, int], seed: int, preset: str,
                  scale: float, orientation: float, anisotropy: float,
                  orientation_field: str | None, scale_field: str | None, tileable: bool,
                  quality: str, method: str, bit_depth: str | None,
                  with_maps: tuple[str, ...], uv_out: str | None, quiet: bool,
                  **tuning) -> int:
    from osmap_cli.synth.options import SynthOptions

    # 1. preset and options (no image work yet)
    loaded = _load_preset(preset)
    options = _resolve_options(
        SynthOptions, loaded.values, size,
        {"seed": seed, "scale": scale, "orientation": orientation, "anisotropy": anisotropy,
         "tileable": tileable, "quality": quality, "method": method},
        tuning,
    )
    if (orientation_field or scale_field) and method != "osmap":
        raise click.UsageError("--orientation-field and --scale-field need --method osmap")

    # 2. the inputs and where their outputs go
    from osmap_cli.batch import expand_inputs

    inputs = expand_inputs(exemplars)
    from osmap_cli.materials import parse_with

    withs = []
    for spec in with_maps:
        try:
            withs.append(parse_with(spec))
        except ValueError as exc:
            raise click.BadParameter(str(exc), param_hint="'--with'") from None
    if len({w.name for w in withs}) != len(withs):
        raise click.BadParameter("two maps with the same NAME", param_hint="'--with'")

    from osmap_cli.batch import Job, real_paths, refusal, run_jobs
    from osmap_cli.presets import is_preset_path

    preset_name = os.path.basename(preset) if is_preset_path(preset) else preset
    preset_values = None if is_preset_path(preset) else dict(loaded.values)
    plans = _plan_outputs(inputs, output, out_dir, name_template, uv_out, withs, options,
                          preset_name, bit_depth, overwrite)
    input_paths = real_paths([*inputs, *(spec.path for _, _, ws, _ in plans for spec, _ in ws),
                              orientation_field, scale_field])
    show_bar = not quiet and jobs == 1 and sys.stderr.isatty()
    job_list = []
    for index, (exemplar, main, maps, uv) in enumerate(plans, 1):
        refused = refusal([main, *(o for _, o in maps), *([uv] if uv else [])], input_paths)
        job_list.append(Job(
            index=index, exemplar=exemplar, output=main, options=options, preset=preset_name,
            preset_values=preset_values, bit_depth=bit_depth, uv_out=uv,
            withs=tuple(maps),
            orientation_field=orientation_field, scale_field=scale_field,
            replace=output is not None or overwrite, refused=refused, progress=show_bar,
            quiet=quiet, label="osmap synth" if len(plans) == 1 else os.path.basename(exemplar),
        ))
    return run_jobs(job_list, workers=jobs, fail_fast=fail_fast, json_lines=json_lines,
                    quiet=quiet, debug=_state["debug"])


NAME_FIELDS = ("stem", "name", "ext", "parent", "index", "width", "height", "seed", "preset",
               "quality")


def _name_fields(exemplar: str, index: int, options, preset_name: str) -> dict:
    base = os.path.basename(exemplar)
    stem, ext = os.path.splitext(base)
    return {"stem": stem, "name": base, "ext": ext.lstrip(".").lower(),
            "parent": os.path.basename(os.path.dirname(os.path.abspath(exemplar))),
            "index": index, "width": options.width, "height": options.height,
            "seed": options.seed, "preset": preset_name, "quality": options.quality}


def _plan_outputs(inputs, output, out_dir, name_template, uv_out, withs, options, preset_name,
                  bit_depth, overwrite):
    """[(exemplar, output, [(WithMap, map output)], uv output)] for every input, checked
    before any work: output paths, formats, bit depths, collisions."""
    from osmap_cli.batch import check_destination, claim_output, fill_template
    from osmap_cli.imageio import output_format
    from osmap_cli.materials import WithMap, expand_path, with_output_path

    if uv_out is not None and os.path.splitext(uv_out)[1].lower() != ".exr":
        raise click.BadParameter(f"{uv_out}: must be an .exr file", param_hint="'--uv-out'")
    check_destination(output, out_dir, len(inputs), name_template, overwrite)

    plans = []
    owners: dict[str, str] = {}
    for index, exemplar in enumerate(inputs, 1):
        fields = _name_fields(exemplar, index, options, preset_name)
        if output is not None:
            main = output
            uv = fill_template(uv_out, fields, "'--uv-out'") if uv_out else None
        else:
            main = os.path.join(out_dir, fill_template(name_template or "{stem}.{ext}", fields,
                                                       "'--name'"))
            uv = (os.path.join(out_dir, fill_template(uv_out, fields, "'--uv-out'"))
                  if uv_out else None)
        maps = [(WithMap(w.name, expand_path(w.path, exemplar)), with_output_path(main, w.name))
                for w in withs]
        output_format(main, None, 1)
        if bit_depth is not None:
            try:
                output_format(main, int(bit_depth), 1)
            except OsmapError as exc:
                raise click.BadParameter(str(exc), param_hint="'--bit-depth'") from None
        if uv is not None:
            if os.path.abspath(uv) == os.path.abspath(main):
                raise click.BadParameter(f"{uv}: is the same file as --output",
                                         param_hint="'--uv-out'")
            output_format(uv, 32, 2)
        for path in [main, *(o for _, o in maps), *([uv] if uv else [])]:
            claim_output(owners, path, exemplar)
        plans.append((exemplar, main, maps, uv))
    return plans


def _load_preset(preset: str):
    from osmap_cli.presets import builtin_names, is_preset_path, read_preset

    if not is_preset_path(preset) and preset not in builtin_names():
        raise click.BadParameter(
            f"unknown preset {preset!r} (built-in: {', '.join(builtin_names())}; "
            "or give the path of a .toml file)",
            param_hint="'--preset'",
        )
    return read_preset(preset)


def _resolve_options(options_cls, preset_values: dict, size: tuple[int, int], given: dict,
                     tuning: dict):
    """defaults < preset < command line; out-of-range command-line values are usage errors."""
    width, height = size
    fields = options_cls.__dataclass_fields__
    for field_name in ("width", "height"):
        lo, hi = fields[field_name].metadata["lo"], fields[field_name].metadata["hi"]
        if not lo <= (width if field_name == "width" else height) <= hi:
            raise click.BadParameter(
                f"{width}x{height}: width and height must be between {lo} and {hi}",
                param_hint="'--size'",
            )
    overrides = {k: v for k, v in tuning.items() if v is not None}
    options = options_cls().replace(**preset_values).replace(
        width=width, height=height, **given, **overrides
    )
    try:
        return options.validated()
    except OsmapError as exc:
        # the preset was validated on loading: what is wrong now came from the command line
        raise click.UsageError(str(exc)) from None


# ---------------------------------------------------------------------------------------------
# osmap presets


PRESETS_EPILOG = """\b
Examples:
  osmap presets
  osmap presets show structured
  osmap presets show default > my_preset.toml
  osmap synth samples/cells.png -o out/cells.png --preset my_preset.toml
"""


@cli.group(
    "presets",
    cls=click.Group,
    invoke_without_command=True,
    epilog=PRESETS_EPILOG,
    short_help="List or show the tuning presets.",
)
@click.pass_context
def presets_command(ctx: click.Context) -> None:
    """List the built-in tuning presets, one per line: name and description.

    A preset is a TOML file with "name", "description" and a [synth] table of
    tuning values (see 'osmap presets show default' for every key). Use one with
    'osmap synth --preset NAME' or '--preset FILE.toml'; tuning flags given on the
    command line override the preset.
    """
    if ctx.invoked_subcommand is None:
        _print_presets()


@presets_command.command(
    "list",
    epilog="""\b
Examples:
  osmap presets list
""",
)
def presets_list_command() -> None:
    """List the built-in presets (the same as 'osmap presets')."""
    _print_presets()


@presets_command.command(
    "show",
    epilog="""\b
Examples:
  osmap presets show default
  osmap presets show stochastic > my_preset.toml
  osmap presets show my_preset.toml
""",
)
@click.argument("name", metavar="NAME|FILE.toml")
def presets_show_command(name: str) -> None:
    """Print the TOML text of a built-in preset (or of a preset file)."""
    from osmap_cli.presets import builtin_names, is_preset_path, preset_text

    if not is_preset_path(name) and name not in builtin_names():
        raise click.BadParameter(
            f"unknown preset {name!r} (built-in: {', '.join(builtin_names())})",
            param_hint="'NAME'",
        )
    text = preset_text(name)
    click.echo(text, nl=not text.endswith("\n"))


def _print_presets() -> None:
    from osmap_cli.presets import list_presets

    presets = list_presets()
    width = max((len(name) for name, _ in presets), default=0)
    for name, description in presets:
        click.echo(f"{name:<{width}}  {description}".rstrip())


# ---------------------------------------------------------------------------------------------
# entry point


def _one_line(text: str) -> str:
    lines = [" ".join(line.split()) for line in str(text).splitlines()]
    return "; ".join(line for line in lines if line)


def _fail(message: str, code: int, exc: BaseException | None = None) -> int:
    if exc is not None and _state["debug"]:
        import traceback

        traceback.print_exception(type(exc), exc, exc.__traceback__, file=sys.stderr)
    sys.stdout.flush()
    print(f"osmap: {_one_line(message)}", file=sys.stderr, flush=True)
    return code


# numpy's BLAS is used only for small matrices (PCA of the exemplar); its worker threads busy-wait
# after each call and steal cores from the Numba kernels. Set before numpy is imported; a value
# in the environment wins.
_SINGLE_THREADED_BLAS = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code (the console script exits with it)."""
    for variable in _SINGLE_THREADED_BLAS:
        os.environ.setdefault(variable, "1")
    _state["debug"] = os.environ.get("OSMAP_DEBUG", "").strip().lower() in ("1", "true", "yes")
    with _latched_interrupts():
        return _main(argv)


@contextlib.contextmanager
def _latched_interrupts():
    """progress.latch_interrupts for the duration of a command (main thread only)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    from osmap_cli import progress

    previous = signal.getsignal(signal.SIGINT)
    progress.latch_interrupts()
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        progress.reset_interrupt()


def _main(argv: list[str] | None) -> int:
    try:
        result = cli.main(args=argv, prog_name="osmap", standalone_mode=False)
    except OsmapError as exc:
        return _fail(f"error: {exc}", EXIT_ERROR, exc)
    except click.UsageError as exc:
        message = exc.format_message().rstrip(".")
        if exc.ctx is not None:
            message += f" (see '{exc.ctx.command_path} --help')"
        return _fail(f"error: {message}", EXIT_USAGE, exc)
    except click.ClickException as exc:
        return _fail(f"error: {exc.format_message()}", exc.exit_code or EXIT_ERROR, exc)
    except (_Interrupted, click.Abort, KeyboardInterrupt) as exc:
        return _fail("interrupted", EXIT_INTERRUPTED, exc)
    except Exception as exc:  # the last line of defence: one line, no traceback
        detail = str(exc) or "(no message)"
        hint = "" if _state["debug"] else " (run with --debug or OSMAP_DEBUG=1 for details)"
        return _fail(f"internal error: {type(exc).__name__}: {detail}{hint}", EXIT_ERROR, exc)
    return result if isinstance(result, int) else EXIT_OK


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
