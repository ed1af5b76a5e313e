"""The metadata every output carries (osmap_cli.provenance): its keys and values as `osmap info`
reads them. The round trips through real runs are in test_info.py and test_option_roundtrip.py;
these check the records themselves, in milliseconds."""

from __future__ import annotations

import json
import shlex

from osmap_cli import __version__
from osmap_cli.provenance import header, image_metadata, volume_metadata
from osmap_cli.solid.options import SolidOptions

# an option set in an order that is not sorted, as a recorded one may come
OPTIONS = {"seed": 7, "levels": 2, "anisotropy": 1.5}


def test_header_names_the_software_its_version_and_the_command():
    assert header("apply") == {"software": f"osmap {__version__}",
                               "osmap_version": __version__, "command": "apply"}


def test_image_metadata_records_the_run():
    meta = image_metadata(OPTIONS, "mine.toml", "in/dir/cells.png", (40, 64, 3),
                          ["--size", "32x24", "--seed", "7", "--name", "a b"])
    assert list(meta)[:3] == ["software", "osmap_version", "command"]
    assert meta["command"] == "synth" and meta["role"] == "image"  # the defaults
    assert meta["exemplar"] == "cells.png"  # a name, no folder
    assert meta["exemplar_size"] == "64x40"  # width x height
    assert meta["preset"] == "mine.toml" and meta["seed"] == "7"
    assert meta["options"] == '{"anisotropy": 1.5, "levels": 2, "seed": 7}'  # canonical
    assert shlex.split(meta["args"])[-2:] == ["--name", "a b"]  # quoted for a shell
    assert "source" not in meta


def test_image_metadata_of_other_roles_and_commands():
    meta = image_metadata(OPTIONS, "fast", "cells.png", (8, 8, 3), [], role="with:rough",
                          extra={"source": "rough.png", "role": "overridden"},
                          command="tileable")
    assert meta["command"] == "tileable" and meta["software"] == f"osmap {__version__}"
    assert meta["source"] == "rough.png" and meta["role"] == "overridden"  # extra comes last


def test_volume_metadata_of_one_exemplar():
    options = SolidOptions(seed=4)
    meta = volume_metadata(options, "soft.toml", ["a/marble.png"], ["--seed", "4"])
    assert meta["command"] == "solid" and meta["osmap_version"] == __version__
    assert meta["exemplar"] == "marble.png" and "inputs" not in meta
    assert meta["preset"] == "soft.toml" and meta["seed"] == "4"
    assert meta["args"] == "--seed 4"
    recorded = json.loads(meta["options"])
    assert recorded["seed"] == 4 and list(recorded) == sorted(recorded)


def test_volume_metadata_of_three_slice_families():
    """--x, --y and --z name their files; the exemplar field lists them (once when they are
    one file)."""
    options = SolidOptions()
    meta = volume_metadata(options, "default", ["d/x.png", "d/y.png", "z.png"], [])
    assert meta["exemplar"] == "x.png,y.png,z.png"
    assert meta["inputs"] == "--x x.png --y y.png --z z.png"
    same = volume_metadata(options, "default", ["x.png", "d/x.png", "x.png"], [])
    assert same["exemplar"] == "x.png" and same["inputs"] == "--x x.png --y x.png --z x.png"
