"""`osmap warmup`: compile the synth kernels now (what the first `osmap synth` would do)."""

from __future__ import annotations

import sys

import click

from osmap_cli.commands.common import CONTEXT_SETTINGS

__all__ = ["warmup_command"]

WARMUP_EPILOG = """\b
Examples:
  osmap warmup            # after installing, e.g. in a Dockerfile or a CI set-up step
  osmap warmup --quiet
"""


@click.command("warmup", epilog=WARMUP_EPILOG, context_settings=CONTEXT_SETTINGS,
               short_help="Compile the synth kernels now, not on the first synth.")
@click.option("-q", "--quiet", is_flag=True, help="Print nothing.")
def warmup_command(quiet: bool) -> None:
    """Compile the Numba kernels `osmap synth` uses into Numba's cache, if they are not
    there yet (two processes at once), so that the first synthesis starts at once. Optional:
    `osmap synth` does the same on its first run, and says so."""
    from osmap_cli.synth.warm import ensure_compiled

    def announce(line):
        print(line, file=sys.stderr, flush=True)

    compiled = ensure_compiled(None if quiet else announce)
    if not quiet:
        click.echo("osmap: kernels compiled" if compiled else "osmap: kernels already compiled")
