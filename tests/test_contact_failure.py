"""A contact solve that finally fails, as a user runs it (issue 26): ``dolfin-rod run``
ends with exit 3, keeps the rows computed so far, and its error names the segment pair
(rods, arc lengths s on each rod) and where in space (step_control.step_failure,
SegmentContact.nearest_pair)."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import pytest

from test_cli import cli

CROSSING = Path(__file__).resolve().parents[1] / "scenes" / "crossing_rods.toml"
# scenes/crossing_rods.toml: the beam (8 cells) rests at its node s = 0.75 on the prop
# (4 cells) at the prop's node s = 0.25: the pair of segments around them
PAIR = re.compile(r"segments of rod beam at s = 0\.\d+ and rod prop at s = 0\.\d+, near "
                  r"\(0\.75\d*, [-0-9.e]+, [-0-9.e]+\)")


def _run(tmp_path, changes: dict[str, str]):
    text = CROSSING.read_text().replace("dt = 0.25", "dt = 0.125\nmax_step_cuts = 2")
    for old, new in changes.items():
        assert old in text
        text = text.replace(old, new, 1)
    scene = tmp_path / "scene.toml"
    scene.write_text(text)
    proc = cli("run", scene, "--out", tmp_path / "run")
    with open(tmp_path / "run" / "timeseries.csv") as f:
        rows = list(csv.DictReader(f))
    return proc, rows


def test_a_barrier_overcome_names_the_pair_and_keeps_the_rows(tmp_path):
    """contact.stiffness = 10: the barrier's force below its exact range (1e-4 delta) is
    bounded, ~0.6 kappa = 6 N per pair, and the prop must take more as the tip load
    grows: at t = 0.34 s every cut still overlaps.  Exit 3; the rows at t = 0, 0.125,
    0.25 kept; the error names the pair, the point (x = 0.75) and the reason."""
    proc, rows = _run(tmp_path, {"gap = 0.0005 ": "stiffness = 10.0\ngap = 0.0005 "})
    assert proc.returncode == 3, proc.stdout + proc.stderr
    assert [float(r["time"]) for r in rows] == pytest.approx([0.0, 0.125, 0.25])
    message = proc.stdout + proc.stderr
    assert "time step failed at t = 0.34375" in message
    assert PAIR.search(message) and "the barrier was overcome" in message


def test_a_newton_failure_in_contact_names_the_pair(tmp_path):
    """Newton limited to 4 iterations (solver.options), which a contact step needs more
    than: the final IntegrationError adds where it failed, the pair nearest to touching
    at Newton's last iterate (rods, s, point, gap), exit 3, the first row kept."""
    proc, rows = _run(tmp_path, {"gap = 0.0005 ": "stiffness = 1e4\ngap = 0.0005 ",
                                 "[time]": "[solver]\noptions = { snes_max_it = 4 }\n[time]"})
    assert proc.returncode == 3, proc.stdout + proc.stderr
    assert len(rows) == 1
    message = proc.stdout + proc.stderr
    assert "DIVERGED_MAX_IT" in message and "; where: " in message
    assert PAIR.search(message) and "at Newton's last iterate" in message


DRAGGED = """
[scene]
units = "SI"
[geometry]
length = 0.5
n_cells = 12
[section]
shape = "circle"
radius = 0.005
[material]
model = "hyperelastic"
youngs_modulus = 1e8
poisson_ratio = 0.4
density = 1150.0
[boundary]
start = "pinned"
end = "free"
start_displacement = { type = "ramp", value = [-0.05, 0.0, 0.0], t0 = 0.02, duration = 0.5 }
[initial]
position = [0.0, 0.0, 0.00525]
orientation = [0.0, 1.5707963267948966, 0.0]
[loads]
gravity = [0.0, 0.0, -9.81]
[[obstacles]]
shape = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
friction = 0.4
[solver]
options = { snes_max_it = 1 }
[time]
t_end = 0.03
dt = 0.005
max_step_cuts = 1
"""


def test_a_newton_failure_on_an_obstacle_names_it_and_the_friction_knobs(tmp_path):
    """A rod lying on a floor with friction, dragged by its start (as a user writes it;
    docs/contact.md), here Newton limited to one iteration, with the fallback line
    search too, so that the first step fails:
    exit 3, and the error names the floor, the gap at the last state (the rod starts
    at z = r + delta / 2: gap 0.00025 m, delta = r / 10 = 0.0005) and the knobs that
    let a stick-slip transition through, with the slip tolerance in use (the default
    1e-3 L / t_end = 1e-3 x 0.5 / 0.03 = 0.0167 m/s)."""
    scene = tmp_path / "dragged.toml"
    scene.write_text(DRAGGED)
    proc = cli("run", scene, "--out", tmp_path / "run")
    assert proc.returncode == 3, proc.stdout + proc.stderr
    message = proc.stdout + proc.stderr
    assert "DIVERGED_MAX_IT" in message
    assert re.search(r"; where: obstacles\[0\] nearest the centre line at s = [0-9.]+, "
                     r"gap 0\.00025 \(the barrier acts below 0\.0005\); with friction "
                     r"mu = 0\.4 ", message), message
    assert "contact.slip_tolerance (now 0.0167), a smaller time.dt" in message



def test_a_rod_dragged_from_rest_slides_at_coulombs_force(tmp_path):
    """The dragged rod above with the default Newton, pulled 5 cm over 0.5 s (it stalled
    at the ramp's kink with the backtracking line search alone: steps of 1e-4 of
    Newton's; the l2 line search, tried where it fails, passes): the run completes on 1
    and 2 ranks, the start ends 5 cm back, and while the rod slides steadily at 0.1 m/s
    (far above the slip tolerance, where the smoothed law is Coulomb's: phi(v / eps) = 1
    beyond eps) the pull equals mu times the floor's normal force.  From t = 0.3 s: the
    kink's transient (the rod's vibration and its acceleration, excited by the velocity
    jump) has decayed to 5e-8 of the pull by then (measured; 2e-3 at 0.1 s), the rest is
    Newton's rtol 1e-8: rel 1e-6."""
    scene = tmp_path / "dragged.toml"
    scene.write_text(DRAGGED.replace("options = { snes_max_it = 1 }\n", "")
                     .replace("t_end = 0.03", "t_end = 0.6").replace("max_step_cuts = 1", ""))
    runs = []
    for ranks in (0, 2):
        out = tmp_path / f"run{ranks}"
        proc = cli("run", scene, "--out", out, "--quiet", mpi=ranks)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        with open(out / "timeseries.csv") as f:
            runs.append([{k: float(v) for k, v in row.items() if v} for row in csv.DictReader(f)])
    for rows in runs:
        sliding = [r for r in rows if 0.3 <= r["time"] <= 0.5]
        for r in sliding:
            assert r["reaction_force_start_x"] == pytest.approx(
                -0.4 * r["contact_force_z"], rel=1e-6, abs=0.0)
        assert rows[-1]["tip_position_x"] == pytest.approx(0.45, abs=1e-5)   # 0.5 - 0.05
    assert runs[1][-1]["reaction_force_start_x"] == pytest.approx(
        runs[0][-1]["reaction_force_start_x"], rel=1e-6)

PRESSED = """
[scene]
units = "SI"
[geometry]
length = 0.1
n_cells = 20
[section]
shape = "circle"
radius = 0.001
[material]
model = "hyperelastic"
youngs_modulus = 2e11
poisson_ratio = 0.3
[boundary]
start = "clamped"
start_displacement = { type = "ramp", value = [0.0, 0.0, -0.01], duration = 1.0 }
[initial]
position = [0.0, 0.0, 0.0015]
orientation = [0.0, 1.5707963267948966, 0.0]
[[obstacles]]
shape = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[time]
t_end = 1.0
dt = 0.1
"""


def test_a_prescribed_end_driven_into_an_obstacle_is_named(tmp_path):
    """A steel wire (r = 1 mm) clamped 1.5 mm above a table, its clamp lowered 1 cm in
    1 s (a robot pressing a compliant finger, written with the clamp's path through the
    table): the clamp's surface reaches the table at t = 0.5 mm / (1 cm/s) = 0.05 s,
    where no barrier can hold back the prescribed end.  Exit 3 before 0.05 s, and the
    error names the motion's key, not "raise contact.stiffness" (which cannot help)."""
    scene = tmp_path / "pressed.toml"
    scene.write_text(PRESSED)
    proc = cli("run", scene, "--out", tmp_path / "run")
    assert proc.returncode == 3, proc.stdout + proc.stderr
    message = proc.stdout + proc.stderr
    failed = float(re.search(r"time step failed at t = ([0-9.e-]+)", message).group(1))
    assert 0.0 < failed < 0.05
    assert ("the prescribed motion boundary.start_displacement drives its end (s = 0) "
            "into obstacles[0]") in message, message
    assert "raise contact.stiffness" not in message
