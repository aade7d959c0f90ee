"""Self-contact of a rod split at the corners of its stress-free polyline (rod/kinks.py):
its pieces are one rod, so `contact.self` pairs segments of any two of them, neighbours
along the rod (across a corner too) excluded as along a straight rod (pair_contact.
SegmentContact.allowed; `dolfin-rod check` mirrors it, scenes/contact.py).  Before, the
pieces were separate rods: `contact.self` alone never paired two of them (a hook pushed
onto its own column passed through it), `check` said OK to pieces overlapping at t = 0,
a rod whose pieces were each shorter than the neighbour exclusion was refused, and the
pass-through check warned "self-contact is off" of two parallel segments in contact."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
QUIET = {"outputs.animation": False, "outputs.plots": False, "outputs.fields": False}

# a steel wire (r = 1 cm, E = 1 GPa) bent into a hook: a column down from the clamp at
# the origin, a foot along e_1, a riser up, and an arm back across the column 3 cm in
# front of it (centre lines 1 cm apart at the crossing, z = -0.5); the arm's tip pushed
# towards the column (-e_2) by a force ramped to 0.5 N: the arm lands on the column at
# t ~ 0.33 and is held there by self-contact
HEAD = """
[scene]
units = "SI"
[section]
shape = "circle"
radius = 0.01
[material]
model = "hyperelastic"
youngs_modulus = 1e9
poisson_ratio = 0.3
[time]
t_end = 0.5
dt = 0.025
"""
POINTS = [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.2, 0.0, -1.0], [0.2, 0.0, -0.5],
          [-0.1, 0.045, -0.5]]
ARM = float(np.linalg.norm(np.subtract(POINTS[4], POINTS[3])))
PUSH = 'end_force = { type = "ramp", value = [0.0, -1.0, 0.0], duration = 1.0 }'

KINKED = HEAD + f"""
[geometry]
length = {1.7 + ARM!r}
n_cells = 40
reference_shape = {{ type = "polyline", points = {POINTS} }}
[contact]
self = true
stiffness = 1.5e5
[boundary]
start = "clamped"
[loads]
{PUSH}
"""


def _rod(name: str, start, direction, length: float, cells: int, extra: str = "") -> str:
    """A [[rods]] table: a straight rod from ``start`` along ``direction`` (the rotation
    vector turning e_3 onto it by the shortest turn)."""
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    axis = np.cross([0.0, 0.0, 1.0], d)
    turn = (axis / np.linalg.norm(axis) * np.arccos(np.clip(d[2], -1, 1))
            if np.linalg.norm(axis) > 1e-12 else
            np.array([0.0, 0.0, 0.0]) if d[2] > 0 else np.array([np.pi, 0.0, 0.0]))
    return (f'\n[[rods]]\nname = "{name}"\nposition = {list(map(float, start))}\n'
            f"orientation = {[float(v) for v in turn]}\n"
            f"geometry = {{ length = {length!r}, n_cells = {cells} }}\n{extra}")


def welded() -> str:
    """The hook as four straight rods welded by rigid joints at its corners, contact
    between rods and self-contact: the same equations and the same pairs as the kinked
    rod (the corners' neighbours excluded through the joints)."""
    P = np.array(POINTS)
    cells = (20, 4, 10, 6)                      # the kinked rod's share of its 40 cells
    ends = ('boundary = { start = "clamped", end = "free" }',
            'boundary = { start = "free", end = "free" }',
            'boundary = { start = "free", end = "free" }',
            'boundary = { start = "free", end = "free" }\nloads = { ' + PUSH + " }")
    text = HEAD + "[contact]\nself = true\nbetween_rods = true\nstiffness = 1.5e5\n"
    for k in range(4):
        text += _rod("abcd"[k], P[k], P[k + 1] - P[k], float(np.linalg.norm(P[k + 1] - P[k])),
                     cells[k], ends[k])
    for k in range(3):
        text += (f'\n[[joints]]\nkind = "rigid"\nrods = ["{"abcd"[k]}", "{"abcd"[k + 1]}"]\n'
                 f"point = {list(map(float, P[k + 1]))}\n")
    return text


def _check(path: Path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "dolfin_rod", "check", str(path), *args],
                          capture_output=True, text=True, timeout=120, cwd=ROOT, env=env)


def test_a_hook_pushed_onto_its_own_column_is_held_as_the_welded_frame(tmp_path):
    """The kinked hook with contact.self only against the same hook as four rods welded
    at its corners with contact between rods (the frame of rods and rigid joints is the
    kinked rod's equations, tests/test_reference_shape.py): the same arm tip and pair
    force to 1e-10 (the same equations and pairs: round-off of the converged states,
    measured 4e-13), the arm resting on the column (pairs in contact, every gap > 0).
    Without the pieces paired the arm passed through the column (its tip 4.1e-3 m off,
    no pair)."""
    from dolfin_rod import run
    (tmp_path / "kinked.toml").write_text(KINKED)
    (tmp_path / "welded.toml").write_text(welded())
    one = run(tmp_path / "kinked.toml", QUIET, out=tmp_path / "one", quiet=True)
    two = run(tmp_path / "welded.toml", QUIET, out=tmp_path / "two", quiet=True)
    assert one.status == two.status == "completed"
    a = np.array([one.series[f"tip_position_{c}"][-1] for c in "xyz"])
    b = np.array([two.series[f"d.tip_position_{c}"][-1] for c in "xyz"])
    moved = np.linalg.norm(b - POINTS[4])
    assert moved > 0.01
    assert np.linalg.norm(a - b) < 1e-10 * moved
    assert one.series["contact_pairs"][-1] >= 1
    assert one.series["pair_contact_force"][-1] == pytest.approx(
        two.series["pair_contact_force"][-1], rel=1e-10)
    assert one.series["pair_contact_force"][-1] > 0.05      # a part of the 0.5 N push
    assert 0.0 < min(one.series["min_pair_gap"]) < 1e-3      # within the barrier, > 0
    assert not one.summary.get("warnings")


@pytest.mark.mpi
def test_a_hook_on_its_column_serial_equals_two_ranks(tmp_path):
    """The kinked hook of the test above, 16 steps (the arm on the column from step 14),
    on the ranks of the run and serially: the same time series to 1e-10 relative
    (quick_scenes.assert_serial_run_equal; the pairs are searched on every rank's
    gathered line), 1e-7 N absolute (2e-7 of the 0.5 N push): the corners' reactions
    across the push are 0 up to the converged Newton residual, and the two runs' differ
    by it (Newton's absolute tolerance since the force scale, checks.NEWTON_FORCE_TOL
    times max |A| / L^2 = 2 N: measured up to 1.3e-8 N apart; 1.7e-10 N with the fixed
    1e-10 before)."""
    from mpi4py import MPI
    from quick_scenes import assert_serial_run_equal, quick_scene

    from dolfin_rod import run_scene
    comm = MPI.COMM_WORLD
    folder = Path(comm.bcast(str(tmp_path), root=0))
    path = folder / "kinked.toml"
    if comm.rank == 0:
        path.write_text(KINKED)
    comm.barrier()
    quiet = {key.replace(".", "__"): value for key, value in QUIET.items()}
    summary = run_scene(quick_scene(path, 16, **quiet), folder / "run", quiet=True)
    assert summary["status"] == "completed"
    if comm.rank == 0:
        series = np.genfromtxt(folder / "run" / "timeseries.csv", delimiter=",", names=True)
        assert series["contact_pairs"][-1] >= 1
    if comm.size > 1 and comm.rank == 0:
        assert_serial_run_equal(path, folder, 16, atol=1e-7, **quiet)


def test_check_sees_the_pieces_of_a_kinked_rod(tmp_path):
    """`dolfin-rod check` (and run) pair the pieces as the model does: the hook's arm
    started through its column (the crossing at y = 0.005 < 2 r) is refused naming
    contact.self and both places on the rod by its own arc length (before: OK); a
    zigzag whose pieces are each shorter than the exclusion pi (r + delta) + h but whose
    rod is not is accepted (before: refused naming contact.radius, "not shorter than the
    rod")."""
    bad = tmp_path / "through.toml"
    bad.write_text(KINKED.replace("0.045,", "0.0075,").replace(
        f"length = {1.7 + ARM!r}", f"length = {1.7 + float(np.hypot(0.3, 0.0075))!r}"))
    out = _check(bad)
    assert out.returncode == 2, out.stdout + out.stderr
    assert "[contact.self]" in out.stderr and "the rod at s = 0.475" in out.stderr, out.stderr
    assert "Traceback" not in out.stderr
    zigzag = tmp_path / "zigzag.toml"
    points = [[0.03 * (k % 2), 0.0, 0.04 * k] for k in range(21)]     # 20 pieces of 0.05
    zigzag.write_text(HEAD + f"""
[geometry]
length = 1.0
n_cells = 40
reference_shape = {{ type = "polyline", points = {points} }}
[contact]
self = true
""")
    out = _check(zigzag)
    assert out.returncode == 0, out.stderr
    # pi (0.01 + 0.001) + 0.025 = 0.0596 > 0.05, each piece's length
    assert "closer along the rod than pi (r + gap) + h = 0.05956" in out.stdout, out.stdout


def test_no_pass_through_warning_of_segments_in_contact(tmp_path):
    """A hairpin (two legs 0.1 apart joined by a foot) with one leg clamped and the
    other's tip pushed onto it: the tip rests on the clamped leg, parallel to it, held by
    self-contact (the gap > 0 at every output), and no warning (before: "the rod passed
    through itself ... self-contact is off", the crossing side of two parallel segments
    flipping with round-off)."""
    from dolfin_rod import run
    path = tmp_path / "hairpin.toml"
    path.write_text(HEAD.replace("t_end = 0.5", "t_end = 0.6").replace(
        "dt = 0.025", "dt = 0.05") + """
[geometry]
length = 2.1
n_cells = 42
reference_shape = { type = "polyline", points = [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.1, 0.0, -1.0], [0.1, 0.0, 0.0]] }
[contact]
self = true
[boundary]
start = "clamped"
[loads]
end_force = { type = "ramp", value = [-2.05, 0.0, 0.0], duration = 1.0 }
[stability]
check = false
""")
    result = run(path, QUIET, out=tmp_path / "run", quiet=True)
    assert result.status == "completed"
    assert result.series["contact_pairs"][-1] >= 1
    assert min(result.series["min_pair_gap"]) > 0.0
    assert result.series["tip_position_x"][-1] > 0.02          # on the leg: 2 r from x = 0
    assert not result.summary.get("warnings"), result.summary.get("warnings")
