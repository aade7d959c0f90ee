"""Natural frequencies about the current state (issue 27 item 5,
dolfin_rod/analysis/vibration.py), against independently computed closed forms, at the
observed second order in h (P1 positions and rotation vectors).

Each bending frequency is double (two bending planes); a rod pinned at both ends also
has the rigid spin about its axis (omega = 0: the supports do not hold it).

* Euler-Bernoulli (EI = rho A = L = 1; shear and axial stiffness 1e5, rotary inertia
  1e-8: their corrections are <= 1e-4 of omega): cantilever omega_n = (beta_n L)^2 with
  cos(beta L) cosh(beta L) = -1 (beta L = 1.8751, 4.6941, 7.8548; brentq here),
  pinned-pinned (n pi)^2.
* A thick pinned-pinned rod (Timoshenko: kappa G A = 100 EI / L^2, rho I = 2.5e-3 rho A
  L^2): for w = W sin(kx), phi = Phi cos(kx), k = n pi / L, Timoshenko's equations
  give det [[kGA k^2 - rho A w^2, -kGA k], [-kGA k, EI k^2 + kGA - rho I w^2]] = 0,
  whose lower root is solved here with brentq: 9.3209, 32.595, 62.617 (Euler-Bernoulli:
  9.8696, 39.478, 88.826).
* A string (EI = 1e-6, EA = 1e3, pre-stretched by 1e-3: T = 1, pinned ends):
  omega_n = (n pi / L) sqrt(T / (lambda rho A)) with lambda = 1.001 the stretch (the
  mass per current length is rho A / lambda); bending adds (n pi)^2 EI / 2T <= 5e-6.

Tolerances: orders within 0.2 of 2 between 8 and 16 cells, errors at 16 cells below
the measured ones (listed per test) times 1.2.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq, minimize_scalar

from determinants import first_root
from determinants import smallest_singular_value as smallest_singular_value_of
from dolfin_rod.analysis.vibration import vibration_modes
from dolfin_rod.rod import EndLoad, RodModel, RodParameters, StartingState, Straight

SLENDER = RodParameters(length=1.0, A=(1.0, 1.0, 1.0), B=(1e5, 1e5, 1e5), density=1.0,
                        section_inertia=1e-8)


def frequencies(params, ends, n_cells, count, start=None) -> np.ndarray:
    rod = RodModel(params, n_cells=n_cells, model="hyperelastic", start=ends[0],
                   end=ends[1])
    rod.set_initial_state(start=start)
    modes = vibration_modes(rod, 0.0, count)
    assert max(modes.residuals) < 1e-10
    omega = modes.omega
    assert np.allclose(omega[-2 * 3:][::2], omega[-2 * 3:][1::2], rtol=1e-7)  # the planes
    return omega


def check(errors8, errors16, measured16):
    errors8, errors16 = np.abs(errors8), np.abs(errors16)
    orders = np.log2(errors8 / errors16)
    assert np.all(np.abs(orders - 2) < 0.2), (orders, errors16)
    assert np.all(errors16 < 1.2 * np.asarray(measured16)), errors16


@pytest.mark.mpi
def test_cantilever_frequencies():
    """Measured relative errors at 8 / 16 cells: 1.85e-3, 3.90e-2, 0.118 / 4.52e-4,
    9.49e-3, 2.76e-2 (orders 2.03, 2.04, 2.09)."""
    beta = [brentq(lambda b: math.cos(b) * math.cosh(b) + 1, a, a + 1.5)
            for a in (1.0, 4.0, 7.0)]
    assert beta == pytest.approx([1.8751, 4.6941, 7.8548], abs=1e-4)
    exact = np.array(beta) ** 2
    errors = [frequencies(SLENDER, ("clamped", "free"), n, 6)[::2] / exact - 1
              for n in (8, 16)]
    check(*errors, [4.52e-4, 9.49e-3, 2.76e-2])


@pytest.mark.mpi
def test_pinned_pinned_frequencies():
    """The rigid spin first, then (n pi)^2; measured relative errors at 8 / 16 cells:
    1.95e-2, 8.18e-2, 0.200 / 4.79e-3, 1.94e-2, 4.44e-2 (orders 2.03, 2.08, 2.17;
    2.05-2.08 from 16 to 32 cells)."""
    exact = (np.arange(1, 4) * math.pi) ** 2
    errors = []
    for n in (8, 16):
        omega = frequencies(SLENDER, ("pinned", "pinned"), n, 7)
        assert omega[0] == 0.0
        errors.append(omega[1::2] / exact - 1)
    check(*errors, [4.79e-3, 1.94e-2, 4.44e-2])


def timoshenko(n: int, EI=1.0, kGA=100.0, rhoA=1.0, rhoI=2.5e-3) -> float:
    k = n * math.pi
    det = lambda w2: (kGA * k * k - rhoA * w2) * (EI * k * k + kGA - rhoI * w2) \
        - (kGA * k) ** 2                                                  # noqa: E731
    return math.sqrt(brentq(det, 1e-12, EI * k ** 4 / rhoA))   # below Euler-Bernoulli


@pytest.mark.mpi
def test_thick_rod_against_timoshenko():
    """Measured relative errors at 8 / 16 cells: 1.82e-2, 6.40e-2, 0.126 / 4.49e-3,
    1.55e-2, 3.01e-2 (orders 2.01, 2.04, 2.07)."""
    thick = RodParameters(length=1.0, A=(1.0, 1.0, 100.0), B=(100.0, 100.0, 1e4),
                          density=1.0, section_inertia=2.5e-3)
    exact = np.array([timoshenko(n) for n in (1, 2, 3)])
    assert exact == pytest.approx([9.3209, 32.595, 62.617], abs=1e-3)
    errors = [frequencies(thick, ("pinned", "pinned"), n, 7)[1::2] / exact - 1
              for n in (8, 16)]
    check(*errors, [4.49e-3, 1.55e-2, 3.01e-2])


@pytest.mark.mpi
def test_string_under_tension():
    """Measured relative errors at 8 / 16 cells: 6.44e-3, 2.59e-2, 5.84e-2 / 1.61e-3,
    6.46e-3, 1.46e-2 (orders 2.00)."""
    string = RodParameters(length=1.0, A=(1e-6, 1e-6, 1e-6), B=(1e5, 1e5, 1e3), density=1.0,
                           section_inertia=1e-8)
    stretch = 1.001
    exact = np.arange(1, 4) * math.pi * math.sqrt(1e3 * (stretch - 1) / stretch)
    errors = [frequencies(string, ("pinned", "pinned"), n, 7,
                          StartingState(shape=Straight(stretch=stretch)))[1::2] / exact - 1
              for n in (8, 16)]
    check(*errors, [1.61e-3, 6.46e-3, 1.46e-2])



def twisted_clamped_rod(moment: float) -> float:
    """The lowest omega of a clamped-clamped rod (B = rho A = L = 1) under an axial
    moment M: w = sum c_k e^{r_k z}, B r^4 - i M r^3 - rho A omega^2 = 0 (w = u + i v,
    Greenhill's twisted-shaft equation with inertia), clamped at both ends: the
    smallest omega where the column-scaled 4 x 4 matrix of w(0), w'(0), w(1), w'(1) is
    singular (numpy: its smallest singular value; a grid, then minimize_scalar)."""
    def smallest_singular_value(omega: float) -> float:
        roots = np.roots([1.0, -1j * moment, 0.0, 0.0, -omega ** 2])
        D = np.array([[(np.exp(r * z), r * np.exp(r * z))[k] for r in roots]
                      for z in (0.0, 1.0) for k in (0, 1)], dtype=complex)
        return smallest_singular_value_of(D)
    return first_root(smallest_singular_value, np.linspace(0.5, 30.0, 600))


@pytest.mark.mpi
def test_pre_twisted_clamped_rod():
    """About a twisted state: clamped at s = 0, at s = L turning freely about the axis
    under an end couple M = 0.3 M_cr (M_cr = 2 x, tan x = x: Greenhill's, 8.9868 B/L;
    the start settled in equilibrium, uniform twist 2.70 rad), GJ = EI.  The reference
    omega = 21.5947 (untwisted 22.3733 = 4.7300^2, which the determinant reproduces);
    measured relative errors at 8, 16, 32 cells: 5.41e-2, 1.29e-2, 3.0e-3 (orders
    2.07, 2.1).  (Twists above pi need several steps: the start's one Newton solve on
    rotation vectors cannot turn a node by more than pi.)"""
    from dolfin_rod.rod import EndLoad
    # (the minimum of a singular value, a cusp: located to ~1e-9)
    assert twisted_clamped_rod(0.0) == pytest.approx(4.730040744862704 ** 2, rel=1e-8)
    moment = 0.3 * 8.986818916818
    exact = twisted_clamped_rod(moment)
    assert exact == pytest.approx(21.5947, abs=1e-4)
    errors = []
    for n in (8, 16):
        rod = RodModel(SLENDER, n_cells=n, model="hyperelastic", start="clamped", end="clamped",
                       end_turn={"end": (0.0, 0.0, 1.0)},
                       end_loads=[EndLoad("couple", (0.0, 0.0, moment))])
        rod.set_initial_state(start=StartingState(equilibrium=True))
        omega = vibration_modes(rod, 0.0, 2).omega
        assert omega[1] == pytest.approx(omega[0], rel=1e-7)
        errors.append(omega[0] / exact - 1)
    assert abs(math.log2(errors[0] / errors[1]) - 2) < 0.2, errors
    assert 0 < errors[1] < 1.2 * 1.29e-2, errors

@pytest.mark.mpi
def test_bad_requests_are_refused():
    quasi_static = RodParameters(length=1.0, B=(1e5, 1e5, 1e5))
    with pytest.raises(ValueError, match="density > 0"):
        vibration_modes(RodModel(quasi_static, n_cells=4, model="hyperelastic"), 0.0)


@pytest.mark.mpi
def test_modes_command(tmp_path):
    """``dolfin-rod modes scenes/string_modes.toml`` (8 cells): the rigid spin, then the
    string's frequencies with the API's error at 8 cells (6.44e-3, 6.44e-3: the two
    planes), modes.json = summary.json's table, modes.bp one step per mode."""
    import json
    from pathlib import Path

    from mpi4py import MPI

    from dolfin_rod import read_vtx
    from dolfin_rod.cli import main
    comm = MPI.COMM_WORLD
    text = (Path(__file__).parents[1] / "scenes" / "string_modes.toml").read_text()
    scene, out = tmp_path / "string.toml", tmp_path / "out"
    if comm.rank == 0:
        scene.write_text(text.replace("n_cells = 16", "n_cells = 8"))
    scene, out = comm.bcast((str(scene), str(out)))
    assert main(["modes", scene, "--out", out, "--quiet", "--count", "3"]) == 0
    if comm.rank != 0:
        return
    table = json.loads((Path(out) / "modes.json").read_text())["modes"]
    omega = [row["omega"] for row in table]
    exact = math.pi * math.sqrt(1e3 * 1e-3 / 1.001)
    assert omega[0] == 0.0
    assert np.array(omega[1:]) / exact - 1 == pytest.approx([6.44e-3] * 2, abs=1e-5)
    assert table[1]["frequency"] == pytest.approx(omega[1] / (2 * math.pi))
    assert json.loads((Path(out) / "summary.json").read_text())["modes"]["modes"] == table
    steps = read_vtx(Path(out) / "modes.bp")
    assert [s["time"] for s in steps] == [1.0, 2.0, 3.0]
    # the spin is a turn alone: no displacement (its round-off was drawn as a bending
    # shape), its rotation about the string's axis e_3 scaled to 1
    spin = steps[0]["point"]
    assert np.max(np.abs(spin["mode_displacement"])) == 0.0
    turn = spin["mode_rotation"].reshape(-1, 3)
    assert np.max(np.linalg.norm(turn, axis=1)) == pytest.approx(1.0)
    assert np.max(np.abs(turn[:, :2])) < 1e-8
    assert np.max(np.abs(steps[1]["point"]["mode_displacement"])) > 0.01


def modes_of(rotations: str, ends) -> object:
    """8 cells, unequal bending stiffnesses (A = (1, 2): every mode single, its shape
    unique up to sign)."""
    params = RodParameters(length=1.0, A=(1.0, 2.0, 1.0), B=(1e5, 1e5, 1e5), density=1.0,
                           section_inertia=(1e-4, 2e-4))
    rod = RodModel(params, n_cells=8, model="hyperelastic", start=ends[0], end=ends[1],
                   rotations=rotations)
    rod.set_initial_state()
    modes = vibration_modes(rod, 0.0, 5)
    assert max(modes.residuals) < 1e-10
    return modes


@pytest.mark.mpi
@pytest.mark.parametrize("ends", [("clamped", "free"), ("pinned", "pinned")])
def test_quaternion_form_has_the_rotation_vectors_modes(ends):
    """The quaternion form (M's rotation block rho J in 2 vec(conj(q) dq)/|q|^2, K and M
    bordered by the gauge multiplier: analysis/vibration.py) gives the rotation vectors'
    frequencies and modes (the rotation part as material rotation vectors), to 1e-9
    (measured: 1e-14); the cantilever's first two against (beta L)^2 sqrt(EI/rho A)
    with EI = 1, 2, the pinned-pinned rod's rigid spin (0) and pi^2, within their 8-cell
    errors (test_cantilever_frequencies, test_pinned_pinned_frequencies: 1.85e-3,
    1.95e-2; rotary inertia 1e-4 lowers them by < 1e-3)."""
    vectors, quaternions = (modes_of(r, ends) for r in ("rotation_vector", "quaternion"))
    assert quaternions.omega == pytest.approx(vectors.omega, rel=1e-9, abs=1e-9)
    for a, b, omega in zip(vectors.shapes, quaternions.shapes, vectors.omega):
        if omega == 0:      # the rigid spin: no displacement to scale by (round-off)
            continue
        sign = np.sign(np.dot(a["displacement"], b["displacement"]))
        for key in ("displacement", "rotation"):
            assert sign * b[key] == pytest.approx(a[key], abs=1e-7)
    first = 1.8751 ** 2 if ends[0] == "clamped" else math.pi ** 2
    bending = quaternions.omega[quaternions.omega > 0][:2]
    tolerance = 2.5e-3 if ends[0] == "clamped" else 2.2e-2
    assert bending / (first * np.sqrt([1.0, 2.0])) == pytest.approx([1, 1], rel=tolerance)
    if ends[0] == "pinned":
        assert quaternions.omega[0] == 0.0


def two_rods_joined(dynamic: bool = True):
    """A cantilever of length 1 as two rods of 8 cells joined rigidly at s = 0.5, the
    upper one turned by pi/2 about the axis with its section's stiffnesses and inertias
    swapped: the one rod of 16 cells (A = (1, 2), I = (1e-3, 2e-3))."""
    from dolfin_rod import Rod, RodSystem
    from dolfin_rod.rod.joints import Joint
    half = [RodParameters(length=0.5, A=(*a, 1.5), B=(1e5, 1e5, 1e5), density=1.0,
                          section_inertia=(i[0], i[1]))
            for a, i in (((1.0, 2.0), (1e-3, 2e-3)), ((2.0, 1.0), (2e-3, 1e-3)))]
    return RodSystem([Rod(half[0], 8, name="lower"),
                      Rod(half[1], 8, "free", end="free", name="upper",
                          position=(0.0, 0.0, 0.5), orientation=(0.0, 0.0, math.pi / 2))],
                     joints=[Joint("rigid", ("lower", "upper"), (0.0, 0.0, 0.5))],
                     model="hyperelastic")


@pytest.mark.mpi
def test_rods_joined_rigidly_vibrate_as_one_rod():
    """Modes through the joint's constraint map (P^T K P, P^T M P): the jointed cantilever
    has the one rod's frequencies to round-off (measured 1e-15 relative; asserted 1e-10),
    3.5013, 4.9630 for (beta L)^2 sqrt(EI / rho A) = 3.5160 sqrt(1, 2) (8.5e-3 below:
    the 16-cell error and rotary inertia 1e-3)."""
    one = RodParameters(length=1.0, A=(1.0, 2.0, 1.5), B=(1e5, 1e5, 1e5), density=1.0,
                        section_inertia=(1e-3, 2e-3))
    single = RodModel(one, n_cells=16, model="hyperelastic")
    joined = two_rods_joined()
    omega = []
    for rod in (single, joined):
        rod.set_initial_state()
        modes = vibration_modes(rod, 0.0, 6)
        assert max(modes.residuals) < 1e-10
        omega.append(modes.omega)
    assert omega[1] == pytest.approx(omega[0], rel=1e-10)
    assert omega[1][:2] / (1.8751 ** 2 * np.sqrt([1.0, 2.0])) == pytest.approx(
        [1.0, 1.0], rel=1e-2)


@pytest.mark.mpi
def test_modes_command_on_an_auto_scene_with_quaternions(tmp_path):
    """``dolfin-rod modes`` of the string scene with time.scheme = "bdf2", for which
    geometry.rotations = "auto" picks quaternions: the table of the rotation vectors'
    (test_modes_command: the rigid spin, then the 8-cell error 6.44e-3)."""
    import json
    from pathlib import Path

    from mpi4py import MPI

    from dolfin_rod.cli import main
    from dolfin_rod.scenes import parse_scene
    from dolfin_rod.scenes.rules import rod_rotations
    comm = MPI.COMM_WORLD
    text = (Path(__file__).parents[1] / "scenes" / "string_modes.toml").read_text()
    text = text.replace("n_cells = 16", "n_cells = 8").replace(
        "[time]\n", '[time]\nscheme = "bdf2"\n')
    assert rod_rotations(parse_scene(text)) == "quaternion"
    scene, out = tmp_path / "string.toml", tmp_path / "out"
    if comm.rank == 0:
        scene.write_text(text)
    scene, out = comm.bcast((str(scene), str(out)))
    assert main(["modes", scene, "--out", out, "--quiet", "--count", "3"]) == 0
    if comm.rank != 0:
        return
    omega = [row["omega"] for row in json.loads((Path(out) / "modes.json").read_text())[
        "modes"]]
    exact = math.pi * math.sqrt(1e3 * 1e-3 / 1.001)
    assert omega[0] == 0.0
    assert np.array(omega[1:]) / exact - 1 == pytest.approx([6.44e-3] * 2, abs=1e-5)


@pytest.mark.parametrize("damping, key", [
    ('model = "hyperelastic"\ndrag = 0.5\n', "material.drag"),
    ('model = "kelvin_voigt"\nviscosity = { M = [0.01, 0.01, 0.01], N = [0.1, 0.1, 0.1] }\n',
     "material.viscosity")])
def test_modes_command_says_damping_is_left_out(tmp_path, capsys, damping, key):
    """The string of test_modes_command with drag or Kelvin-Voigt viscosity: the modes
    are those of K phi = omega^2 M phi, undamped (the same table: the rigid spin, then
    the 8-cell error 6.44e-3); the table gave no hint of it, now a note printed and in
    summary.json names the key left out."""
    import json
    from pathlib import Path

    from mpi4py import MPI

    from dolfin_rod.cli import main
    comm = MPI.COMM_WORLD
    text = (Path(__file__).parents[1] / "scenes" / "string_modes.toml").read_text()
    text = text.replace("n_cells = 16", "n_cells = 8").replace(
        'model = "hyperelastic"\n', "").replace("[material]\n", f"[material]\n{damping}")
    scene, out = tmp_path / "string.toml", tmp_path / "out"
    if comm.rank == 0:
        scene.write_text(text)
    scene, out = comm.bcast((str(scene), str(out)))
    assert main(["modes", scene, "--out", out, "--count", "3"]) == 0
    if comm.rank != 0:
        return
    assert f"modes: undamped: the modes leave out the rod's {key}" in capsys.readouterr().out
    entry = json.loads((Path(out) / "summary.json").read_text())["modes"]
    assert entry["note"].startswith(f"undamped: the modes leave out the rod's {key}")
    omega = [row["omega"] for row in entry["modes"]]
    exact = math.pi * math.sqrt(1e3 * 1e-3 / 1.001)
    assert omega[0] == 0.0
    assert np.array(omega[1:]) / exact - 1 == pytest.approx([6.44e-3] * 2, abs=1e-5)


def beck_determinant(w2: float, p: float) -> float:
    """Beck's column (clamped at z = 0; at z = 1 a follower force P tangent to the rod,
    EI = rho A = L = 1, p = P L^2 / EI, w2 = rho A omega^2 L^4 / EI): w'''' + p w'' -
    w2 w = 0 with w = a_1 cosh(a z) + a_2 sinh(a z) + a_3 cos(b z) + a_4 sin(b z), a^2,
    b^2 = (sqrt(p^2 + 4 w2) -+ p) / 2; w(0) = w'(0) = 0 leave a_3 = -a_1, a_4 = -a a_2
    / b, and w''(1) = 0, w'''(1) = 0 (the follower force's transverse part P w'
    cancels the axial force's) the 2 x 2 determinant, divided by a cosh^2 a (at p = 0:
    2 (1 + cos b cosh b), the cantilever's)."""
    s = math.sqrt(p * p + 4 * w2)
    a, b = math.sqrt((s - p) / 2), math.sqrt((s + p) / 2)
    ch, sh, c, sn = math.cosh(a), math.sinh(a), math.cos(b), math.sin(b)
    return ((a * a * ch + b * b * c) ** 2
            - (a * sh + b * sn) * (a ** 3 * sh - b ** 3 * sn)) / ch ** 2


def beck_flutter_load() -> float:
    """p where the two lowest roots w2 of beck_determinant meet: between them the
    determinant has the sign opposite to its sign outside (w2 = 60, 200 here), its
    extremum there crosses 0 when they meet (brentq on it)."""
    def gap(p):
        outside = np.sign(beck_determinant(60.0, p))
        found = minimize_scalar(lambda w2: outside * beck_determinant(w2, p),
                                bounds=(60.0, 200.0), method="bounded",
                                options={"xatol": 1e-10})
        return -found.fun
    return brentq(gap, 19.5, 20.5, xtol=1e-12)


BECK = RodParameters(length=1.0, A=(1.0, 100.0, 1.0), B=(1e5, 1e5, 1e5), density=1.0,
                     section_inertia=1e-8)


def discrete_flutter_load(n_cells: int) -> tuple[float, object]:
    """The follower tip force at which the lowest two omega^2 of the rod meet: brentq on
    the discriminant (omega_2^2 - omega_1^2)^2, real on both sides (a complex pair a +- ib
    gives -4 b^2) and smooth through the meeting; the modes just above it.  xtol 1e-6:
    the test reads relative errors of 7.8e-2 and 1.8e-2 (8, 16 cells) and their order to
    0.15, and 1e-6 in p is 5e-8 relative, 3e-6 of the smaller error (the 16-cell root
    moved by 1e-10 from xtol 1e-10's); brentq stops two evaluations sooner (6, not 8)."""
    scale = [0.0]
    rod = RodModel(BECK, n_cells=n_cells, model="hyperelastic", end_loads=[
        EndLoad("force", (0.0, 0.0, -1.0), lambda t: scale[0], follower=True)])

    def modes(p):
        scale[0] = p
        rod.set_initial_state(start=StartingState(equilibrium=True))   # compressed
        return vibration_modes(rod, 0.0, 2)

    def discriminant(p):
        found = modes(p)
        assert max(found.residuals) < 1e-10
        return (np.diff(found.eigenvalues)[0] ** 2 - np.diff(found.imaginary)[0] ** 2)
    p = brentq(discriminant, 19.0, 23.0, xtol=1e-6)
    return p, modes(p * (1 + 1e-3))


# Serial only: the non-Hermitian pencil on two ranks is test_modes_command_reports_flutter
# (Beck's column at 16 cells above its flutter load: the complex pair, its growth rate).
def test_beck_column_flutters():
    """Beck's column (clamped-free, a follower tip force P: not conservative, K not
    symmetric; analysis/vibration.py solves the non-Hermitian pencil): the lowest two
    bending frequencies meet at P L^2 / EI = 20.050954 (beck_flutter_load; Beck 1952:
    20.05) at omega^2 = 121.34, above it they are a complex pair (flutter: a growing
    mode).  EI = 1 in the plane of the modes, 100 out of it (those modes stay above),
    axial and shear 1e5, rotary inertia 1e-8 (their corrections <= 1e-4).  Measured
    discrete flutter loads at 8 / 16 / 32 cells: 21.60768, 20.42061, 20.14069, relative
    errors 7.76e-2, 1.84e-2, 4.48e-3 (orders 2.07, 2.04)."""
    reference = beck_flutter_load()
    assert reference == pytest.approx(20.05, abs=5e-3)
    errors = []
    for n in (8, 16):
        p, above = discrete_flutter_load(n)
        errors.append(p / reference - 1)
        assert above.flutter and above.growth_rates[0] > 0
        assert above.omega[0] == pytest.approx(above.omega[1], rel=1e-12)
        assert above.omega[0] ** 2 == pytest.approx(121.34, rel=2 * errors[-1])
    assert abs(math.log2(errors[0] / errors[1]) - 2) < 0.15, errors
    assert 0 < errors[1] < 1.2 * 1.84e-2, errors
    # below it: two real frequencies, no growth
    below = RodModel(BECK, n_cells=16, model="hyperelastic", end_loads=[
        EndLoad("force", (0.0, 0.0, -0.95 * reference), follower=True)])
    below.set_initial_state(start=StartingState(equilibrium=True))
    modes = vibration_modes(below, 0.0, 2)
    assert not modes.flutter and modes.omega[1] > modes.omega[0] * 1.2


@pytest.mark.mpi
def test_modes_command_reports_flutter(tmp_path):
    """``dolfin-rod modes scenes/beck_column.toml`` (16 cells, 20.5 EI/L^2: above the
    16-cell flutter load 20.42 of test_beck_column_flutters): the first two rows are the
    complex pair, one omega (measured 11.1677; 11.0 at Beck's load) with the growth rate
    (measured 0.614), the others real (growth_rate 0)."""
    import json
    from pathlib import Path

    from mpi4py import MPI

    from dolfin_rod.cli import main
    comm = MPI.COMM_WORLD
    scene = str(Path(__file__).parents[1] / "scenes" / "beck_column.toml")
    out = comm.bcast(str(tmp_path / "out"))
    assert main(["modes", scene, "--out", out, "--quiet", "--count", "3"]) == 0
    if comm.rank != 0:
        return
    rows = json.loads((Path(out) / "modes.json").read_text())["modes"]
    assert rows[0]["omega"] == pytest.approx(rows[1]["omega"], rel=1e-12)
    assert rows[0]["omega"] == pytest.approx(11.1677, rel=1e-4)
    assert rows[0]["growth_rate"] == rows[1]["growth_rate"] == pytest.approx(0.614227,
                                                                             rel=1e-4)
    assert rows[2]["growth_rate"] == 0.0


@pytest.mark.mpi
def test_a_hinged_clamped_beam_vibrates_as_its_halves():
    """Modes through a hinge's map (fem/multipoint.NodeMap: P^T K P + the map's
    curvature, zero at rest, and P^T M P): a beam of length 1 clamped at both ends, made
    of two rods of half its length joined by a hinge about e_1 at mid-span (EI = rho A =
    1, shear and axial 1e5, rotary inertia 1e-8).  In the hinge's plane its symmetric
    mode has no moment (the hinge) and no shear (symmetry) at mid-span: a clamped-free
    half, omega = 4 (1.8751)^2 = 14.0640; its antisymmetric one no displacement and no
    moment there, as the clamped-clamped beam's second mode: 7.8532^2 = 61.6728, which
    the other plane (the hinge holds) also has, after its first, 4.7300^2 = 22.3733.
    Measured relative errors at 8 / 16 cells per rod: 1.78e-3 / 3.82e-4, 1.19e-2 /
    2.77e-3, 3.31e-2 / 7.68e-3 (x 2); asserted: the 16-cell errors below 1.2 times
    those, the orders 8 -> 16 within 0.3 of 2 (the shear's constant -1e-4 shows at 32
    cells), the double mode to 1e-8."""
    from dolfin_rod import Rod, RodSystem
    from dolfin_rod.rod.joints import Joint
    half = RodParameters(length=0.5, A=(1.0, 1.0, 1.0), B=(1e5, 1e5, 1e5), density=1.0,
                         section_inertia=1e-8)
    exact = np.array([4 * 1.875104068711961 ** 2, 4.730040744862704 ** 2,
                      7.853204624095838 ** 2, 7.853204624095838 ** 2])
    errors = []
    for n in (8, 16):
        beam = RodSystem([Rod(half, n, name="left"),
                          Rod(half, n, "free", end="clamped", name="right",
                              position=(0.0, 0.0, 0.5))],
                         joints=[Joint("hinge", ("left", "right"), (0.0, 0.0, 0.5),
                                       axis=(1.0, 0.0, 0.0))],
                         model="hyperelastic")
        beam.set_initial_state()
        omega = vibration_modes(beam, 0.0, 4).omega
        assert omega[3] == pytest.approx(omega[2], rel=1e-8)
        errors.append(omega / exact - 1)
    assert np.all(errors[1] > 0) and np.all(errors[1] < 1.2 * np.array(
        [3.82e-4, 2.77e-3, 7.68e-3, 7.68e-3])), errors
    assert np.all(np.abs(np.log2(errors[0] / errors[1]) - 2) < 0.3), errors
