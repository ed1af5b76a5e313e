"""Presets: the shipped TOML files, loading, listing, and every validation error."""

from __future__ import annotations

import subprocess
import sys

import pytest

from osmap_cli import presets
from osmap_cli.errors import OsmapError
from osmap_cli.presets import (
    builtin_names,
    is_preset_path,
    list_presets,
    load_preset,
    preset_text,
    read_preset,
)
from osmap_cli.synth.options import SynthOptions

SHIPPED = ("default", "stochastic", "structured", "directional", "fast")


def _write(tmp_path, text, name="preset.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


# ---------------------------------------------------------------------------------------------
# the shipped presets


def test_default_preset_matches_the_dataclass_defaults():
    """default.toml writes out every tunable with exactly the SynthOptions default."""
    values = load_preset("default")
    defaults = SynthOptions()
    tunables = SynthOptions.tunables()
    assert list(values) == list(tunables)  # every key, in the dataclass order
    for name, value in values.items():
        expected = getattr(defaults, name)
        assert value == expected, name
        assert type(value) is type(expected), name


def test_shipped_presets_are_valid(repo_root):
    assert set(SHIPPED) <= set(builtin_names())
    files = sorted(p.stem for p in (repo_root / "presets").glob("*.toml"))
    assert builtin_names() == ["default"] + [n for n in files if n != "default"]
    tunables = SynthOptions.tunables()
    for name in builtin_names():
        preset = read_preset(name)
        assert preset.name == name
        assert preset.description and "\n" not in preset.description
        assert set(preset.values) <= set(tunables)
        SynthOptions().replace(**preset.values).validated()
        if name != "default":
            assert preset.values, name  # a preset that changes nothing is pointless
            assert preset.values != {k: getattr(SynthOptions(), k) for k in preset.values}


def test_shipped_presets_differ_as_intended():
    assert load_preset("structured")["patch_radius"] > SynthOptions().patch_radius
    assert load_preset("stochastic")["occupancy"] > SynthOptions().occupancy
    assert load_preset("directional")["som_anisotropy"] < SynthOptions().som_anisotropy
    fast = load_preset("fast")
    assert fast["sweeps"] < SynthOptions().sweeps and fast["knn"] < SynthOptions().knn


def test_list_presets():
    listed = list_presets()
    assert listed[0][0] == "default"
    assert [name for name, _ in listed] == builtin_names()
    assert all(isinstance(d, str) and d for _, d in listed)


def test_preset_text(repo_root, tmp_path):
    assert preset_text("fast") == (repo_root / "presets" / "fast.toml").read_text()
    own = _write(tmp_path, "[synth]\nknn = 3\n")
    assert preset_text(str(own)) == "[synth]\nknn = 3\n"


def test_presets_module_is_light():
    code = ("import sys, osmap_cli.presets as p; p.list_presets(); "
            "print([m for m in ('numpy', 'numba', 'OpenImageIO') if m in sys.modules])")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


# ---------------------------------------------------------------------------------------------
# user files


def test_user_file_partial_keys(tmp_path):
    path = _write(tmp_path, 'name = "mine"\ndescription = "d"\n[synth]\nlevels = 2\n'
                            "occupancy = 1\n")
    preset = read_preset(str(path))
    assert preset.name == "mine" and preset.description == "d"
    assert preset.values == {"levels": 2, "occupancy": 1.0}
    assert type(preset.values["occupancy"]) is float  # an integer is fine for a float key


def test_user_file_without_name_or_synth_table(tmp_path):
    path = _write(tmp_path, "# nothing\n", name="empty.toml")
    preset = read_preset(str(path))
    assert preset.name == "empty" and preset.values == {}


def test_names_and_paths(tmp_path):
    assert is_preset_path("mine.toml") and is_preset_path("MINE.TOML")
    assert is_preset_path("folder/mine") and not is_preset_path("structured")
    path = _write(tmp_path, "[synth]\nlevels = 3\n", name="noext")
    assert read_preset(str(path)).values == {"levels": 3}  # a path needs no .toml suffix


# ---------------------------------------------------------------------------------------------
# errors: one line, naming the file and the key


BAD_FILES = [
    # (id, text, strings the message must contain)
    ("malformed", 'name = "x"\n[synth\nlevels = 3\n', ["invalid TOML", "line 2"]),
    ("bad value syntax", "[synth]\nlevels = \n", ["invalid TOML", "line 2"]),
    ("unknown key", "[synth]\nlevelz = 3\n", ["[synth] unknown key 'levelz'", "levels"]),
    ("string for int", '[synth]\nsweeps = "many"\n', ["sweeps", "whole number"]),
    ("float for int", "[synth]\nlevels = 2.5\n", ["levels", "whole number"]),
    ("bool for int", "[synth]\nknn = true\n", ["knn", "whole number"]),
    ("string for float", '[synth]\noccupancy = "high"\n', ["occupancy", "number"]),
    ("bool for float", "[synth]\noccupancy = false\n", ["occupancy", "number"]),
    ("nan", "[synth]\noccupancy = nan\n", ["occupancy", "finite"]),
    ("above range", "[synth]\nlevels = 99\n", ["levels = 99", "out of range", "0 to 8"]),
    ("below range", "[synth]\noccupancy = -1.0\n", ["occupancy = -1.0", "out of range"]),
    ("cross-field", "[synth]\nsom_sigma_min = 5.0\nsom_sigma_max = 1.0\n", ["som_sigma_min"]),
    ("unknown top-level key", "levels = 3\n", ["unknown top-level key 'levels'"]),
    ("name not a string", "name = 3\n", ["name must be a string"]),
    ("synth not a table", "synth = 3\n", ["synth must be a table"]),
    ("array for int", "[synth]\nlevels = [1, 2]\n", ["levels"]),
]


@pytest.mark.parametrize("case", BAD_FILES, ids=[c[0] for c in BAD_FILES])
def test_bad_preset_file(tmp_path, case):
    _, text, needles = case
    path = _write(tmp_path, text, name="bad_preset.toml")
    with pytest.raises(OsmapError) as info:
        load_preset(str(path))
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(str(path) + ": ")
    for needle in needles:
        assert needle in message, (needle, message)


def test_not_utf8(tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes('name = "caf\xe9"\n'.encode("latin-1"))
    with pytest.raises(OsmapError, match="latin1.toml: not a UTF-8"):
        load_preset(str(path))


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(OsmapError, match="nope.toml: no such preset file"):
        load_preset(str(tmp_path / "nope.toml"))
    folder = tmp_path / "dir.toml"
    folder.mkdir()
    with pytest.raises(OsmapError, match="dir.toml: is a directory"):
        load_preset(str(folder))


def test_unknown_builtin_name():
    with pytest.raises(OsmapError) as info:
        load_preset("nope")
    message = str(info.value)
    assert "--preset" in message and "'nope'" in message
    for name in SHIPPED:
        assert name in message


def test_builtin_errors_name_the_builtin_file(monkeypatch):
    monkeypatch.setattr(presets, "_read_source",
                        lambda name: ("[synth]\nlevels = 99\n", "fast.toml (built-in preset)"))
    with pytest.raises(OsmapError, match=r"^fast.toml \(built-in preset\): \[synth\] levels"):
        load_preset("fast")
