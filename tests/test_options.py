"""osmap_cli.options: validation, preset values, canonical flags and the tables made from one
declaration, on a small options class of every kind (independent of the commands' options)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import pytest

from osmap_cli.errors import OsmapError
from osmap_cli.options import (
    Options,
    OptionSpec,
    check_number,
    check_preset_value,
    flag,
    flag_args,
    number_text,
    option,
    option_spec,
    preset_toml,
    tunables,
    usage_rows,
    validate,
)


@dataclass(frozen=True)
class Demo(Options):
    size: int = option(64, 8, 4096, "output side")
    ratio: float = option(0.5, 0.0, 1.0, "plain ratio")
    smooth: bool = option(False, help="smooth it")
    mode: str = option("fast", help="how", choices=("fast", "slow"))
    big_seed: int = option(0, 0, 2**63 - 1, "seed")
    sweeps: int = option(3, 0, 20, "sweeps per level", tunable=True)
    step_size: float = option(1.5, 0.25, 8.0, "step", tunable=True)
    kind: str = option("a", help="kind", choices=("a", "b", "c"), tunable=True)

    def check_relations(self) -> None:
        if self.sweeps > self.size:
            raise OsmapError("sweeps exceeds size")


@dataclass(frozen=True)
class Wide(Options):
    """A text tunable first, a long name (wider columns), a huge whole number."""

    mode: str = option("a", help="m", choices=("a", "b"), tunable=True)
    a_rather_long_tunable_name: float = option(1.0, 0.0, 1e30, "long", tunable=True)
    count: int = option(2, 0, 10**30, "c", tunable=True)


def test_option_declares_a_field_and_its_spec():
    """Declared here, at test time: option()'s defaults are those of OptionSpec."""
    @dataclass(frozen=True)
    class Local(Options):
        plain: int = option(3)
        ranged: float = option(0.5, 0.0, 1.0, "r", tunable=True)
        picked: str = option("x", choices=["x", "y"])

    fields = {f.name: f for f in dataclasses.fields(Local)}
    assert fields["plain"].default == 3 and Local().ranged == 0.5 and Local().picked == "x"
    assert fields["plain"].metadata["spec"] == OptionSpec(3, None, None, "", (), False)
    assert option_spec(Local, "ranged") == OptionSpec(0.5, 0.0, 1.0, "r", (), True)
    assert option_spec(Local, "picked") == OptionSpec("x", None, None, "", ("x", "y"), False)
    assert list(tunables(Local)) == ["ranged"]


def test_spec_of_a_field_and_its_kind():
    spec = option_spec(Demo, "step_size")
    assert (spec.default, spec.lo, spec.hi, spec.help, spec.tunable) == (1.5, 0.25, 8.0, "step",
                                                                         True)
    assert spec.kind is float and option_spec(Demo, "mode").choices == ("fast", "slow")
    assert option_spec(Demo(), "size").kind is int and not option_spec(Demo, "size").tunable
    assert Demo().step_size == 1.5  # the declared default is the field's default


def test_tunables_in_declaration_order():
    assert list(tunables(Demo)) == ["sweeps", "step_size", "kind"]
    assert list(Demo.tunables()) == list(tunables(Demo()))


def test_flag_names():
    assert flag("som_sigma_max") == "--som-sigma-max" and flag("seed") == "--seed"


@pytest.mark.parametrize("value, message", [
    (True, "expected a number, got True"), ("3", "expected a number, got '3'"),
    (2.5, "expected a whole number, got 2.5"), (math.inf, "expected a whole number"),
    (7, "7 is out of range (allowed 8 to 4096)"), (4097, "4097 is out of range"),
])
def test_check_number_refuses_for_an_int(value, message):
    with pytest.raises(OsmapError, match="^where: --size: " + message.replace("(", r"\(")
                       .replace(")", r"\)")):
        check_number("--size", value, option_spec(Demo, "size"), "where: ")


@pytest.mark.parametrize("value", [8, 4096, 64.0, 100])
def test_check_number_accepts_whole_values_in_range(value):
    check_number("--size", value, option_spec(Demo, "size"))


def test_check_number_floats_and_huge_integers():
    spec = option_spec(Demo, "ratio")
    for bad, text in ((math.nan, "expected a finite number, got nan"),
                      (math.inf, "expected a finite number"), (-0.01, "out of range"),
                      (1.01, "out of range")):
        with pytest.raises(OsmapError, match=text):
            check_number("--ratio", bad, spec)
    with pytest.raises(OsmapError, match=r"^--ratio: 2 is out of range \(allowed 0.0 to 1.0\)$"):
        check_number("--ratio", 2, spec)  # no `where`: the message starts with the option
    check_number("--ratio", 0.0, spec)
    check_number("--ratio", 1, spec)
    seed = option_spec(Demo, "big_seed")
    check_number("--big-seed", 2**63 - 1, seed)  # compared exactly, not through a float
    with pytest.raises(OsmapError, match="out of range"):
        check_number("--big-seed", 2**63, seed)


def test_validate_every_kind():
    assert Demo().validated() == Demo()
    for changes, text in (({"smooth": 1}, "--smooth: expected true or false, got 1"),
                          ({"mode": "quick"}, "--mode: 'quick' is not one of fast, slow"),
                          ({"kind": "z"}, "--kind: 'z' is not one of a, b, c"),
                          ({"step_size": 9.0}, "--step-size: 9.0 is out of range"),
                          ({"sweeps": 2.0 + 0.5}, "--sweeps: expected a whole number"),
                          ({"sweeps": 20, "size": 10}, "sweeps exceeds size")):
        with pytest.raises(OsmapError, match=text):
            Demo().replace(**changes).validated()
    import numpy as np

    validate(Demo(smooth=np.bool_(True)))  # numpy's truth values are true or false too
    assert Demo().replace(size=128).size == 128 and Demo().size == 64


@pytest.mark.parametrize("name, value, expected", [
    ("sweeps", 4, 4), ("step_size", 2, 2.0), ("step_size", 0.25, 0.25), ("kind", "c", "c"),
    ("smooth", True, True), ("smooth", False, False), ("step_size", 8, 8.0),
])
def test_preset_values_accepted(name, value, expected):
    got = check_preset_value("p.toml: [t] key", value, option_spec(Demo, name))
    assert got == expected and type(got) is type(expected)


@pytest.mark.parametrize("name, value, message", [
    ("smooth", 1, "must be true or false, got 1"),
    ("kind", 3, "must be a string, got 3"),
    ("kind", "z", "= 'z' is not one of a, b, c"),
    ("sweeps", True, "must be a whole number, got True"),
    ("sweeps", 2.0, "must be a whole number, got 2.0"),
    ("step_size", False, "must be a number, got False"),
    ("step_size", "2", "must be a number, got '2'"),
    ("step_size", math.nan, "must be a finite number, got nan"),
    ("step_size", 0.2, "= 0.2 is out of range (allowed 0.25 to 8.0)"),
    ("sweeps", 21, "= 21 is out of range (allowed 0 to 20)"),
    ("sweeps", -1, "= -1 is out of range (allowed 0 to 20)"),
])
def test_preset_values_refused(name, value, message):
    with pytest.raises(OsmapError) as info:
        check_preset_value("p.toml: [t] key", value, option_spec(Demo, name))
    assert str(info.value) == f"p.toml: [t] key {message}"


@pytest.mark.parametrize("value, text", [(True, "true"), (False, "false"), (3, "3"),
                                         (2.0, "2"), (0.1, "0.1"), (1e20, "1e+20"),
                                         (-4.0, "-4"), (2.5e-7, "2.5e-07"),
                                         (1e15, "1000000000000000.0"),
                                         (999999999999999.0, "999999999999999")])
def test_number_text_reads_back_exactly(value, text):
    assert number_text(value) == text


def test_flag_args_against_a_baseline_or_all():
    changed = Demo(sweeps=5, step_size=2.0, ratio=0.9)
    assert flag_args(changed, Demo()) == ["--sweeps", "5", "--step-size", "2"]
    assert flag_args(Demo(kind="b"), Demo()) == ["--kind", "b"]
    assert flag_args(Demo(), None) == ["--sweeps", "3", "--step-size", "1.5", "--kind", "a"]
    assert flag_args(Demo(), Demo()) == []


def test_preset_toml_holds_every_tunable_with_its_help():
    text = preset_toml(Demo, "demo", "mine", "my preset", {"sweeps": 7, "step_size": 2},
                       header="# MAX\n")
    lines = text.splitlines()
    assert lines[:5] == ["# MAX", 'name = "mine"', 'description = "my preset"', "", "[demo]"]
    assert lines[5].split("#") == ["sweeps = 7".ljust(28), " sweeps per level"]
    assert lines[6].split("#") == ["step_size = 2.0".ljust(28), " step"]
    assert lines[7].split("#") == ['kind = "a"'.ljust(28), " a, b, c"]
    assert text.endswith("\n") and len(lines) == 8
    assert preset_toml(Demo, "demo", "n", "d", {}).startswith('name = "n"\n')
    assert "\nstep_size = 2.5 " in preset_toml(Demo, "demo", "n", "d", {"step_size": 2.5})


def test_preset_toml_columns_follow_the_longest_key():
    text = preset_toml(Wide, "w", "n", "d", {"a_rather_long_tunable_name": 10**20,
                                             "count": 10**20},
                       header="# TOTAL MAX  \n")
    assert text.splitlines() == [
        "# TOTAL MAX  ", 'name = "n"', 'description = "d"', "", "[w]",
        'mode = "a"'.ljust(36) + "# a, b",
        "a_rather_long_tunable_name = 1e+20".ljust(36) + "# long",
        "count = 100000000000000000000".ljust(36) + "# c",
    ]


def test_usage_rows():
    assert usage_rows(Wide) == [
        "| `--mode M` | a | a, b | m |",
        "| `--a-rather-long-tunable-name X` | 1 | 0 to 1e+30 | long |",
        "| `--count N` | 2 | 0 to 1000000000000000000000000000000 | c |",
    ]
    assert usage_rows(Demo) == [
        "| `--sweeps N` | 3 | 0 to 20 | sweeps per level |",
        "| `--step-size X` | 1.5 | 0.25 to 8 | step |",
        "| `--kind M` | a | a, b, c | kind |",
    ]
