"""`osmap synth` jobs: one exemplar -> its outputs, run one at a time or in worker processes.

A :class:`Job` holds everything one synthesis needs (paths, resolved options); :func:`run_job`
does it the way a single `osmap synth X -o Y` always did (read, check, synthesize, write all
outputs atomically) and returns a JSON-ready record. :func:`run_jobs` runs a list of jobs, in
this process (``-j 1``) or in ``-j N`` spawned worker processes, reports each finished job
(one line, or one JSON object with ``--json``), and returns the exit code: 0 when no job
failed, 1 otherwise. A job's bytes do not depend on how it was run.
"""

from __future__ import annotations

import dataclasses
import json
import os
import sys
import time

import click

from osmap_cli.errors import OsmapError

__all__ = ["Job", "batch_options", "check_destination", "claim_output", "expand_inputs",
           "fill_template", "job_record", "real_paths", "refusal", "run_job", "run_jobs",
           "skip_or_refuse"]

UV_DESCRIPTION = ("u = exemplar column (x), v = exemplar row (y), in exemplar pixels; "
                  "(0, 0) is the centre of the top-left exemplar pixel")


@dataclasses.dataclass(frozen=True)
class Job:
    """One exemplar and where its outputs go."""

    index: int
    exemplar: str
    output: str
    options: object  # SynthOptions (validated)
    preset: str  # as recorded: a built-in name or a preset file's name
    preset_values: dict | None  # the built-in preset's table; None for a preset file
    bit_depth: str | None = None
    uv_out: str | None = None
    withs: tuple = ()  # ((WithMap with the path filled in, output path), ...)
    orientation_field: str | None = None
    scale_field: str | None = None
    replace: bool = True  # False: an existing output makes the job "skipped"
    refused: str | None = None  # why the job must not run (an output would replace an input)
    progress: bool = False
    quiet: bool = False
    label: str = "osmap synth"

    @property
    def outputs(self) -> list[str]:
        paths = [self.output] + [path for _, path in self.withs]
        return paths + ([self.uv_out] if self.uv_out else [])

    def describe(self) -> dict:
        """The JSON record's job fields (input, outputs, size, seed, options)."""
        opts = self.options
        return {"input": self.exemplar, "outputs": self.outputs,
                "size": [opts.width, opts.height], "seed": opts.seed,
                "options": {"preset": self.preset, **dataclasses.asdict(opts)}}

    def run(self) -> dict:
        return run_job(self)


def job_record(job, status: str, started: float, **more) -> dict:
    """A finished job's record: the job's `describe()` fields, seconds, status and MORE.

    Any job type works with run_jobs if it has `exemplar`, `outputs`, `replace`, `refused`,
    `describe()` and `run()` (which returns this record, or raises OsmapError).
    """
    record = {**job.describe(), "seconds": round(time.monotonic() - started, 3),
              "status": status}
    record.update(more)
    return record



def skip_or_refuse(job, started: float) -> dict | None:
    """The "skipped" record when an output exists and the job may not replace it; raises
    OsmapError when the job is refused; None when it may run."""
    if not job.replace:
        existing = [p for p in job.outputs if os.path.lexists(p)]
        if existing:
            return job_record(job, "skipped", started,
                              reason=f"{existing[0]} exists (--overwrite replaces it)")
    if job.refused:
        raise OsmapError(job.refused)
    return None


# ---------------------------------------------------------------------------------------------
# planning: options, inputs, output names, collisions


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
)


def batch_options(function):
    """Add -j/--jobs, --fail-fast, --json and --overwrite (in that order) to a command."""
    for option in reversed(_BATCH_OPTIONS):
        function = option(function)
    return function


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


def real_paths(paths) -> set[str]:
    """The resolved paths of the given (None skipped): the inputs no output may replace."""
    return {os.path.realpath(p) for p in paths if p}


def refusal(outputs, input_paths: set[str]) -> str | None:
    """Why a job must not run: one of OUTPUTS is one of INPUT_PATHS (from real_paths)."""
    for out in outputs:
        if os.path.realpath(out.rstrip("/" + os.sep) or out) in input_paths:
            return f"{out}: refusing to write over an input file"
    return None


def output_depth(output: str, bit_depth: str | None, channels: int, input_depth: int):
    """(format, bit depth) for OUTPUT; path problems raise OsmapError, a bad --bit-depth is a
    click usage error."""
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


def run_job(job: Job) -> dict:
    """Synthesize one job's outputs; returns its record (status "ok" or "skipped").

    Raises OsmapError for a bad input or output (nothing is written then).
    """
    started = time.monotonic()
    skipped = skip_or_refuse(job, started)
    if skipped is not None:
        return skipped

    from osmap_cli import synth
    from osmap_cli.fields import load_fields
    from osmap_cli.imageio import read_image
    from osmap_cli.materials import load_aligned, render_map
    from osmap_cli.progress import ProgressBar
    from osmap_cli.provenance import image_metadata, synth_args
    from osmap_cli.synth.render import render_settings

    options = job.options
    image = read_image(job.exemplar)
    channels = image.pixels.shape[2]
    names = tuple(image.channel_names)
    fmt, depth = output_depth(job.output, job.bit_depth, channels, image.bit_depth)
    if fmt == "jpeg" and channels in (2, 4) and names[-1] != "A":
        raise OsmapError(f"{job.output}: JPEG cannot store {channels} channels "
                         f"({', '.join(names)}); use .png, .tif or .exr")
    maps = []
    for spec, path in job.withs:
        mapped = load_aligned(spec.path, image.pixels.shape, job.exemplar)
        map_fmt, map_depth = output_depth(path, job.bit_depth, mapped.pixels.shape[2],
                                          mapped.bit_depth)
        map_names = tuple(mapped.channel_names)
        if map_fmt == "jpeg" and len(map_names) in (2, 4) and map_names[-1] != "A":
            raise OsmapError(f"{path}: JPEG cannot store {len(map_names)} channels "
                             f"({', '.join(map_names)}); use .png, .tif or .exr")
        maps.append((spec, path, mapped, map_depth))
    fields = load_fields(job.orientation_field, job.scale_field,
                         (options.height, options.width), options.scale)

    with ProgressBar(enabled=job.progress, desc=job.label) as progress:
        extra = {"fields": fields} if fields is not None else {}
        result = synth.synthesize(image.pixels, options, progress=progress, **extra)

    args = synth_args(options, job.preset, job.preset_values, depth, job.orientation_field,
                      job.scale_field)
    fields_meta = {}
    if job.orientation_field:
        fields_meta["orientation_field"] = os.path.basename(job.orientation_field)
    if job.scale_field:
        fields_meta["scale_field"] = os.path.basename(job.scale_field)

    def meta(role, more_args=(), extra=None):
        return image_metadata(options, job.preset, job.exemplar, image.pixels.shape,
                              args + list(more_args), role, {**fields_meta, **(extra or {})})

    items = [(job.output, result.pixels, depth, names, meta("image"))]
    jacobian = result.jacobian if result.jacobian is not None else options.jacobian()
    for spec, path, mapped, map_depth in maps:
        pixels = render_map(mapped, result.positions, jacobian, spec.normal, spec.path,
                            *render_settings(options))
        source = os.path.basename(spec.path)
        items.append((path, pixels, map_depth, tuple(mapped.channel_names),
                      meta(f"with:{spec.name}", ["--with", f"{spec.name}={source}"],
                           {"source": source, "normal_map": str(spec.normal).lower()})))
    if job.uv_out is not None:
        uv = result.positions[..., ::-1]  # (row, col) -> (u = col, v = row)
        ext = os.path.splitext(job.output)[1].lower()
        items.append((job.uv_out, uv, 32, ("u", "v"),
                      meta("uv", (), {"uv_channels": UV_DESCRIPTION, "image_ext": ext})))
    write_all(items)

    height, width = result.pixels.shape[:2]
    kept = channels - 1 if fmt == "jpeg" and channels in (2, 4) else channels
    label = {"png": "PNG", "openexr": "EXR", "tiff": "TIFF", "jpeg": "JPEG"}[fmt]
    sample = {16: "half", 32: "float"}[depth] if fmt == "openexr" else f"{depth}-bit"
    if fmt == "tiff" and depth == 32:
        sample = "float"
    line = f"wrote {job.output}: {width}x{height}, {kept} channel{'s' * (kept != 1)}, " \
           f"{sample} {label}"
    if maps:
        line += "; " + ", ".join(f"{spec.name} in {path}" for spec, path, _, _ in maps)
    if job.uv_out is not None:
        line += f"; positions in {job.uv_out}"
    warnings = []
    if fmt == "jpeg" and channels in (2, 4):
        warnings.append(f"{job.output}: JPEG cannot store alpha; the alpha channel was dropped")
    record = job_record(job, "ok", started)
    record["_line"] = f"{line} ({record['seconds']:.1f} s)"
    record["_warnings"] = warnings
    return record


def write_all(items) -> None:
    """Write every (path, pixels, depth, channel names, metadata) or none of them.

    Each image goes to a hidden temporary file next to its target first (imageio writes
    atomically); only when all are complete are they renamed onto the targets. On any failure
    (or Ctrl-C) the temporary files are removed and no target is touched.
    """
    import secrets

    from osmap_cli import imageio

    done: list[tuple[str, str]] = []
    try:
        for path, pixels, depth, names, metadata in items:
            directory, base = os.path.split(path)
            ext = os.path.splitext(base)[1]
            temp = os.path.join(directory, f".{base}.osmap-{secrets.token_hex(6)}{ext}")
            try:
                imageio.write_image(temp, pixels, depth, channel_names=names, metadata=metadata)
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
# running many jobs


def _failure(job, message: str, started: float, internal: bool = False) -> dict:
    text = " ".join(str(message).split())
    if job.exemplar not in text:
        text = f"{job.exemplar}: {text}"
    record = job_record(job, "failed", started, error=text)
    record["_internal"] = internal
    return record


def _run_caught(job, debug: bool = False) -> dict:
    """job.run(), with every failure turned into a "failed" record (for batches and workers)."""
    started = time.monotonic()
    try:
        return job.run()
    except OsmapError as exc:
        return _failure(job, str(exc), started)
    except click.UsageError as exc:
        return _failure(job, exc.format_message(), started)
    except Exception as exc:  # noqa: BLE001 - one broken job must not stop the batch
        record = _failure(job, f"{type(exc).__name__}: {exc}", started, internal=True)
        if debug:
            import traceback

            record["_traceback"] = traceback.format_exc()
        return record


def _init_worker(threads: int) -> None:
    # before Numba is imported in this process; a value the user set wins
    os.environ.setdefault("NUMBA_NUM_THREADS", str(threads))
    for variable in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(variable, "1")


def _worker_job(job, debug: bool) -> dict:
    try:
        return _run_caught(job, debug)
    except KeyboardInterrupt:
        return _failure(job, "interrupted", time.monotonic())


class _Reporter:
    """Prints one finished job: a line (or a JSON object) and counts the outcomes."""

    def __init__(self, json_lines: bool, quiet: bool, debug: bool):
        self.json_lines, self.quiet, self.debug = json_lines, quiet, debug
        self.counts = {"ok": 0, "skipped": 0, "failed": 0}

    def __call__(self, record: dict) -> None:
        status = record["status"]
        self.counts[status] += 1
        if status == "failed":
            if record.get("_traceback"):
                click.echo(record["_traceback"].rstrip(), err=True)
            kind = "internal error" if record.get("_internal") else "error"
            click.echo(f"osmap: {kind}: {record['error']}", err=True)
        elif status == "skipped" and not self.quiet:
            click.echo(f"osmap: skipped {record['input']}: {record['reason']}", err=True)
        if not self.quiet:
            for warning in record.get("_warnings", ()):
                click.echo(f"osmap: warning: {warning}", err=True)
        if self.json_lines:
            public = {k: v for k, v in record.items() if not k.startswith("_")}
            click.echo(json.dumps(public, sort_keys=False))
        elif status == "ok" and not self.quiet:
            click.echo(record["_line"])
        sys.stdout.flush()


def run_jobs(jobs: list, workers: int = 1, fail_fast: bool = False,
             json_lines: bool = False, quiet: bool = False, debug: bool = False) -> int:
    """Run the jobs and report each one; returns 0 when none failed, else 1.

    A single job (``osmap synth X -o Y``) raises its error instead, so that it is reported
    exactly like any other command failure.
    """
    report = _Reporter(json_lines, quiet, debug)
    started = time.monotonic()
    if len(jobs) == 1 and not json_lines:
        report(jobs[0].run())
        return 0
    not_run = 0
    if workers <= 1 or len(jobs) == 1:
        for position, job in enumerate(jobs):
            record = _run_caught(job, debug)
            report(record)
            if fail_fast and record["status"] == "failed":
                not_run = len(jobs) - position - 1
                break
    else:
        not_run = _run_pool(jobs, workers, fail_fast, debug, report)
    failed = report.counts["failed"]
    if len(jobs) > 1 and not quiet:
        parts = [f"{report.counts['ok']} written", f"{report.counts['skipped']} skipped",
                 f"{failed} failed"]
        if not_run:
            parts.append(f"{not_run} not run (--fail-fast)")
        click.echo(f"osmap: {len(jobs)} jobs: {', '.join(parts)} "
                   f"({time.monotonic() - started:.1f} s)", err=True)
    return 1 if failed else 0


def _run_pool(jobs: list, workers: int, fail_fast: bool, debug: bool, report) -> int:
    """Run jobs in `workers` spawned processes; returns how many were cancelled."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    workers = min(workers, len(jobs))
    threads = max(1, (os.cpu_count() or 1) // workers)
    context = multiprocessing.get_context("spawn")
    not_run = 0
    with ProcessPoolExecutor(max_workers=workers, mp_context=context,
                             initializer=_init_worker, initargs=(threads,)) as pool:
        pending = {pool.submit(_worker_job, job, debug) for job in jobs}
        try:
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for future in sorted(done, key=lambda f: id(f)):
                    record = future.result()
                    report(record)
                    if fail_fast and record["status"] == "failed" and pending:
                        cancelled = [f for f in pending if f.cancel()]
                        not_run += len(cancelled)
                        pending -= set(cancelled)
        except BaseException:
            for future in pending:
                future.cancel()
            raise
    return not_run
