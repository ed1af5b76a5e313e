"""`osmap presets`: list the built-in tuning presets and print their TOML."""

from __future__ import annotations

import click

from osmap_cli.commands.common import CONTEXT_SETTINGS

__all__ = ["presets_command"]


PRESETS_EPILOG = """\b
Examples:
  osmap presets
  osmap presets show structured
  osmap presets show default > my_preset.toml
  osmap synth samples/cells.png -o out/cells.png --preset my_preset.toml
  osmap presets --solid
  osmap presets show fast --solid
"""


_FOR_SOLID = click.option("--solid", is_flag=True,
                          help="The presets of 'osmap solid' ([solid] tables) instead.")


@click.group(
    "presets",
    cls=click.Group,
    invoke_without_command=True,
    epilog=PRESETS_EPILOG,
    short_help="List or show the tuning presets.",
    context_settings=CONTEXT_SETTINGS,
)
@_FOR_SOLID
@click.pass_context
def presets_command(ctx: click.Context, solid: bool) -> None:
    """List the built-in tuning presets, one per line: name and description.

    A preset is a TOML file with "name", "description" and a [synth] table of
    tuning values (see 'osmap presets show default' for every key). Use one with
    'osmap synth --preset NAME' or '--preset FILE.toml'; tuning flags given on the
    command line override the preset. With --solid: the presets of 'osmap solid'
    and their [solid] tables.
    """
    if ctx.invoked_subcommand is None:
        _print_presets("solid" if solid else "synth")


@presets_command.command(
    "list",
    epilog="""\b
Examples:
  osmap presets list
""",
)
@_FOR_SOLID
def presets_list_command(solid: bool) -> None:
    """List the built-in presets (the same as 'osmap presets')."""
    _print_presets("solid" if solid else "synth")


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
@_FOR_SOLID
def presets_show_command(name: str, solid: bool) -> None:
    """Print the TOML text of a built-in preset (or of a preset file)."""
    from osmap_cli.presets import builtin_names, is_preset_path, preset_text

    table = "solid" if solid else "synth"
    if not is_preset_path(name) and name not in builtin_names(table):
        raise click.BadParameter(
            f"unknown preset {name!r} (built-in: {', '.join(builtin_names(table))})",
            param_hint="'NAME'",
        )
    text = preset_text(name, table)
    click.echo(text, nl=not text.endswith("\n"))


def _print_presets(table: str) -> None:
    from osmap_cli.presets import list_presets

    presets = list_presets(table)
    width = max((len(name) for name, _ in presets), default=0)
    for name, description in presets:
        click.echo(f"{name:<{width}}  {description}".rstrip())
