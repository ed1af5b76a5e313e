"""Options declared once: each command's options class is a frozen dataclass whose fields are
made with :func:`option`, and everything else is derived from those declarations.

>>> from osmap_cli.synth.options import SynthOptions
>>> spec = option_spec(SynthOptions, "seam")
>>> spec.lo, spec.hi, spec.default
(0.0, 10.0, 1.0)
>>> SynthOptions(seam=99.0).validated()
Traceback (most recent call last):
...
osmap_cli.errors.OsmapError: --seam: 99.0 is out of range (allowed 0.0 to 10.0)

From the same declaration come: validation (:func:`validate`), the preset tables (the tunable
fields: :func:`tunables`, :func:`check_preset_value`, :func:`preset_toml`), the command-line
tuning flags (:func:`osmap_cli.commands.common.tuning_flags`), the canonical flags stored as
provenance (:func:`flag_args`) and the usage reference (:func:`usage_rows`). Adding a tunable
touches its declaration and its use, nothing else.

This module imports neither numpy nor Numba: ``osmap COMMAND --help`` stays fast.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass

from osmap_cli.errors import OsmapError

__all__ = ["Options", "OptionSpec", "check_number", "check_preset_value", "flag_args", "option",
           "option_spec", "preset_toml", "tunables", "usage_rows", "validate"]


@dataclass(frozen=True)
class OptionSpec:
    """What a field accepts: a range for numbers, the choices for text; help is one phrase."""

    default: object
    lo: float | None = None
    hi: float | None = None
    help: str = ""
    choices: tuple[str, ...] = ()
    tunable: bool = False  # a preset key and a tuning flag

    @property
    def kind(self) -> type:
        return type(self.default)


class Options:
    """The methods every options dataclass shares (subclass it with a frozen dataclass whose
    fields are made with :func:`option`)."""

    @classmethod
    def tunables(cls) -> dict[str, OptionSpec]:
        """The fields a preset may set: {name: OptionSpec}."""
        return tunables(cls)

    def replace(self, **changes):
        """A copy with some fields changed (not yet validated)."""
        return dataclasses.replace(self, **changes)

    def validated(self):
        """These options checked field by field, then across fields; raises OsmapError on the
        first bad value, else returns them."""
        validate(self)
        self.check_relations()
        return self

    def check_relations(self) -> None:
        """Constraints between fields (none by default)."""


def option(default, lo=None, hi=None, help: str = "", *, choices: tuple[str, ...] = (),
           tunable: bool = False) -> dataclasses.Field:
    """A dataclass field carrying its OptionSpec (see the module docstring)."""
    spec = OptionSpec(default, lo, hi, help, tuple(choices), tunable)
    return dataclasses.field(default=default, metadata={"spec": spec})


def option_spec(cls_or_options, name: str) -> OptionSpec:
    """The OptionSpec of one field."""
    return {f.name: f for f in dataclasses.fields(cls_or_options)}[name].metadata["spec"]


def tunables(cls_or_options) -> dict[str, OptionSpec]:
    """The tunable fields (preset keys and tuning flags), in declaration order."""
    return {f.name: f.metadata["spec"] for f in dataclasses.fields(cls_or_options)
            if f.metadata["spec"].tunable}


def flag(name: str) -> str:
    """The command-line flag of a field: som_sigma_max -> --som-sigma-max."""
    return "--" + name.replace("_", "-")


def check_number(option_name: str, value, spec: OptionSpec, where: str = "") -> None:
    """Raise OsmapError unless value is a finite number of the spec's kind inside [lo, hi]."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise OsmapError(f"{where}{option_name}: expected a number, got {value!r}")
    if spec.kind is int:
        if not isinstance(value, numbers.Integral) and not (
                math.isfinite(value) and float(value).is_integer()):
            raise OsmapError(f"{where}{option_name}: expected a whole number, got {value!r}")
    elif not math.isfinite(float(value)):
        raise OsmapError(f"{where}{option_name}: expected a finite number, got {value!r}")
    # integers compare exactly: a seed near 2**63 must not be rounded through a float
    if not spec.lo <= value <= spec.hi:
        raise OsmapError(f"{where}{option_name}: {value!r} is out of range "
                         f"(allowed {spec.lo} to {spec.hi})")


def validate(options) -> None:
    """Check every field of an options dataclass against its spec; raises OsmapError."""
    for f in dataclasses.fields(options):
        spec, value = f.metadata["spec"], getattr(options, f.name)
        name = flag(f.name)
        if spec.kind is bool:
            # numpy's truth values: numpy.bool_ ("bool" since numpy 2)
            if not isinstance(value, bool) and type(value).__name__ not in ("bool", "bool_"):
                raise OsmapError(f"{name}: expected true or false, got {value!r}")
        elif spec.kind is str:
            if spec.choices and value not in spec.choices:
                raise OsmapError(f"{name}: {value!r} is not one of {', '.join(spec.choices)}")
        else:
            check_number(name, value, spec)


def check_preset_value(where: str, value, spec: OptionSpec):
    """One preset key's value checked against its spec; returns it (floats as float).

    `where` names the file, table and key for the message, e.g. "fast.toml: [synth] sweeps".
    """
    if spec.kind is bool:
        if not isinstance(value, bool):
            raise OsmapError(f"{where} must be true or false, got {value!r}")
        return value
    if spec.kind is str:
        if not isinstance(value, str):
            raise OsmapError(f"{where} must be a string, got {value!r}")
        if spec.choices and value not in spec.choices:
            raise OsmapError(f"{where} = {value!r} is not one of {', '.join(spec.choices)}")
        return value
    if spec.kind is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise OsmapError(f"{where} must be a whole number, got {value!r}")
    else:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise OsmapError(f"{where} must be a number, got {value!r}")
        if not math.isfinite(value):
            raise OsmapError(f"{where} must be a finite number, got {value!r}")
        value = float(value)
    if (spec.lo is not None and value < spec.lo) or (spec.hi is not None and value > spec.hi):
        raise OsmapError(f"{where} = {value!r} is out of range (allowed {spec.lo} to {spec.hi})")
    return value


def number_text(value) -> str:
    """The shortest text that reads back as exactly `value` (flags, TOML)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):  # a free-text option (no choices)
        return value
    if isinstance(value, int):
        return str(value)
    value = float(value)
    return str(int(value)) if value.is_integer() and abs(value) < 1e15 else repr(value)


def flag_args(options, baseline) -> list[str]:
    """`--flag value` for every tunable of `options` that differs from `baseline` (None: all)."""
    args = []
    for name in tunables(options):
        value = getattr(options, name)
        if baseline is None or value != getattr(baseline, name):
            args += [flag(name), value if isinstance(value, str) else number_text(value)]
    return args


def preset_toml(cls, table: str, name: str, description: str, values: dict,
                header: str = "") -> str:
    """A preset file's text: the `[table]` holds every tunable (VALUES over the defaults),
    each with its help as a comment."""
    defaults = cls()
    lines = [header.rstrip("\n")] if header else []
    lines += [f'name = "{name}"', f'description = "{description}"', "", f"[{table}]"]
    specs = tunables(cls)
    width = max(28, max(len(key) for key in specs) + 10)
    for key, spec in specs.items():
        value = values.get(key, getattr(defaults, key))
        if spec.kind is str:
            lines.append(f'{key} = "{value}"'.ljust(width)
                         + f"# {', '.join(spec.choices) or spec.help}")
            continue
        text = number_text(float(value) if spec.kind is float else value)
        if spec.kind is float and "." not in text and "e" not in text:
            text += ".0"
        lines.append(f"{key} = {text}".ljust(width) + f"# {spec.help}")
    return "\n".join(lines) + "\n"


def usage_rows(cls) -> list[str]:
    """Markdown table rows (flag, default, range, meaning) of the tunables, for docs/usage.md."""
    rows = []
    defaults = cls()
    for key, spec in tunables(cls).items():
        if spec.kind is str:
            rows.append(f"| `{flag(key)} M` | {getattr(defaults, key)} | "
                        f"{', '.join(spec.choices) or 'text'} | {spec.help} |")
            continue
        metavar = "N" if spec.kind is int else "X"
        default = number_text(getattr(defaults, key))
        rows.append(f"| `{flag(key)} {metavar}` | {default} | {number_text(spec.lo)} to "
                    f"{number_text(spec.hi)} | {spec.help} |")
    return rows
