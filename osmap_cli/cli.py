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

import importlib
import os
import re
import sys
import time

import click

from osmap_cli import __version__
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
    ("levels", int, "pyramid levels"),
    ("patch_radius", int, "matching window half-size, in feature vectors"),
    ("sweeps", int, "coherence sweeps per pyramid level"),
    ("coarse_sweeps", int, "coherence sweeps at the coarsest level"),
    ("occupancy", float, "penalty on over-used exemplar regions"),
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
}

# The order of `osmap --help`'s command list.
COMMAND_ORDER = ("synth", "surface", "presets")

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
  osmap presets
  osmap synth --help

Exit codes: 0 success, 1 error (input, output, runtime), 2 usage error, 130 interrupted.
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
Option precedence, lowest to highest: built-in defaults, the --preset,
tuning flags given here (--levels, --sweeps, ...); --quality then scales
the work (fast: about half the sweeps; high: more sweeps and candidates).

\b
--uv-out writes, for every output pixel, the exemplar position it was
copied from: a 2-channel float EXR, channel "u" = exemplar column (x) and
"v" = exemplar row (y), in exemplar pixels, (0, 0) = centre of the
top-left exemplar pixel.

Same inputs, options and seed give the same output, whatever the number of
threads (NUMBA_NUM_THREADS), byte for byte in every format. Outputs are
written atomically: on any error nothing is written.
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
"""


@cli.command("synth", help=SYNTH_HELP, epilog=SYNTH_EPILOG, short_help="Synthesize a texture.")
@click.argument("exemplar", type=click.Path(path_type=str), metavar="EXEMPLAR")
@click.option(
    "-o",
    "--output",
    "output",
    required=True,
    type=click.Path(path_type=str),
    metavar="OUTPUT",
    help="Output image; the extension (.png .exr .tif .tiff .jpg .jpeg) picks the format. "
    "An existing file is replaced (atomically).",
)
@click.option(
    "--size",
    type=SizeType(),
    default=str(DEFAULT_SIZE),
    show_default=True,
    help="Output size in pixels: WxH (e.g. 512x256) or N for NxN.",
)
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
@click.option(
    "--uv-out",
    type=click.Path(path_type=str),
    default=None,
    metavar="FILE.exr",
    help='Also write the exemplar position of every output pixel: float EXR, channels "u" '
    '(column, x) and "v" (row, y) in exemplar pixels.',
)
@click.option("-q", "--quiet", is_flag=True,
              help="No progress bar, no summary line, no warnings (errors are still shown).")
@_tuning_options
def synth_command(exemplar: str, output: str, size: tuple[int, int], seed: int, preset: str,
                  scale: float, orientation: float, anisotropy: float, tileable: bool,
                  quality: str, method: str, bit_depth: str | None, uv_out: str | None,
                  quiet: bool, **tuning) -> None:
    from osmap_cli.synth.options import SynthOptions

    started = time.monotonic()

    # 1. preset and options (no image work yet)
    loaded = _load_preset(preset)
    options = _resolve_options(
        SynthOptions, loaded.values, size,
        {"seed": seed, "scale": scale, "orientation": orientation, "anisotropy": anisotropy,
         "tileable": tileable, "quality": quality, "method": method},
        tuning,
    )

    # 2. the exemplar, then the outputs it determines
    from osmap_cli.imageio import output_format, read_image

    image = read_image(exemplar)
    channels = image.pixels.shape[2]
    names = tuple(image.channel_names)
    fmt, depth = _output_depth(output, bit_depth, channels, image.bit_depth)
    if fmt == "jpeg" and channels in (2, 4) and names[-1] != "A":
        raise OsmapError(f"{output}: JPEG cannot store {channels} channels ({', '.join(names)}); "
                         "use .png, .tif or .exr")
    if uv_out is not None:
        if os.path.splitext(uv_out)[1].lower() != ".exr":
            raise click.BadParameter(f"{uv_out}: must be an .exr file", param_hint="'--uv-out'")
        if os.path.abspath(uv_out) == os.path.abspath(output):
            raise click.BadParameter(f"{uv_out}: is the same file as --output",
                                     param_hint="'--uv-out'")
        output_format(uv_out, 32, 2)

    # 3. the work
    from osmap_cli.progress import ProgressBar
    from osmap_cli.synth import synthesize

    show_bar = not quiet and sys.stderr.isatty()
    with ProgressBar(enabled=show_bar, desc="osmap synth") as progress:
        result = synthesize(image.pixels, options, progress=progress)

    # 4. the outputs, all or nothing
    from osmap_cli.presets import is_preset_path

    preset_name = os.path.basename(preset) if is_preset_path(preset) else preset
    metadata = _provenance(options, preset_name, exemplar)
    items = [(output, result.pixels, depth, names, metadata)]
    if uv_out is not None:
        uv = result.positions[..., ::-1]  # (row, col) -> (u = col, v = row)
        uv_meta = dict(metadata, uv_channels=UV_DESCRIPTION)
        items.append((uv_out, uv, 32, ("u", "v"), uv_meta))
    _write_all(items)

    if not quiet:
        if fmt == "jpeg" and channels in (2, 4):
            click.echo(f"osmap: warning: {output}: JPEG cannot store alpha; the alpha channel "
                       "was dropped", err=True)
        height, width = result.pixels.shape[:2]
        kept = channels - 1 if fmt == "jpeg" and channels in (2, 4) else channels
        label = {"png": "PNG", "openexr": "EXR", "tiff": "TIFF", "jpeg": "JPEG"}[fmt]
        sample = {16: "half", 32: "float"}[depth] if fmt == "openexr" else f"{depth}-bit"
        if fmt == "tiff" and depth == 32:
            sample = "float"
        line = f"wrote {output}: {width}x{height}, {kept} channel{'s' * (kept != 1)}, " \
               f"{sample} {label}"
        if uv_out is not None:
            line += f"; positions in {uv_out}"
        click.echo(f"{line} ({time.monotonic() - started:.1f} s)")


UV_DESCRIPTION = ("u = exemplar column (x), v = exemplar row (y), in exemplar pixels; "
                  "(0, 0) is the centre of the top-left exemplar pixel")


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


def _output_depth(output: str, bit_depth: str | None, channels: int, input_depth: int):
    """(format, bit depth) for OUTPUT; path problems exit 1, a bad --bit-depth exits 2."""
    from osmap_cli.imageio import output_format

    fmt, default_depth = output_format(output, None, channels)
    if bit_depth is not None:
        try:
            return output_format(output, int(bit_depth), channels)
        except OsmapError as exc:
            raise click.BadParameter(str(exc), param_hint="'--bit-depth'") from None
    if fmt == "png" and input_depth >= 16:
        return fmt, 16
    if fmt == "tiff" and input_depth > default_depth:
        return fmt, input_depth
    return fmt, default_depth


def _provenance(options, preset_name: str, exemplar: str) -> dict[str, str]:
    """Metadata stored in every output: enough to reproduce it."""
    import dataclasses
    import json

    return {
        "software": f"osmap {__version__}",
        "osmap_version": __version__,
        "command": "synth",
        "exemplar": os.path.basename(exemplar),
        "preset": preset_name,
        "seed": str(options.seed),
        "options": json.dumps(dataclasses.asdict(options), sort_keys=True),
    }


def _write_all(items) -> None:
    """Write every (path, pixels, depth, channel names, metadata) or none of them.

    Each image goes to a hidden temporary file next to its target first (imageio writes
    atomically); only when all are complete are they renamed onto the targets. On any failure
    (or Ctrl-C) the temporary files are removed and no target is touched.
    """
    import secrets

    from osmap_cli.imageio import write_image

    done: list[tuple[str, str]] = []
    try:
        for path, pixels, depth, names, metadata in items:
            directory, base = os.path.split(path)
            ext = os.path.splitext(base)[1]
            temp = os.path.join(directory, f".{base}.osmap-{secrets.token_hex(6)}{ext}")
            try:
                write_image(temp, pixels, depth, channel_names=names, metadata=metadata)
            except OsmapError as exc:
                raise OsmapError(str(exc).replace(temp, path)) from None
            done.append((temp, path))
        for temp, path in done:
            try:
                os.replace(temp, path)
            except OSError as exc:
                raise OsmapError(f"{path}: cannot write file ({exc.strerror or exc})") from None
        done = []
    finally:
        for temp, _ in done:
            try:
                os.remove(temp)
            except OSError:
                pass


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
