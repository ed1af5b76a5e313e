"""The ``osmap`` command line.

This module holds only the group, the exit-code contract and the registry of commands: each
command lives in its own module under :mod:`osmap_cli.commands` and is imported only when it
runs (or its --help is shown), so ``osmap --help`` imports nothing but click and the standard
library.

Errors: every failure prints exactly one line on stderr, ``osmap: error: <message>``, and exits
with 1 (bad input file, unwritable output, runtime failure) or 2 (usage: malformed or
out-of-range option values, including click's own parse errors). Ctrl-C prints
``osmap: interrupted`` and exits with 130; SIGTERM and SIGHUP likewise, with 143 and 129. A
closed stdout (``osmap presets | head -0``) ends the run quietly with 141, as Unix tools do.
Anything unexpected prints ``osmap: internal error: ...`` and exits with 1; ``osmap --debug ...``
or ``OSMAP_DEBUG=1`` adds the Python traceback.

The console script is :func:`run`: :func:`main`, then :func:`exit_now`, which ends the process
without the interpreter's teardown (a Numba process spends 0.1-0.2 s in it) once the standard
streams are flushed and every exit handler has run. A stop signal that lands after the command
(while its outputs are already committed) is reported like one during it.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import sys

import click

from osmap_cli import __version__
from osmap_cli.errors import OsmapError, Terminated, UsageError

__all__ = ["EXIT_ERROR", "EXIT_INTERRUPTED", "EXIT_OK", "EXIT_USAGE", "cli", "exit_now", "main",
           "run"]

EXIT_OK = 0
EXIT_ERROR = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130

# Every command: name -> (module, attribute, one-line help for `osmap --help`). A command's
# module is imported only when it runs or its --help is shown.
LAZY_COMMANDS: dict[str, tuple[str, str, str]] = {
    "synth": ("osmap_cli.commands.synth", "synth_command", "Synthesize a texture."),
    "inpaint": ("osmap_cli.commands.inpaint", "inpaint_command",
                "Fill a masked region of an image."),
    "tileable": ("osmap_cli.commands.tileable", "tileable_command",
                 "Make a photo tile seamlessly."),
    "solid": ("osmap_cli.commands.solid", "solid_command",
              "Synthesize a solid (3D) texture from a 2D exemplar."),
    "carve": ("osmap_cli.commands.carve", "carve_command", "Carve a solid texture into a mesh."),
    "apply": ("osmap_cli.commands.apply", "apply_command",
              "Render a saved position map (--uv-out) on another aligned map."),
    "info": ("osmap_cli.commands.info", "info_command",
             "Print the provenance stored in an osmap output."),
    "surface": ("osmap_cli.commands.surface", "surface_command",
                "Fit a quad grid (an OS-Map) to a point-sampled surface."),
    "presets": ("osmap_cli.commands.presets", "presets_command",
                "List or show the tuning presets."),
    "warmup": ("osmap_cli.commands.warmup", "warmup_command",
               "Compile the kernels for this CPU now."),
}

# The order of `osmap --help`'s command list.
COMMAND_ORDER = ("synth", "inpaint", "tileable", "solid", "apply", "info", "surface", "presets",
                 "warmup")

CONTEXT_SETTINGS = {"help_option_names": ["-h", "--help"], "max_content_width": 100}


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
    ctx.ensure_object(dict)
    if debug:
        ctx.obj["debug"] = True
    if ctx.invoked_subcommand is None:
        click.echo(ctx.get_help())


# ---------------------------------------------------------------------------------------------
# entry point


def _one_line(text: str) -> str:
    lines = [" ".join(line.split()) for line in str(text).splitlines()]
    return "; ".join(line for line in lines if line)


def _fail(message: str, code: int, exc: BaseException | None = None,
          debug: bool = False) -> int:
    if exc is not None and debug:
        import traceback

        traceback.print_exception(type(exc), exc, exc.__traceback__, file=sys.stderr)
    with contextlib.suppress(OSError, ValueError):
        sys.stdout.flush()
    print(f"osmap: {_one_line(message)}", file=sys.stderr, flush=True)
    return code


_STOP_SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")

# numpy's BLAS is used only for small matrices (PCA of the exemplar); its worker threads busy-wait
# after each call and steal cores from the Numba kernels. Set before numpy is imported; a value
# in the environment wins.
_SINGLE_THREADED_BLAS = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def _single_threaded_blas() -> None:
    for variable in _SINGLE_THREADED_BLAS:
        os.environ.setdefault(variable, "1")


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code (the console script exits with it)."""
    _single_threaded_blas()
    state = {"debug": os.environ.get("OSMAP_DEBUG", "").strip().lower() in ("1", "true", "yes")}
    threads = os.environ.get("NUMBA_NUM_THREADS")
    if threads is not None and not (threads.strip().isdigit() and int(threads) >= 1):
        return _fail(f"error: NUMBA_NUM_THREADS={threads!r}: expected a whole number of "
                     "threads >= 1 (or leave it unset for all cores)", EXIT_USAGE)
    try:
        with _latched_signals():
            return _main(argv, state)
    except KeyboardInterrupt as exc:  # one that landed after the command's own handling
        return _fail("interrupted", EXIT_INTERRUPTED, exc, state["debug"])
    except Terminated as exc:
        return _fail("terminated", 128 + exc.signum, exc, state["debug"])


@contextlib.contextmanager
def _latched_signals():
    """progress.latch_interrupts (Ctrl-C, SIGTERM, SIGHUP) for the duration of a command (main
    thread only)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    from osmap_cli import progress

    names = [n for n in _STOP_SIGNALS if hasattr(signal, n)]
    previous = {n: signal.getsignal(getattr(signal, n)) for n in names}
    progress.latch_interrupts()
    try:
        yield
    finally:
        for name, handler in previous.items():
            signal.signal(getattr(signal, name), _record_stop if _console[0] else handler)
        progress.reset_interrupt()


def _main(argv: list[str] | None, state: dict) -> int:
    try:
        result = cli.main(args=argv, prog_name="osmap", standalone_mode=False, obj=state)
    except UsageError as exc:
        return _fail(f"error: {exc}", EXIT_USAGE, exc, state["debug"])
    except OsmapError as exc:
        return _fail(f"error: {exc}", EXIT_ERROR, exc, state["debug"])
    except click.UsageError as exc:
        message = exc.format_message().rstrip(".")
        if exc.ctx is not None:
            message += f" (see '{exc.ctx.command_path} --help')"
        return _fail(f"error: {message}", EXIT_USAGE, exc, state["debug"])
    except click.ClickException as exc:
        return _fail(f"error: {exc.format_message()}", exc.exit_code or EXIT_ERROR, exc,
                     state["debug"])
    except (_Interrupted, click.Abort, KeyboardInterrupt) as exc:
        return _fail("interrupted", EXIT_INTERRUPTED, exc, state["debug"])
    except Terminated as exc:
        return _fail("terminated", 128 + exc.signum, exc, state["debug"])
    except BrokenPipeError:
        return _closed_stdout()
    except SystemExit:
        # click ends the run with exit(1) when stdout's reader went away (EPIPE), after
        # wrapping stdout so that nothing more is reported
        if type(sys.stdout).__name__.lstrip("_") == "PacifyFlushWrapper":
            return _closed_stdout()
        raise
    except Exception as exc:  # the last line of defence: one line, no traceback
        debug = state["debug"]
        detail = str(exc) or "(no message)"
        hint = "" if debug else " (run with --debug or OSMAP_DEBUG=1 for details)"
        return _fail(f"internal error: {type(exc).__name__}: {detail}{hint}", EXIT_ERROR, exc,
                     debug)
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        return _closed_stdout()
    return result if isinstance(result, int) else EXIT_OK


def _closed_stdout() -> int:
    """The reader of stdout went away (`osmap presets | head -1`): stop quietly, as Unix tools
    do, with the exit status of SIGPIPE."""
    import signal

    # Python would report the unflushed rest at exit: point stdout at /dev/null instead.
    with contextlib.suppress(OSError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    return 128 + getattr(signal, "SIGPIPE", 13)


# ---------------------------------------------------------------------------------------------
# the console script and its exit

_console = [False]  # running as the console script: stop signals after the command are recorded
_stopped_after: list = [None]  # a stop signal that arrived after the command


def run() -> None:
    """The `osmap` console script: main(), then exit_now() with its code.

    Stop signals are only recorded outside the command (main latches them during it), so one
    that lands while the process ends, after the outputs are committed, still exits with
    128 + its number and one line, instead of killing the interpreter half torn down.
    """
    _console[0] = True
    _single_threaded_blas()  # before prepare() may import numpy
    os.environ.setdefault("OSMAP_KERNELS", "auto")
    os.environ.setdefault("OSMAP_QUICK_LOADS", "1")  # osmap_kernels.cacheload
    from osmap_cli import kernelwarm

    kernelwarm.prepare()
    exit_now(main())


def _record_stop(signum, frame) -> None:
    _stopped_after[0] = signum


def exit_now(code: int) -> None:
    """End the process with CODE, skipping the interpreter's teardown.

    Skipped is only what Python does after the exit handlers: freeing every object and module,
    and joining idle worker threads. Kept, in order: flushing stdout and stderr; the exit
    handlers (atexit: temporary folders, multiprocessing's children and semaphores, anything a
    library registered); a background compile for this CPU when the run used the portable
    kernels (osmap_cli.kernelwarm). Every output was committed or removed by the command
    itself, progress bars are closed by their jobs, a local Dask cluster by its `with` block.
    """
    import atexit
    import signal

    stdout_closed = False
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        stdout_closed = True
    except (OSError, ValueError):
        pass
    if stdout_closed:
        code = _closed_stdout()
    with contextlib.suppress(Exception):
        atexit._run_exitfuncs()
    if code == EXIT_OK:
        from osmap_cli import kernelwarm

        kernelwarm.after_run()
    stops = {getattr(signal, n) for n in _STOP_SIGNALS if hasattr(signal, n)}
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_BLOCK, stops)
    signum = _stop_recorded()  # a handler still pending has run by the time this returns
    if signum is not None:
        code = _fail("interrupted" if signum == signal.SIGINT else "terminated", 128 + signum)
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(code)


def _stop_recorded() -> int | None:
    return _stopped_after[0]


if __name__ == "__main__":  # pragma: no cover
    run()
