"""Presets: named sets of synthesis tunables, stored as TOML.

A preset file looks like this (every key of ``[synth]`` is optional; keys not given keep the
built-in defaults of :class:`osmap_cli.synth.options.SynthOptions`)::

    name = "structured"
    description = "regular textures: bricks, tiles, weaves"

    [synth]
    patch_radius = 3
    sweeps = 4

The built-in presets live in the ``presets/`` folder of the repository, installed as the package
``osmap_presets``. ``--preset`` takes either a built-in name or a path to a ``.toml`` file:

>>> load_preset("structured")["patch_radius"]
3
>>> load_preset("my/own.toml")          # a user file, validated the same way
>>> list_presets()[0]
('default', 'the built-in defaults: a good start for most textures')

Every problem (unknown name, missing file, malformed TOML, unknown key, wrong type, value out of
range) raises :class:`~osmap_cli.errors.OsmapError` with a one-line message naming the file and
the key.

This module is imported by ``osmap --help``: it must stay light (no numpy / numba at import
time); the tunables are looked up only when a preset is validated.
"""

from __future__ import annotations

import math
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
_TOP_LEVEL_KEYS = ("name", "description", "synth")


@dataclass(frozen=True)
class Preset:
    """A loaded, validated preset: ``values`` holds the ``[synth]`` table (tunable -> value)."""

    name: str
    description: str
    values: dict = field(default_factory=dict)
    source: str = ""


# ---------------------------------------------------------------------------------------------
# locating presets


def _builtin_dir():
    return resources.files(PACKAGE)


def builtin_names() -> list[str]:
    """Names of the built-in presets, sorted, with "default" first."""
    names = sorted(
        entry.name[: -len(".toml")]
        for entry in _builtin_dir().iterdir()
        if entry.name.endswith(".toml") and entry.is_file()
    )
    if DEFAULT_PRESET in names:
        names.remove(DEFAULT_PRESET)
        names.insert(0, DEFAULT_PRESET)
    return names


def is_preset_path(name_or_path: str) -> bool:
    """True when ``--preset`` names a file (ends in .toml or contains a path separator)."""
    text = os.fspath(name_or_path)
    separators = {"/", os.sep} | ({os.altsep} if os.altsep else set())
    return text.lower().endswith(".toml") or any(s in text for s in separators)


def _read_source(name_or_path: str) -> tuple[str, str]:
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
        names = builtin_names()
        if text_name not in names:
            raise OsmapError(
                f"--preset: unknown preset {text_name!r} (built-in: {', '.join(names)}; "
                "or give the path of a .toml file)"
            )
        raw = (_builtin_dir() / f"{text_name}.toml").read_bytes()
        source = f"{text_name}.toml (built-in preset)"
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
                f"{source}: unknown top-level key {key!r} (allowed: name, description, [synth])"
            )
    for key in ("name", "description"):
        if key in document and not isinstance(document[key], str):
            raise OsmapError(f"{source}: {key} must be a string, got {document[key]!r}")
    if "synth" in document and not isinstance(document["synth"], dict):
        raise OsmapError(f"{source}: synth must be a table ([synth]), got {document['synth']!r}")
    return document


# ---------------------------------------------------------------------------------------------
# validation


def _check_value(source: str, key: str, value, spec) -> object:
    """The value of one [synth] key checked against its SynthOptions field; returns it."""
    default = spec.default
    where = f"{source}: [synth] {key}"
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise OsmapError(f"{where} must be true or false, got {value!r}")
        return value
    if isinstance(default, str):
        if not isinstance(value, str):
            raise OsmapError(f"{where} must be a string, got {value!r}")
        return value
    if isinstance(default, int):
        if isinstance(value, bool) or not isinstance(value, int):
            raise OsmapError(f"{where} must be a whole number, got {value!r}")
    else:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise OsmapError(f"{where} must be a number, got {value!r}")
        if not math.isfinite(value):
            raise OsmapError(f"{where} must be a finite number, got {value!r}")
        value = float(value)
    lo, hi = spec.metadata.get("lo"), spec.metadata.get("hi")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise OsmapError(f"{where} = {value!r} is out of range (allowed {lo} to {hi})")
    return value


def _validate(document: dict, source: str) -> dict:
    # Imported here, not at module level: osmap --help must not import numpy / numba.
    from osmap_cli.synth.options import SynthOptions

    tunables = SynthOptions.tunables()
    values: dict = {}
    for key, value in document.get("synth", {}).items():
        if key not in tunables:
            raise OsmapError(
                f"{source}: [synth] unknown key {key!r} (allowed: {', '.join(tunables)})"
            )
        values[key] = _check_value(source, key, value, tunables[key])
    try:  # constraints between keys (e.g. som_sigma_min <= som_sigma_max)
        SynthOptions().replace(**values).validated()
    except OsmapError as exc:
        raise OsmapError(f"{source}: [synth] {exc}") from None
    return values


# ---------------------------------------------------------------------------------------------
# public API


def read_preset(name_or_path: str = DEFAULT_PRESET) -> Preset:
    """Load and validate a built-in preset (by name) or a preset file (a path ending in .toml)."""
    text, source = _read_source(name_or_path)
    document = _parse(text, source)
    values = _validate(document, source)
    fallback = os.path.splitext(os.path.basename(os.fspath(name_or_path)))[0]
    return Preset(
        name=document.get("name", fallback),
        description=document.get("description", ""),
        values=values,
        source=source,
    )


def load_preset(name_or_path: str = DEFAULT_PRESET) -> dict:
    """The validated ``[synth]`` table of a preset: {tunable name: value}."""
    return dict(read_preset(name_or_path).values)


def list_presets() -> list[tuple[str, str]]:
    """(name, description) of every built-in preset, "default" first (not validated)."""
    result = []
    for name in builtin_names():
        text, source = _read_source(name)
        result.append((name, _parse(text, source).get("description", "")))
    return result


def preset_text(name_or_path: str) -> str:
    """The TOML source of a built-in preset (by name) or of a preset file."""
    return _read_source(name_or_path)[0]
