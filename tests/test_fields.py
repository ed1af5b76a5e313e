"""Control fields: the output's local structure follows --orientation-field and
--scale-field.

Measured on a stripes exemplar (vertical sinusoidal stripes, period 8 px, light noise):
- direction: the structure-tensor orientation of each half of the output is within
  ANGLE_TOLERANCE degrees of the field's angle there;
- scale: the dominant stripe period of each half (FFT along the rows) is within
  PERIOD_TOLERANCE of 8 px times the field's scale there.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from osmap_cli.fields import jacobians
from osmap_cli.imageio import read_image, write_image
from osmap_cli.synth.options import SynthOptions

ANGLE_TOLERANCE = 12.0  # degrees
PERIOD_TOLERANCE = 0.3  # relative
PERIOD = 8
H, W = 64, 160
MARGIN = 6  # pixels next to the boundary between the halves are not measured


def stripes(size: int = 48) -> np.ndarray:
    x = np.arange(size)
    row = 0.5 + 0.4 * np.sin(2 * np.pi * x / PERIOD)
    image = np.tile(row[None, :], (size, 1))
    image += 0.05 * np.random.default_rng(0).standard_normal(image.shape)
    return np.clip(image, 0, 1).astype(np.float32)[..., None]


def gradient_angle(image: np.ndarray) -> float:
    """Dominant gradient direction, degrees counter-clockwise on screen, in [-90, 90)."""
    gy, gx = np.gradient(image[..., 0].astype(np.float64))
    jxx, jyy, jxy = (gx * gx).mean(), (gy * gy).mean(), (gx * gy).mean()
    return -0.5 * math.degrees(math.atan2(2 * jxy, jxx - jyy))


def stripe_period(image: np.ndarray) -> float:
    """Dominant period along the rows, pixels (peak of the mean row power spectrum)."""
    g = image[..., 0].astype(np.float64)
    g = g - g.mean(axis=1, keepdims=True)
    power = (np.abs(np.fft.rfft(g * np.hanning(g.shape[1]), axis=1)) ** 2).mean(0)
    power[0] = 0
    return g.shape[1] / int(np.argmax(power))


def _angle_error(a: float, b: float) -> float:
    return abs((a - b + 90.0) % 180.0 - 90.0)


@pytest.fixture(scope="module")
def exemplar(tmp_path_factory):
    path = tmp_path_factory.mktemp("stripes") / "stripes.png"
    write_image(path, stripes(), 8)
    return path


def _halves(value_left, value_right, channels=1):
    field = np.zeros((H, W, channels), np.float32)
    field[:, : W // 2] = value_left
    field[:, W // 2:] = value_right
    return field


def _synth(run_cli, exemplar, out, *args):
    result = run_cli("synth", exemplar, "-o", out, "--size", f"{W}x{H}", "--seed", "1",
                     "--quiet", *args)
    assert result.code == 0, result.err
    pixels = read_image(out).pixels
    return pixels[:, MARGIN: W // 2 - MARGIN], pixels[:, W // 2 + MARGIN: -MARGIN]


@pytest.mark.parametrize("encoding", ["gray8", "vector", "exr-degrees"])
def test_structure_follows_the_orientation_field(run_cli, exemplar, tmp_path, encoding):
    left_deg, right_deg = 0.0, 60.0
    if encoding == "gray8":
        path = tmp_path / "field.png"
        write_image(path, _halves(left_deg / 360, right_deg / 360), 16)
    elif encoding == "vector":  # R = x right, G = y up, 0.5 = zero
        path = tmp_path / "field.png"
        vec = [(math.cos(math.radians(d)), math.sin(math.radians(d)), 0.0)
               for d in (left_deg, right_deg)]
        write_image(path, _halves(*[(np.array(v) + 1) / 2 for v in vec], channels=3), 16)
    else:
        path = tmp_path / "field.exr"
        write_image(path, _halves(left_deg, right_deg), 32)
    left, right = _synth(run_cli, exemplar, tmp_path / "out.png", "--orientation-field", path)
    # the exemplar's gradient points along x (0 degrees); the texture turns by the field
    assert _angle_error(gradient_angle(left), left_deg) < ANGLE_TOLERANCE
    assert _angle_error(gradient_angle(right), right_deg) < ANGLE_TOLERANCE


def test_orientation_field_adds_to_orientation(run_cli, exemplar, tmp_path):
    path = tmp_path / "field.png"
    write_image(path, _halves(0.0, 0.25), 8)  # 0 and 90 degrees
    left, right = _synth(run_cli, exemplar, tmp_path / "out.png", "--orientation-field", path,
                         "--orientation", "-45")
    assert _angle_error(gradient_angle(left), -45) < ANGLE_TOLERANCE
    assert _angle_error(gradient_angle(right), 45) < ANGLE_TOLERANCE


def test_feature_size_follows_the_scale_field(run_cli, exemplar, tmp_path):
    path = tmp_path / "scale.png"
    write_image(path, _halves(0.0, 1.0), 8)  # 8-bit: 0 -> scale 0.5, 1 -> scale 2
    left, right = _synth(run_cli, exemplar, tmp_path / "out.png", "--scale-field", path)
    assert abs(stripe_period(left) / (PERIOD * 0.5) - 1) < PERIOD_TOLERANCE
    assert abs(stripe_period(right) / (PERIOD * 2.0) - 1) < PERIOD_TOLERANCE


def test_float_scale_field_and_range_check(run_cli, exemplar, tmp_path):
    path = tmp_path / "scale.exr"
    write_image(path, _halves(1.0, 1.5), 32)
    left, right = _synth(run_cli, exemplar, tmp_path / "out.png", "--scale-field", path)
    assert abs(stripe_period(left) / PERIOD - 1) < PERIOD_TOLERANCE
    assert abs(stripe_period(right) / (PERIOD * 1.5) - 1) < PERIOD_TOLERANCE
    write_image(path, _halves(1.0, 20.0), 32)
    result = run_cli("synth", exemplar, "-o", tmp_path / "bad.png", "--scale-field", path)
    assert result.code == 1 and len(result.err_lines) == 1
    assert "scale.exr: scale field times --scale gives 1 to 20" in result.err
    assert not (tmp_path / "bad.png").exists()


def test_fields_need_the_osmap_method(run_cli, exemplar, tmp_path):
    result = run_cli("synth", exemplar, "-o", tmp_path / "x.png", "--method", "paper",
                     "--orientation-field", exemplar)
    assert result.code == 2 and "--method osmap" in result.err


def test_bad_field_file_is_one_line(run_cli, exemplar, tmp_path):
    (tmp_path / "f.png").write_text("nope")
    result = run_cli("synth", exemplar, "-o", tmp_path / "x.png", "--orientation-field",
                     tmp_path / "f.png")
    assert result.code == 1 and len(result.err_lines) == 1 and "f.png" in result.err


@pytest.mark.parametrize("degrees, scale, anisotropy", [(30, 2, 1.5), (-70, 0.5, 0.7), (0, 1, 1)])
def test_jacobian_field_matches_the_global_options(degrees, scale, anisotropy):
    expected = SynthOptions(orientation=degrees, scale=scale, anisotropy=anisotropy).jacobian()
    theta = math.radians(degrees)
    assert np.allclose(jacobians(math.cos(theta), math.sin(theta), scale, anisotropy),
                       expected, atol=1e-6)
