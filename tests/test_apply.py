"""Material sets: `osmap synth --with`, and `osmap apply` on a saved position map."""

from __future__ import annotations

import os

import numpy as np
import pytest

from osmap_cli.imageio import read_image, read_metadata, write_image

FAST = ("--size", "40", "--preset", "fast", "--levels", "2", "--quiet")


@pytest.fixture(scope="module")
def material(small_samples, tmp_path_factory):
    """A 64x64 exemplar with aligned maps: roughness (gray, 16-bit) and a normal map made from
    the exemplar's brightness as a height field."""
    folder = tmp_path_factory.mktemp("material")
    colour = read_image(small_samples / "cells.png").pixels
    write_image(folder / "rock.png", colour, 8)
    height = colour.mean(axis=2).astype(np.float64)
    write_image(folder / "rock_rough.png", (1.0 - height)[..., None], 16)
    gy, gx = np.gradient(height * 4.0)
    n = np.stack([-gx, gy, np.ones_like(gx)], -1)  # OpenGL: y up, the rows go down
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    write_image(folder / "rock_normal.png", (n + 1.0) / 2.0, 8)
    write_image(folder / "small.png", colour[:32, :32], 8)
    return folder


def _decode(path) -> np.ndarray:
    return read_image(path).pixels.astype(np.float64) * 2.0 - 1.0


def test_with_maps_are_aligned_and_named_after_the_output(run_cli, material, tmp_path):
    out = tmp_path / "r.png"
    result = run_cli("synth", material / "rock.png", "-o", out, "--with",
                     material / "rock_rough.png", "--with", f"copy={material / 'rock.png'}",
                     "--uv-out", tmp_path / "uv.exr", *FAST, "--orientation", "25")
    assert result.code == 0, result.err
    assert sorted(os.listdir(tmp_path)) == ["r.png", "r_copy.png", "r_rock_rough.png", "uv.exr"]
    # the exemplar itself as a --with map renders exactly the main output: same positions
    assert np.array_equal(read_image(tmp_path / "r_copy.png").pixels, read_image(out).pixels)
    rough = read_image(tmp_path / "r_rock_rough.png")
    assert rough.pixels.shape == (40, 40, 1) and rough.bit_depth == 16  # the map's depth
    assert read_metadata(tmp_path / "r_rock_rough.png")["role"] == "with:rock_rough"
    # osmap apply on the saved positions gives the same map
    applied = tmp_path / "applied.png"
    result = run_cli("apply", tmp_path / "uv.exr", material / "rock_rough.png", "-o", applied)
    assert result.code == 0, result.err
    assert np.array_equal(read_image(applied).pixels, rough.pixels)
    assert read_metadata(applied)["command"] == "apply"


@pytest.mark.parametrize("orientation", [0, 30])
def test_normal_maps_stay_unit_length(run_cli, material, tmp_path, orientation):
    out = tmp_path / "r.png"
    result = run_cli("synth", material / "rock.png", "-o", out, "--with",
                     f"normal={material / 'rock_normal.png'}", *FAST, "--scale", "1.5",
                     "--orientation", str(orientation))
    assert result.code == 0, result.err
    n = _decode(tmp_path / "r_normal.png")
    length = np.linalg.norm(n, axis=-1)
    # 8-bit quantisation: each component is within 1/255 of the unit vector's
    assert np.abs(length - 1.0).max() < 0.01
    assert n[..., 2].min() > 0  # still facing out


def test_normals_turn_with_the_texture(run_cli, small_samples, tmp_path):
    """A constant normal tilted to +x reads tilted to +y after a 90-degree turn (OpenGL)."""
    normal = np.zeros((64, 64, 3), np.float32)
    normal[...] = (np.array([0.6, 0.0, 0.8]) + 1.0) / 2.0
    write_image(tmp_path / "tilt_normal.png", normal, 16)
    result = run_cli("synth", small_samples / "cells.png", "-o", tmp_path / "o.png",
                     "--with", tmp_path / "tilt_normal.png", *FAST, "--orientation", "90")
    assert result.code == 0, result.err
    n = read_image(tmp_path / "o_tilt_normal.png").pixels.astype(np.float64) * 2 - 1
    assert np.allclose(n.reshape(-1, 3).mean(0), [0.0, 0.6, 0.8], atol=0.002)


def test_with_size_mismatch_is_one_clear_error(run_cli, material, tmp_path):
    result = run_cli("synth", material / "rock.png", "-o", tmp_path / "r.png", "--with",
                     material / "small.png", *FAST)
    assert result.code == 1
    assert len(result.err_lines) == 1
    assert "small.png: map is 32x32 but the exemplar" in result.err and "64x64" in result.err
    assert os.listdir(tmp_path) == []


def test_with_template_in_a_batch(run_cli, material, tmp_path):
    result = run_cli("synth", material / "rock.png", "--out-dir", tmp_path, "--with",
                     "rough={dir}/{stem}_rough.png", *FAST)
    assert result.code == 0, result.err
    assert sorted(os.listdir(tmp_path)) == ["rock.png", "rock_rough.png"]


def test_apply_normal_map_and_errors(run_cli, material, tmp_path):
    uv = tmp_path / "uv.exr"
    assert run_cli("synth", material / "rock.png", "-o", tmp_path / "r.png", "--uv-out", uv,
                   *FAST, "--orientation", "40").code == 0
    result = run_cli("apply", uv, material / "rock_normal.png", "-o", tmp_path / "n.png")
    assert result.code == 0, result.err
    n = _decode(tmp_path / "n.png")
    assert np.abs(np.linalg.norm(n, axis=-1) - 1.0).max() < 0.01
    # the same as --with at synthesis time
    assert run_cli("synth", material / "rock.png", "-o", tmp_path / "w.png", "--with",
                   material / "rock_normal.png", *FAST, "--orientation", "40").code == 0
    assert np.array_equal(read_image(tmp_path / "w_rock_normal.png").pixels,
                          read_image(tmp_path / "n.png").pixels)
    # a map not aligned with the exemplar
    result = run_cli("apply", uv, material / "small.png", "-o", tmp_path / "bad.png")
    assert result.code == 1 and len(result.err_lines) == 1
    assert "small.png: map is 32x32" in result.err
    # not a position map
    result = run_cli("apply", material / "rock.png", material / "rock.png", "-o",
                     tmp_path / "bad.png")
    assert result.code == 1 and "not a position map" in result.err
    assert not (tmp_path / "bad.png").exists()


def test_apply_volume_position_map(run_cli, material, tmp_path):
    """A solid's (Z, Y, X, 3) position volume rendered on an aligned map."""
    rng = np.random.default_rng(0)
    uv = np.zeros((4, 5, 6, 3), np.float32)
    uv[..., 0] = rng.integers(0, 64, uv.shape[:3])
    uv[..., 1] = rng.integers(0, 64, uv.shape[:3])
    np.save(tmp_path / "vol_uv.npy", uv)
    result = run_cli("apply", tmp_path / "vol_uv.npy", material / "rock_rough.png", "-o",
                     tmp_path / "vol.npy")
    assert result.code == 0, result.err
    volume = np.load(tmp_path / "vol.npy")
    rough = read_image(material / "rock_rough.png").pixels
    assert volume.shape == (4, 5, 6, 1)
    expected = rough[uv[..., 1].astype(int), uv[..., 0].astype(int)]
    assert np.array_equal(volume, expected)  # the exemplar pixels, copied (no blending)


def test_apply_volume_without_the_solid_renderer_is_one_line(run_cli, material, tmp_path,
                                                             monkeypatch):
    """An osmap whose solid package lacks render_volume refuses a volume position map with one
    line naming it, and writes nothing."""
    from osmap_cli.solid import render

    np.save(tmp_path / "vol_uv.npy", np.zeros((4, 5, 6, 3), np.float32))
    monkeypatch.delattr(render, "render_volume")
    result = run_cli("apply", tmp_path / "vol_uv.npy", material / "rock_rough.png", "-o",
                     tmp_path / "vol.npy")
    assert result.code == 1 and len(result.err_lines) == 1, result.err
    assert "vol_uv.npy: volume position maps need osmap solid's render_volume" in result.err
    assert sorted(os.listdir(tmp_path)) == ["vol_uv.npy"]
