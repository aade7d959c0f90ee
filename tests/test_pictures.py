"""The 3-D pictures (issue 29 item 2): the colour field chosen from the scene, the
deformation magnification, the picture's size."""

from __future__ import annotations

import numpy as np
import pytest

from dolfin_rod.output.animation import (Look, animation_name, colour_field, colour_scale,
                                         colour_values, cylinder_wire, magnification,
                                         plane_patch,
                                         rod_animation, rod_snapshots, support_nodes)
from dolfin_rod.output.closing import FILES
from dolfin_rod.output.line_fields import LineSample

N = 4   # cells of the synthetic rod: s in [0, 1] along e_3


def frame(t, tip=0.0, stretch=0.0, curvature=0.0):
    """A straight rod bent by tip * s^2 along x, with v_d_3 = 1 + stretch t and
    u_d_1 = curvature t on every cell."""
    s = np.linspace(0.0, 1.0, N + 1)
    centre = np.column_stack([tip * s**2, 0 * s, s])
    ones = np.ones((N, 3))
    cell = {"u": 0 * ones, "v": ones * [0, 0, 1], "u_d": ones * [curvature * t, 0, 0],
            "v_d": ones * [0, 0, 1 + stretch * t], "n": ones, "m": 2 * ones,
            "xi": np.full(N, 3.0)}
    return t, LineSample(s, 0.5 * (s[1:] + s[:-1]), {"centre_line": centre}, cell)


def test_colour_is_the_evolving_strain_that_changes_most():
    """Overstretching: v_d goes 1 -> 1.7 while u_d stays (dna_overstretching showed the
    round-off of |u_d - u_ref| before); creep in bending: u_d changes by 2 / L, v_d by
    0.1 (curvatures compare times L); nothing evolves: the strain that changes."""
    stretch = [frame(t, stretch=0.7) for t in (0.0, 1.0)]
    assert colour_field(stretch) == "v_d"
    np.testing.assert_allclose(colour_values(stretch[1][1], stretch[0][1], "v_d"), 0.7)
    bend = [frame(t, stretch=0.1, curvature=2.0) for t in (0.0, 1.0)]
    assert colour_field(bend) == "u_d"
    assert colour_field(bend, "m") == "m"
    np.testing.assert_allclose(colour_values(bend[1][1], bend[0][1], "m"), 2 * np.sqrt(3))
    still = [frame(0.0), frame(1.0)]
    still[1][1].cell["v"] = still[1][1].cell["v"] * 1.01
    assert colour_field(still) == "v"


@pytest.mark.parametrize("tip, factor", [(1e-3, 200.0), (3e-3, 50.0), (0.02, 10.0),
                                         (0.1, 1.0)])
def test_magnification_brings_small_motion_to_a_fifth_of_the_rod(tip, factor):
    """Size 1 (the arc length), motion = tip: below 5 % the factor is the largest 1-2-5
    number <= 0.2 / tip (200, 66.7 -> 50, 10); 10 % is shown as it is."""
    assert magnification([frame(0.0), frame(1.0, tip=tip)]) == factor


def test_animation_is_wide_and_marks_the_motion(tmp_path):
    from PIL import Image
    frames = [frame(t, tip=1e-3 * t, curvature=1.0) for t in np.linspace(0, 1, 5)]
    rod_animation(frames, tmp_path / "a.gif", "test",
                  Look("auto", {"start": "clamped", "end": "free"}, (-9.81, 0.0, 0.0)))
    gif = Image.open(tmp_path / "a.gif")
    assert gif.n_frames == 5 and gif.size[0] >= 800
    gif.seek(4)
    last = np.asarray(gif.convert("RGB"))
    gif.seek(0)
    assert np.any(last != np.asarray(gif.convert("RGB")))     # the rod moved on screen


def test_the_animation_is_an_mp4_where_ffmpeg_exists_and_a_gif_otherwise(tmp_path,
                                                                           monkeypatch):
    """The choice follows the PATH, as matplotlib's FFMpegWriter would: with an executable
    named ffmpeg on it, animation.mp4; without, animation.gif, written as a GIF (Pillow
    reads its 5 frames) and named so with the reason on the terminal (closing.FILES).
    The MP4 itself cannot be written here (no ffmpeg in this environment)."""
    from PIL import Image
    with_ffmpeg, without = tmp_path / "with", tmp_path / "without"
    with_ffmpeg.mkdir(), without.mkdir()
    (with_ffmpeg / "ffmpeg").write_text("#!/bin/sh\nexit 0\n")
    (with_ffmpeg / "ffmpeg").chmod(0o755)
    monkeypatch.setenv("PATH", str(with_ffmpeg))
    assert animation_name() == "animation.mp4" and "MP4" in FILES["animation.mp4"]
    monkeypatch.setenv("PATH", str(without))
    name = animation_name()
    assert name == "animation.gif" and "no ffmpeg" in FILES[name]
    frames = [frame(t, tip=0.1 * t) for t in np.linspace(0, 1, 5)]
    rod_animation(frames, tmp_path / name, "test")
    gif = Image.open(tmp_path / name)
    assert gif.format == "GIF" and gif.n_frames == 5


def test_a_signed_field_gets_a_colour_scale_symmetric_about_zero():
    """xi of the uniform variant is negative in places: -1 .. 3 is drawn on -3 .. 3 of a
    diverging map (white at 0); a field of one sign keeps 0 .. max on viridis."""
    name, norm = colour_scale([np.array([-1.0, 0.5]), np.array([3.0])])
    assert name == "coolwarm" and (norm.vmin, norm.vmax) == (-3.0, 3.0)
    name, norm = colour_scale([np.array([0.25, 2.0])])
    assert name == "viridis" and (norm.vmin, norm.vmax) == (0.0, 2.0)
    # a rod sliding rigidly (rod_on_incline): strain changes of 1.8e-11 are round-off
    name, norm = colour_scale([np.array([0.0, 1.8e-11])])
    assert (norm.vmin, norm.vmax) == (0.0, 1.0)


def test_supports_of_each_rod_of_a_system_are_found():
    """Two rods on one mesh (nodes 0-4 and 5-9, a gap in s between them): the first
    clamped at its start, the second pinned at its end -> nodes 0 and 9."""
    s = np.concatenate([np.linspace(0, 1, 5), np.linspace(2, 3, 5)])
    cells = np.array([[i, i + 1] for i in range(4)] + [[i, i + 1] for i in range(5, 9)])
    sample = LineSample(s, 0.5 * (s[cells[:, 0]] + s[cells[:, 1]]), {}, {}, cells)
    look = Look("auto", ({"start": "clamped", "end": "free"}, {"start": "free", "end": "pinned"}))
    assert support_nodes(sample, look) == [(0, "clamped"), (9, "pinned")]
    assert support_nodes(sample, Look("auto", {"start": "clamped"})) == []   # 1 for 2 rods


@pytest.mark.parametrize("gravity", [None, (-9.81, 0.0, 0.0)])
def test_snapshots_draw_the_gravity_arrow(tmp_path, gravity):
    """snapshots.png has the red 'g' arrow (RGB 199, 31, 31) exactly when the scene has
    gravity; nothing else in the picture is that red."""
    from PIL import Image
    frames = [frame(t, tip=0.3 * t, curvature=1.0) for t in np.linspace(0, 1, 4)]
    rod_snapshots(frames, tmp_path / "s.png", "test", look=Look("auto", {}, gravity))
    rgb = np.asarray(Image.open(tmp_path / "s.png").convert("RGB")).astype(int)
    red = np.sum(np.all(np.abs(rgb - [199, 31, 31]) <= 12, axis=-1))
    assert (red > 20) == (gravity is not None), red


def test_a_plane_obstacle_is_drawn_in_its_plane(tmp_path):
    """rope_on_floor's floor (point (-0.02, 0, 1), normal (0.98, 0, -0.19)) in the box
    [-1, 1]^3: the square's corners lie in the plane (1e-15), its centre is the foot of
    the box's centre on it, its sides are the box's width 2."""
    point, normal = np.array([-0.02, 0.0, 1.0]), np.array([0.98, 0.0, -0.19])
    corners = plane_patch((-np.ones(3), np.ones(3)), point, normal)
    n = normal / np.linalg.norm(normal)
    np.testing.assert_allclose((corners - point) @ n, 0.0, atol=1e-15)
    np.testing.assert_allclose(corners.mean(axis=(0, 1)), -np.dot(-point, n) * n, atol=1e-15)
    assert np.linalg.norm(corners[0, 1] - corners[0, 0]) == pytest.approx(2.0, rel=1e-15)
    assert np.linalg.norm(corners[1, 0] - corners[0, 0]) == pytest.approx(2.0, rel=1e-15)
    frames = [frame(t, tip=0.3 * t) for t in np.linspace(0, 1, 3)]
    look = Look("auto", {}, None, ({"shape": "plane", "point": point, "normal": normal},
                                   {"shape": "sphere", "centre": (0.5, 0, 0.5), "radius": 0.2},
                                   {"shape": "cylinder", "centre": (0, 0, 0.5), "radius": 0.01,
                                    "axis": (0, 1, 0), "length": 0.5}))
    rod_snapshots(frames, tmp_path / "s.png", look=look)      # plane, sphere, cylinder
    assert (tmp_path / "s.png").stat().st_size > 10_000
    # the cylinder's wire: on its surface (radius 0.01 about the axis e_2), lid to lid
    wire = cylinder_wire(look.obstacles[2]) - (0, 0, 0.5)
    np.testing.assert_allclose(np.linalg.norm(wire[..., [0, 2]], axis=-1), 0.01, rtol=1e-14)
    assert wire[..., 1].min() == pytest.approx(-0.25) and wire[..., 1].max() == pytest.approx(0.25)
