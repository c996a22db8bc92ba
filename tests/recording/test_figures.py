"""PNG figures: written, right pixel size, deterministic."""

from __future__ import annotations

import math

import matplotlib.image as mpimg
import numpy as np
import pytest

from jointctl.recording.figures import DPI, FIGSIZE_IN, plot_command_and_position, plot_series

PIXELS = (round(FIGSIZE_IN[1] * DPI), round(FIGSIZE_IN[0] * DPI))  # (rows, cols)


@pytest.fixture
def trace():
    t = np.arange(3000) * 1e-3
    command = np.where(t < 0.5, -0.2, -0.5)
    position = -0.5 + 0.3 * np.exp(-5 * np.clip(t - 0.5, 0, None)) * np.cos(
        19 * np.clip(t - 0.5, 0, None)
    )
    position[t < 0.5] = -0.2
    return t, command, position


def test_pixel_size_is_880_by_495():
    assert PIXELS == (495, 880)


def test_command_and_position_png(tmp_path, trace):
    t, command, position = trace
    out = tmp_path / "sub" / "step.png"
    returned = plot_command_and_position(out, t, command, position, title="Step, Kp = 400")
    assert returned == out
    assert out.stat().st_size > 1000
    image = mpimg.imread(out)
    assert image.shape[:2] == PIXELS
    assert np.ptp(image[..., :3]) > 0.5  # something was drawn


def test_zoom_changes_the_picture(tmp_path, trace):
    t, command, position = trace
    full = plot_command_and_position(tmp_path / "full.png", t, command, position, title="s")
    zoom = plot_command_and_position(
        tmp_path / "zoom.png", t, command, position, title="s", zoom=(0.45, 0.8),
        ylabel="position [rad]", command_label="ref", position_label="joint1",
    )
    assert mpimg.imread(zoom).shape[:2] == PIXELS
    assert full.read_bytes() != zoom.read_bytes()
    with pytest.raises(ValueError, match="zoom"):
        plot_command_and_position(tmp_path / "bad.png", t, command, position, title="s",
                                  zoom=(1.0, 0.5))


def test_plot_series_png(tmp_path):
    t = np.arange(2000) * 1e-3
    series = {
        "effort (Kp=100)": 5 * np.sin(2 * math.pi * t),
        "effort (Kp=400)": 8 * np.sin(2 * math.pi * t + 0.3),
        "gravity": np.full_like(t, 9.81),
    }
    out = plot_series(str(tmp_path / "effort.png"), t, series, title="Effort",
                      ylabel="effort [N]", zoom=(0.2, 0.6))
    assert out.stat().st_size > 1000
    assert mpimg.imread(out).shape[:2] == PIXELS


def test_figures_are_deterministic(tmp_path, trace):
    t, command, position = trace
    a = plot_command_and_position(tmp_path / "a.png", t, command, position, title="same")
    b = plot_command_and_position(tmp_path / "b.png", t, command, position, title="same")
    assert a.read_bytes() == b.read_bytes()
    assert b"matplotlib" not in a.read_bytes()  # no version stamp in the metadata


def test_bad_input(tmp_path, trace):
    t, command, position = trace
    with pytest.raises(ValueError, match="shape"):
        plot_series(tmp_path / "x.png", t, {"v": position[:-1]}, title="v", ylabel="v [m/s]")
    with pytest.raises(ValueError, match="no series"):
        plot_series(tmp_path / "x.png", t, {}, title="v", ylabel="v [m/s]")
    with pytest.raises(ValueError, match="differ"):
        plot_command_and_position(tmp_path / "x.png", t, command, position, title="s",
                                  command_label="x", position_label="x")
    assert not (tmp_path / "x.png").exists()
    plot_series(tmp_path / "x.png", t, {"v": position}, title="v", ylabel="v [m/s]")
    assert (tmp_path / "x.png").exists()  # where the refused calls would have written, a good one does
