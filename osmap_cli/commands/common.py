"""What the commands share: option types, the batch and tuning flags, preset loading and
option resolution, and the planning of outputs (names, collisions, inputs never overwritten).

Only click and the standard library at import time (`osmap COMMAND --help` stays fast).
"""

from __future__ import annotations

import os
import re
import sys

import click

from osmap_cli.errors import OsmapError

CONTEXT_SETTINGS = {"help_option_names": ["-h", "--help"], "max_content_width": 100}


# ---------------------------------------------------------------------------------------------
# option types and flag groups


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


_BATCH_OPTIONS = (
    click.option("-j", "--jobs", type=click.IntRange(1, 256), default=1, show_default=True,
                 metavar="N", help="Worker processes running jobs at once (Numba threads "
                 "split between them); outputs are the same bytes for any N."),
    click.option("--fail-fast", is_flag=True, help="Stop at the first failed job (running "
                 "jobs finish; the rest are not started)."),
    click.option("--json", "json_lines", is_flag=True, help="Print one JSON object per "
                 "finished job on stdout (input, outputs, size, seed, options, seconds, status) "
                 "and nothing else there."),
    click.option("--overwrite", is_flag=True, help="In --out-dir mode, replace existing "
                 "outputs instead of skipping the job."),
    click.option("--scheduler", default=None, metavar="ADDRESS|local:N", help="Run each job "
                 "as a task on a Dask cluster: its scheduler's ADDRESS (tcp://HOST:8786), or "
                 "local:N to start N single-threaded workers on 127.0.0.1 for this batch. The "
                 "workers write the outputs (a file system they share, same paths). Not with "
                 "-j. Needs pip install 'osmap[cluster]'."),
    click.option("--scheduler-file", type=click.Path(exists=True, dir_okay=False,
                                                     path_type=str),
                 default=None, metavar="FILE", help="Like --scheduler, with the address read "
                 "from FILE (as 'dask scheduler --scheduler-file FILE' writes it)."),
    click.option("--threads", type=click.IntRange(1, 256), default=None, metavar="N",
                 help="Numba threads for each job on a cluster worker (with --scheduler or "
                 "--scheduler-file); the bytes do not depend on N. [default: 1]"),
)


def batch_options(function):
    """Add -j/--jobs, --fail-fast, --json, --overwrite, --scheduler, --scheduler-file and
    --threads (in that order) to a command."""
    for option in reversed(_BATCH_OPTIONS):
        function = option(function)
    return function


def cluster_spec(scheduler, scheduler_file, threads, jobs: int):
    """The osmap_cli.cluster.ClusterSpec of --scheduler / --scheduler-file / --threads, or None
    (no cluster); usage errors for the combinations that make no sense."""
    if scheduler is None and scheduler_file is None:
        if threads is not None:
            raise click.UsageError("--threads works with --scheduler or --scheduler-file "
                                   "only (-j N shares the cores itself)")
        return None
    from osmap_cli import cluster

    if scheduler is not None and scheduler_file is not None:
        raise click.UsageError("give either --scheduler or --scheduler-file, not both")
    flag = "--scheduler" if scheduler is not None else "--scheduler-file"
    if jobs > 1:
        raise click.UsageError(f"{flag} runs the jobs on the cluster's workers: -j/--jobs "
                               "is for this machine only (leave it out)")
    address, local = None, None
    if scheduler is not None:
        try:
            address, local = cluster.parse_scheduler(scheduler)
        except ValueError as exc:
            raise click.BadParameter(str(exc), param_hint="'--scheduler'") from None
    if not cluster.available():
        raise click.UsageError(f"{flag} needs Dask's distributed scheduler, which is not "
                               f"installed: {cluster.EXTRA_HINT}")
    return cluster.ClusterSpec(address=address, scheduler_file=scheduler_file, local=local,
                               threads=threads or 1)


def tuning_flags(options_cls, skip=()):
    """A decorator adding one --flag per tunable of OPTIONS_CLS (default: the preset's value),
    made from the option declarations (osmap_cli.options); SKIP: names of tunables the command
    does not use."""
    from osmap_cli.options import flag, tunables

    def decorate(function):
        for name, spec in reversed(tunables(options_cls).items()):
            if name in skip:
                continue
            if spec.kind is str:  # free text when there are no choices (checked later)
                kind, metavar = (click.Choice(spec.choices), None) if spec.choices \
                    else (click.STRING, "TEXT")
            else:
                kind = click.INT if spec.kind is int else click.FLOAT
                metavar = "N" if spec.kind is int else "X"
            function = click.option(
                flag(name), name, type=kind, default=None, metavar=metavar,
                help=f"Tuning: {spec.help}. [default: from the preset]",
            )(function)
        return function

    return decorate


# ---------------------------------------------------------------------------------------------
# presets and options


def load_preset(preset: str, table: str):
    """The validated preset for `osmap TABLE`; an unknown built-in name is a usage error."""
    from osmap_cli.presets import builtin_names, is_preset_path, read_preset

    if not is_preset_path(preset) and preset not in builtin_names(table):
        kind = "" if table == "synth" else f"{table} "
        hint = "" if table == "synth" else f" with a [{table}] table"
        raise click.BadParameter(
            f"unknown {kind}preset {preset!r} (built-in: {', '.join(builtin_names(table))}; "
            f"or give the path of a .toml file{hint})",
            param_hint="'--preset'",
        )
    return read_preset(preset, table)


def resolve_options(options_cls, preset_values: dict, given: dict, tuning: dict):
    """defaults < preset < command line; out-of-range command-line values are usage errors."""
    overrides = {k: v for k, v in tuning.items() if v is not None}
    options = options_cls().replace(**preset_values).replace(**given, **overrides)
    try:
        return options.validated()
    except OsmapError as exc:
        # the preset was validated on loading: what is wrong now came from the command line
        raise click.UsageError(str(exc)) from None


def debug_enabled() -> bool:
    """--debug (before the command) or OSMAP_DEBUG, as the group recorded it."""
    ctx = click.get_current_context(silent=True)
    return bool(ctx is not None and (ctx.find_root().obj or {}).get("debug"))


def show_progress(quiet: bool, jobs: int) -> bool:
    """A progress bar: one job at a time, not --quiet, stderr a terminal."""
    return not quiet and jobs == 1 and sys.stderr.isatty()


# ---------------------------------------------------------------------------------------------
# inputs and output planning


def expand_inputs(exemplars) -> list[str]:
    """The exemplar paths, "-" replaced by the lines of stdin (blank lines skipped)."""
    inputs: list[str] = []
    for item in exemplars:
        if item == "-":
            text = sys.stdin.read()
            inputs.extend(line.strip() for line in text.splitlines() if line.strip())
        else:
            inputs.append(item)
    if not inputs:
        raise click.BadParameter("no exemplar paths (stdin was empty)", param_hint="'EXEMPLAR'")
    return inputs


def fill_template(template: str, fields: dict, hint: str) -> str:
    """TEMPLATE with {field}s from FIELDS; a bad template is a usage error naming them."""
    try:
        return template.format_map(fields)
    except (KeyError, IndexError, ValueError, AttributeError) as exc:
        raise click.BadParameter(f"{template!r}: {exc!s} (fields: "
                                 f"{', '.join('{' + f + '}' for f in fields)})",
                                 param_hint=hint) from None


def input_fields(exemplar: str, index: int) -> dict:
    """The name-template fields every command has: {stem} {name} {parent} {index}."""
    base = os.path.basename(exemplar)
    return {"stem": os.path.splitext(base)[0], "name": base,
            "parent": os.path.basename(os.path.dirname(os.path.abspath(exemplar))),
            "index": index}


def check_destination(output, out_dir, count: int, name_template, overwrite) -> None:
    """Usage errors of -o/--out-dir/--name/--overwrite; creates --out-dir."""
    if output is not None and out_dir is not None:
        raise click.UsageError("give either -o/--output (one exemplar) or --out-dir (any "
                               "number), not both")
    if output is None and out_dir is None:
        raise click.UsageError("missing option '-o' / '--output' (or --out-dir DIR for "
                               "several exemplars)")
    if output is not None:
        if count > 1:
            raise click.UsageError(f"-o names one output but {count} exemplars were "
                                   "given; use --out-dir DIR (and --name TEMPLATE)")
        for flag, value in (("--name", name_template), ("--overwrite", overwrite)):
            if value:
                raise click.UsageError(f"{flag} works with --out-dir only")
        return
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise OsmapError(f"{out_dir}: --out-dir exists and is not a directory")
    try:
        os.makedirs(out_dir, exist_ok=True)
    except OSError as exc:
        raise OsmapError(f"{out_dir}: cannot create the output directory "
                         f"({exc.strerror or exc})") from None


def claim_output(owners: dict, path: str, exemplar: str) -> None:
    """Record that EXEMPLAR writes PATH; two jobs (or one twice) writing it is a usage error."""
    key = os.path.abspath(path.rstrip("/" + os.sep) or path)
    if key in owners:
        other = owners[key]
        what = "twice" if other == exemplar else f"for {other} and {exemplar}"
        raise click.UsageError(f"{path}: the same output {what}; make --name unique "
                               "(e.g. add {index} or {parent})")
    owners[key] = exemplar


def parse_withs(with_maps) -> list:
    """The --with values as materials.WithMap records; a bad one or a repeated NAME is a usage
    error."""
    from osmap_cli.materials import parse_with

    withs = []
    for spec in with_maps:
        try:
            withs.append(parse_with(spec))
        except ValueError as exc:
            raise click.BadParameter(str(exc), param_hint="'--with'") from None
    if len({w.name for w in withs}) != len(withs):
        raise click.BadParameter("two maps with the same NAME", param_hint="'--with'")
    return withs


def image_outputs(source: str, fields: dict, output, out_dir, name_template, uv_out, withs,
                  bit_depth, owners: dict):
    """(main output, [(WithMap, map output)], uv output or None) of one image input, every path
    and format checked and claimed in `owners` before any work (osmap synth, inpaint, tileable)."""
    from osmap_cli.imageio import output_format
    from osmap_cli.materials import WithMap, expand_path, with_output_path

    if output is not None:
        main = output
        uv = fill_template(uv_out, fields, "'--uv-out'") if uv_out else None
    else:
        main = os.path.join(out_dir, fill_template(name_template or "{stem}.{ext}", fields,
                                                   "'--name'"))
        uv = (os.path.join(out_dir, fill_template(uv_out, fields, "'--uv-out'"))
              if uv_out else None)
    maps = [(WithMap(w.name, expand_path(w.path, source)), with_output_path(main, w.name))
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
        claim_output(owners, path, source)
    return main, maps, uv


def real_paths(paths) -> set[str]:
    """The resolved paths of the given (None skipped): the inputs no output may replace."""
    return {os.path.realpath(p) for p in paths if p}


def refusal(outputs, input_paths: set[str]) -> str | None:
    """Why a job must not run: one of OUTPUTS is one of INPUT_PATHS (from real_paths)."""
    for out in outputs:
        if os.path.realpath(out.rstrip("/" + os.sep) or out) in input_paths:
            return f"{out}: refusing to write over an input file"
    return None


def run_batch(jobs: list, workers: int, fail_fast: bool, json_lines: bool, quiet: bool,
              cluster=None) -> int:
    """osmap_cli.batch.run_jobs with the group's --debug (CLUSTER: from cluster_spec)."""
    from osmap_cli.batch import run_jobs

    return run_jobs(jobs, workers=workers, fail_fast=fail_fast, json_lines=json_lines,
                    quiet=quiet, debug=debug_enabled(), cluster=cluster)
