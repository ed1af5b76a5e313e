"""Presets: named sets of synthesis tunables, stored as TOML.

A preset file looks like this (every key of ``[synth]`` is optional; keys not given keep the
built-in defaults of :class:`osmap_cli.synth.options.SynthOptions`)::

    name = "structured"
    description = "regular textures: bricks, tiles, weaves"

    [synth]
    patch_radius = 3
    sweeps = 4

`osmap solid` reads the ``[solid]`` table instead (its tunables are those of
:class:`osmap_cli.solid.options.SolidOptions`); one file may hold both tables. The built-in synth
presets live in the ``presets/`` folder of the repository, the solid ones in ``presets/solid/``,
installed as the package ``osmap_presets``; the ``default`` presets are not files but written
out from the option declarations. ``--preset`` takes either a built-in name or a path to a
``.toml`` file:

>>> load_preset("structured")["patch_radius"]
3
>>> load_preset("my/own.toml")          # a user file, validated the same way  # doctest: +SKIP
>>> list_presets()[0]
('default', 'the built-in defaults: a good start for most textures')
>>> read_preset("fast", "solid").values["iterations"]
1

Every problem (unknown name, missing file, malformed TOML, unknown key, wrong type, value out of
range) raises :class:`~osmap_cli.errors.OsmapError` with a one-line message naming the file and
the key.

This module must stay light (no numpy / numba at import time).
"""

from __future__ import annotations

import importlib
import os
import sys
from dataclasses import dataclass, field
from importlib import resources

from osmap_cli.errors import OsmapError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10 needs the tomli backport
    import tomli as tomllib

__all__ = [
    "DEFAULT_PRESET",
    "Preset",
    "builtin_names",
    "is_preset_path",
    "list_presets",
    "load_preset",
    "preset_text",
    "read_preset",
]

PACKAGE = "osmap_presets"
DEFAULT_PRESET = "default"
# table -> (options class, built-in folder inside the package, description of "default")
TABLES = {
    "synth": ("osmap_cli.synth.options:SynthOptions", "",
              "the built-in defaults: a good start for most textures"),
    "solid": ("osmap_cli.solid.options:SolidOptions", "solid",
              "the built-in defaults: stone, marble, terrazzo, gravel"),
}
_TOP_LEVEL_KEYS = ("name", "description", *TABLES)
_DEFAULT_HEADER = {
    "synth": "# The built-in defaults of `osmap synth`, written out: every tunable and its value.",
    "solid": "# The built-in defaults of `osmap solid`, written out: every tunable and its value.",
}


def options_class(table: str):
    """The options dataclass whose tunables fill a preset's TABLE."""
    module, name = TABLES[table][0].split(":")
    return getattr(importlib.import_module(module), name)


@dataclass(frozen=True)
class Preset:
    """A loaded, validated preset: ``values`` holds the ``[synth]`` table (tunable -> value)."""

    name: str
    description: str
    values: dict = field(default_factory=dict)
    source: str = ""


# ---------------------------------------------------------------------------------------------
# locating presets


def _builtin_dir(table: str = "synth"):
    folder = resources.files(PACKAGE)
    return folder / TABLES[table][1] if TABLES[table][1] else folder


def builtin_names(table: str = "synth") -> list[str]:
    """Names of the built-in presets for TABLE's command, "default" first, the rest sorted."""
    names = sorted(
        entry.name[: -len(".toml")]
        for entry in _builtin_dir(table).iterdir()
        if entry.name.endswith(".toml") and entry.is_file()
    )
    return [DEFAULT_PRESET] + [n for n in names if n != DEFAULT_PRESET]


def default_preset_text(table: str = "synth") -> str:
    """The "default" preset: every tunable of TABLE's options class at its declared default."""
    from osmap_cli.options import preset_toml

    header = (_DEFAULT_HEADER[table] + "\n# Copy this file, edit it and pass it with "
              "`--preset my.toml`. Keys you leave out keep these\n# values; options given on the "
              "command line override the file.")
    return preset_toml(options_class(table), table, DEFAULT_PRESET, TABLES[table][2], {},
                       header)


def is_preset_path(name_or_path: str) -> bool:
    """True when ``--preset`` names a file (ends in .toml or contains a path separator)."""
    text = os.fspath(name_or_path)
    separators = {"/", os.sep} | ({os.altsep} if os.altsep else set())
    return text.lower().endswith(".toml") or any(s in text for s in separators)


def _read_source(name_or_path: str, table: str = "synth") -> tuple[str, str]:
    """(TOML text, display name of the source) for a built-in name or a file path."""
    text_name = os.fspath(name_or_path)
    if is_preset_path(text_name):
        try:
            with open(text_name, "rb") as handle:
                raw = handle.read()
        except FileNotFoundError:
            raise OsmapError(f"{text_name}: no such preset file") from None
        except IsADirectoryError:
            raise OsmapError(f"{text_name}: is a directory, not a preset file") from None
        except OSError as exc:
            raise OsmapError(
                f"{text_name}: cannot read preset file ({exc.strerror or exc})"
            ) from None
        source = text_name
    else:
        names = builtin_names(table)
        if text_name not in names:
            kind = "" if table == "synth" else f"{table} "
            raise OsmapError(
                f"--preset: unknown {kind}preset {text_name!r} (built-in: {', '.join(names)}; "
                "or give the path of a .toml file)"
            )
        source = f"{text_name}.toml (built-in preset)"
        if text_name == DEFAULT_PRESET:
            return default_preset_text(table), source
        raw = (_builtin_dir(table) / f"{text_name}.toml").read_bytes()
    try:
        return raw.decode("utf-8"), source
    except UnicodeDecodeError as exc:
        raise OsmapError(
            f"{source}: not a UTF-8 text file ({exc.reason} at byte {exc.start})"
        ) from None


def _parse(text: str, source: str) -> dict:
    try:
        document = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        message = " ".join(str(exc).split())
        raise OsmapError(f"{source}: invalid TOML: {message}") from None
    for key in document:
        if key not in _TOP_LEVEL_KEYS:
            raise OsmapError(
                f"{source}: unknown top-level key {key!r} (allowed: name, description, "
                f"{', '.join(f'[{t}]' for t in TABLES)})"
            )
    for key in ("name", "description"):
        if key in document and not isinstance(document[key], str):
            raise OsmapError(f"{source}: {key} must be a string, got {document[key]!r}")
    for table in TABLES:
        if table in document and not isinstance(document[table], dict):
            raise OsmapError(f"{source}: {table} must be a table ([{table}]), "
                             f"got {document[table]!r}")
    return document


# ---------------------------------------------------------------------------------------------
# validation


def _validate(document: dict, source: str, table: str) -> dict:
    """The [TABLE] values checked against its options class (the keys and each value, then
    the constraints between keys)."""
    from osmap_cli.options import check_preset_value

    cls = options_class(table)
    tunables = cls.tunables()
    values: dict = {}
    for key, value in document.get(table, {}).items():
        if key not in tunables:
            raise OsmapError(
                f"{source}: [{table}] unknown key {key!r} (allowed: {', '.join(tunables)})"
            )
        values[key] = check_preset_value(f"{source}: [{table}] {key}", value, tunables[key])
    try:  # constraints between keys (e.g. som_sigma_min <= som_sigma_max)
        cls().replace(**values).validated()
    except OsmapError as exc:
        raise OsmapError(f"{source}: [{table}] {exc}") from None
    return values


# ---------------------------------------------------------------------------------------------
# public API


def read_preset(name_or_path: str = DEFAULT_PRESET, table: str = "synth") -> Preset:
    """Load and validate a built-in preset (by name) or a preset file (a path ending in .toml);
    ``values`` is its [TABLE] ("synth" or "solid"). A file's other tables are validated too."""
    text, source = (_read_source(name_or_path) if table == "synth"
                    else _read_source(name_or_path, table))
    document = _parse(text, source)
    if table != "synth" and is_preset_path(name_or_path) and table not in document:
        raise OsmapError(f"{source}: no [{table}] table (osmap {table} reads its tunables from "
                         f"[{table}])")
    tables = {t: _validate(document, source, t) for t in TABLES if t in document or t == table}
    values = tables[table]
    fallback = os.path.splitext(os.path.basename(os.fspath(name_or_path)))[0]
    return Preset(
        name=document.get("name", fallback),
        description=document.get("description", ""),
        values=values,
        source=source,
    )


def load_preset(name_or_path: str = DEFAULT_PRESET, table: str = "synth") -> dict:
    """The validated ``[TABLE]`` of a preset: {tunable name: value}."""
    return dict(read_preset(name_or_path, table).values)


def list_presets(table: str = "synth") -> list[tuple[str, str]]:
    """(name, description) of every built-in preset of TABLE's command, "default" first."""
    result = []
    for name in builtin_names(table):
        text, source = _read_source(name, table)
        result.append((name, _parse(text, source).get("description", "")))
    return result


def preset_text(name_or_path: str, table: str = "synth") -> str:
    """The TOML source of a built-in preset (by name) or of a preset file."""
    return _read_source(name_or_path, table)[0]
