"""`osmap warmup`: compile the kernels for this CPU now (osmap_cli.kernelwarm)."""

from __future__ import annotations

import sys

import click

from osmap_cli.commands.common import CONTEXT_SETTINGS
from osmap_cli.errors import OsmapError

__all__ = ["warmup_command"]

WARMUP_EPILOG = """\b
Examples:
  osmap warmup            # after installing, e.g. in a Dockerfile or a CI set-up step
  osmap warmup --quiet
"""


@click.command("warmup", epilog=WARMUP_EPILOG, context_settings=CONTEXT_SETTINGS,
               short_help="Compile the kernels for this CPU now.")
@click.option("-q", "--quiet", is_flag=True, help="Print nothing.")
def warmup_command(quiet: bool) -> None:
    """Compile every kernel the commands use for this CPU into Numba's cache, on every core,
    unless that is done already.

    Optional. An installed osmap ships portable kernels (compiled for any CPU of its kind, about
    15 % slower): the first runs use them and start at once, and after the first one this CPU's
    kernels compile in the background, at the lowest priority; warmup does that now instead
    (e.g. in a Dockerfile or a CI set-up step). Without portable kernels (a development tree),
    the first run of a command compiles its kernels, and warmup does all of them now.

    OSMAP_KERNELS chooses which kernels the osmap command uses: auto (the default: this CPU's
    once compiled, the portable ones until then, then the background compile), portable (the
    same without the background compile: this CPU's once warmup compiled them), host (this
    CPU's only, compiled on first use).
    """
    from osmap_cli.kernelwarm import warm_host

    def announce(line):
        print(line, file=sys.stderr, flush=True)

    try:
        compiled = warm_host(None if quiet else announce)
    except RuntimeError as exc:
        raise OsmapError(str(exc)) from None
    if not quiet:
        click.echo("osmap: kernels compiled" if compiled else "osmap: kernels already compiled")
