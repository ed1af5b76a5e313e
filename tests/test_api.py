"""The public Python API: the names `osmap_cli` exports, and their docstring examples run."""

from __future__ import annotations

import doctest
import importlib
import subprocess
import sys

import pytest

import osmap_cli

# modules whose docstring examples are complete programs (the others sketch a call)
EXECUTED = ("osmap_cli", "osmap_cli.options", "osmap_cli.synth.options",
            "osmap_cli.solid.options", "osmap_cli.presets")


@pytest.mark.parametrize("name", EXECUTED)
def test_docstring_examples_run(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0, f"{name} has no examples"
    assert result.failed == 0


def test_every_exported_name_resolves_and_is_documented():
    for name in osmap_cli.__all__:
        value = getattr(osmap_cli, name)
        assert value.__doc__, name
        assert f"osmap.{name}" in osmap_cli.__doc__ or name in ("SynthResult", "SolidResult",
                                                                "render_volume", "Schedule",
                                                                "Orientation", "OsmapError"), name
    with pytest.raises(AttributeError):
        osmap_cli.no_such_name  # noqa: B018


def test_import_is_cheap():
    code = ("import sys, osmap_cli; print([m for m in ('numpy', 'numba', 'OpenImageIO') "
            "if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "[]"
