"""The first-run compile: detected from Numba's cache, announced once, silent with --quiet."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from osmap_cli.synth import warm


def test_an_empty_cache_is_cold_and_the_repository_cache_is_warm(tmp_path):
    code = "from osmap_cli.synth.warm import cold_groups; print(cold_groups())"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "['organise', 'refine']"
    assert warm.cold_groups() == []  # the session fixture compiled them


@pytest.fixture
def cold(monkeypatch):
    """Pretend the cache is cold once; record what would be compiled."""
    compiled = []
    state = {"cold": True}
    monkeypatch.setattr(warm, "cold_groups", lambda: ["organise", "refine"] if state["cold"]
                        else [])

    def fake_compile(groups, workers):
        compiled.append(groups)
        state["cold"] = False

    monkeypatch.setattr(warm, "_compile", fake_compile)
    return compiled


def test_a_cold_run_announces_the_compile_once(cold, run_cli, small_samples, tmp_path):
    args = ("--size", "32", "--preset", "fast")
    first = run_cli("synth", small_samples / "cells.png", "-o", tmp_path / "a.png", *args)
    assert first.code == 0, first.err
    assert cold == [["organise", "refine"]]
    assert first.err_lines[0].startswith("osmap: compiling kernels, first run only (about ")
    second = run_cli("synth", small_samples / "cells.png", "-o", tmp_path / "b.png", *args)
    assert second.code == 0 and "compiling" not in second.err
    assert cold == [["organise", "refine"]]


def test_quiet_compiles_without_a_word(cold, run_cli, small_samples, tmp_path):
    result = run_cli("synth", small_samples / "cells.png", "-o", tmp_path / "a.png",
                     "--size", "32", "--preset", "fast", "--quiet")
    assert result.code == 0 and result.err == ""
    assert cold == [["organise", "refine"]]


def test_json_keeps_stdout_for_records(cold, run_cli, small_samples, tmp_path):
    result = run_cli("synth", small_samples / "cells.png", "-o", tmp_path / "a.png",
                     "--size", "32", "--preset", "fast", "--json")
    assert result.code == 0
    assert "compiling" not in result.out and "compiling kernels" in result.err


def test_a_refused_size_neither_compiles_nor_announces(cold, run_cli, monkeypatch,
                                                       small_samples, tmp_path):
    monkeypatch.setenv("OSMAP_MEMORY_LIMIT", "300M")
    result = run_cli("synth", small_samples / "cells.png", "-o", tmp_path / "big.png",
                     "--size", "4096")
    assert result.code == 1 and "needs about" in result.err
    assert "compiling" not in result.err and cold == []


def test_warmup_command(cold, run_cli):
    first = run_cli("warmup")
    assert first.code == 0 and "compiling kernels" in first.err
    assert first.out.strip() == "osmap: kernels compiled" and cold == [["organise", "refine"]]
    again = run_cli("warmup")
    assert again.code == 0 and again.out.strip() == "osmap: kernels already compiled"
    assert run_cli("warmup", "--quiet").out == ""
