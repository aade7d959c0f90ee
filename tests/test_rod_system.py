"""Several rods in one model (dolfin_rod.rod.system.RodSystem): independence of unjoined
rods, serial = 2 ranks, bad input.  The rods of tests/rod_systems.py: a dynamic
clamped rod with a tip force and a pinned one with another material, length, cell count
and reference curvature, moved and turned in space, with a tip couple."""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI
from rod_systems import (COUPLE_B, POSITION_B, alone, run_system, turn_b, two_rods)
from serial_reference import serial

from dolfin_rod import EndLoad, Rod, RodParameters, RodSystem

XYZ = "xyz"


def vector(d: dict, key: str) -> np.ndarray:
    return np.array([d[f"{key}_{c}"] for c in XYZ])


@pytest.mark.mpi
@pytest.mark.parametrize("placed", [False, True])
def test_unjoined_rods_move_as_each_alone(placed):
    """Rod a and rod b in one system equal each run alone: tips, reactions, energies.
    The system's Jacobian is the two rods' block-diagonal one; Newton runs to 1e-13
    (ROUND_OFF), but it stops on the system's residual, one iteration sooner or later
    than a rod alone: measured differences 8e-12 (tips, moved rod), 1e-12 (tips,
    turned rod: its rotations and couple turned, which the discrete strains cancel
    exactly, rotation_vector.py), 2.3e-11 (reactions ~ 1): tolerance 1e-10.  Each rod's
    own energies (``<name>.free_energy``, ``.kinetic_energy``) are its run alone's, and
    they add up to the system's (round-off: 1e-14)."""
    system = run_system(two_rods(placed))
    a, b = run_system(alone("a")), run_system(alone("b"))
    turn = turn_b() if placed else np.eye(3)
    tol = 1e-10
    assert np.allclose(vector(system, "a.tip_position"), vector(a, "tip_position"),
                       rtol=0, atol=tol)
    assert np.allclose(vector(system, "b.tip_position"),
                       POSITION_B + turn @ vector(b, "tip_position"), rtol=0, atol=tol)
    for rod, turned, own in (("a", np.eye(3), a), ("b", turn, b)):
        for key in ("reaction_force_start",) + (("reaction_couple_start",) if rod == "a" else ()):
            assert np.allclose(vector(system, f"{rod}.{key}"), turned @ vector(own, key),
                               rtol=0, atol=tol)
    for key in ("free_energy", "kinetic_energy", "dissipation_rate", "load_power"):
        assert system[key] == pytest.approx(a[key] + b[key], rel=tol, abs=tol)
    for key in ("free_energy", "kinetic_energy"):
        for rod, own in (("a", a), ("b", b)):
            assert system[f"{rod}.{key}"] == pytest.approx(own[key], rel=tol, abs=tol)
        assert system[f"a.{key}"] + system[f"b.{key}"] == pytest.approx(system[key],
                                                                      rel=1e-14, abs=1e-16)
        assert system[f"a.{key}"] > 0 and system[f"b.{key}"] > 0
    assert abs(a["tip_position_x"]) > 0.05 and abs(b["tip_position_x"]) > 0.02  # moved


@pytest.mark.mpi
def test_rod_system_serial_equals_two_ranks():
    """The same system on the ranks of the run and serially (a separate process):
    Newton to 1e-13, so the partition changes only round-off (1e-10 on values ~1)."""
    here = run_system(two_rods(placed=True, comm=MPI.COMM_WORLD))
    reference = serial("rod_system")
    assert set(here) == set(reference)
    for key, value in reference.items():
        assert here[key] == pytest.approx(value, rel=1e-10, abs=1e-10), key


@pytest.mark.parametrize("change, message", [
    (dict(name="a"), "rods[1].name 'a' is used twice"),
    (dict(params=RodParameters(length=0.5)), "rods[1].params.density"),
    (dict(position=(1.0, 2.0)), "rods[1] 'b': position must be a finite 3-vector"),
    (dict(end_loads=[EndLoad("force", (1, 0, 0), end="middle")]), "rods[1] 'b': EndLoad end must be 'start'"),
])
def test_bad_rods_are_named(change, message):
    rods = [Rod(RodParameters(density=1.0), 4, name="a"),
            Rod(**{**dict(params=RodParameters(density=1.0), n_cells=4, name="b"), **change})]
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace("[", r"\[")):
        RodSystem(rods)


def test_one_paraview_file_with_every_rod(tmp_path):
    """rod.bp holds every rod as its own line: the sum of the rods' nodes and cells, no
    cell between two rods, each rod's nodes where it was placed (rod b's left end at
    POSITION_B); the pictures draw each rod apart."""
    from dolfin_rod.output.field_outputs import FieldOutputs
    from dolfin_rod.output.vtx import read_vtx
    system = two_rods(placed=True)
    system.set_initial_state()
    out = FieldOutputs(tmp_path, system, MPI.COMM_WORLD)
    out.write(0.0)
    from dolfin_rod import TimeStepper
    TimeStepper(system.problem).run(0.0, 0.04, 0.02, observer=lambda t, _: out.write(t))
    out.finish("two rods")
    step = read_vtx(tmp_path / "rod.bp")[0]
    assert step["points"].shape == ((6 + 1) + (5 + 1), 3)
    assert len(step["cells"]) == 6 + 5
    lengths = np.linalg.norm(np.diff(step["points"][step["cells"]], axis=1)[:, 0], axis=1)
    # cell lengths: 1/6 (rod a, straight) and the chords 0.14 sinc(0.3 0.14 / 2) of rod b
    assert np.allclose(lengths[:6], 1 / 6, rtol=1e-12)
    assert np.allclose(lengths[6:], 0.14 * np.sinc(0.3 * 0.14 / 2 / np.pi), rtol=1e-12)
    assert np.allclose(step["points"][7], POSITION_B, rtol=0, atol=1e-14)
    assert np.allclose(step["points"][:7, 2], np.linspace(0, 1, 7), rtol=0, atol=1e-14)
    assert (tmp_path / "animation.gif").exists() and (tmp_path / "snapshots.png").exists()


@pytest.mark.mpi
def test_uniform_variant_rods_have_their_own_global_strains():
    """The uniform variant (eq. unatevolunif: one global natural curvature and stretch per
    rod): two quasi-static evolving rods of different material, length and reference
    curvature in one system relax each as it would alone (backward Euler, 5 steps,
    Newton to 1e-13: measured 2.6e-15 on the tips), each rod's global natural strains
    its own (rod b keeps its reference curvature 0.3 in u_d,1)."""
    from dolfin_rod import TimeStepper
    pa = RodParameters(length=1.0, M_d=(5, 5, 5), N_d=(5, 5, 5))
    pb = RodParameters(length=0.7, A=(2, 1.5, 1), B=(3, 3, 4), M_d=(2, 2, 2), N_d=(2, 2, 2),
                       reference_curvature=(0.3, 0, 0))
    la, lb = [EndLoad("force", (0.3, 0, 0))], [EndLoad("couple", (0, 0.5, 0.2))]

    def run(model):
        model.set_initial_state()
        TimeStepper(model.problem, "backward_euler", solver_options=ROUND_OFF).run(0, 0.5, 0.1)
        return model.diagnostics(0.5)

    from dolfin_rod import RodModel
    from rod_systems import ROUND_OFF
    a = run(RodModel(pa, 6, variant="uniform", end_loads=la))
    b = run(RodModel(pb, 5, variant="uniform", end_loads=lb))
    system = RodSystem([Rod(pa, 6, end_loads=la, name="a"),
                        Rod(pb, 5, end_loads=lb, name="b", position=POSITION_B)],
                       variant="uniform")
    d = run(system)
    assert np.allclose(vector(d, "a.tip_position"), vector(a, "tip_position"), atol=1e-13)
    assert np.allclose(vector(d, "b.tip_position"), POSITION_B + vector(b, "tip_position"),
                       atol=1e-13)
    for key in ("free_energy", "dissipation_rate"):
        assert d[key] == pytest.approx(a[key] + b[key], rel=1e-12)
    natural = MPI.COMM_WORLD.bcast(system.unknowns.f["natural_curvature"].x.array[:6].copy())
    assert natural[3] == pytest.approx(0.3, abs=0.05) and abs(natural[0]) < 1e-12
    assert abs(a["tip_position_x"]) > 0.01


NATURAL = {"natural_curvature": {"a": (0.0, 0.4, 0.0), "b": (0.1, 0.0, 0.2)},
           "natural_stretch": {"a": (0.0, 0.0, 1.1)}}


@pytest.mark.mpi
@pytest.mark.parametrize("variant", ["local", "uniform"])
def test_rods_with_their_own_natural_strains_move_as_each_alone(variant):
    """Each rod its own initial natural strains (set_initial_state(natural_curvature=
    {rod: u_d}, ...); rod b's natural stretch left at its reference strains): two
    quasi-static evolving rods of different material, length and reference curvature in
    one system, started away from their natural state, relax each as it does alone with
    the same natural strains (backward Euler, 5 steps, Newton to 1e-13: measured
    1.9e-13 local, 2.2e-15 uniform; tolerance 1e-12 on tips ~1); the given strains matter (rod a's tip moves by more
    than 1e-2 from its run with the default ones)."""
    from dolfin_rod import RodModel, TimeStepper
    from rod_systems import ROUND_OFF
    pa = RodParameters(length=1.0, M_d=(5, 5, 5), N_d=(5, 5, 5))
    pb = RodParameters(length=0.7, A=(2, 1.5, 1), B=(3, 3, 4), M_d=(2, 2, 2), N_d=(2, 2, 2),
                       reference_curvature=(0.3, 0, 0))

    def run(model, **natural):
        model.set_initial_state(**natural)
        TimeStepper(model.problem, "backward_euler", solver_options=ROUND_OFF).run(0, 0.5, 0.1)
        return model.diagnostics(0.5)

    def own(rod):
        return {k: v[rod] for k, v in NATURAL.items() if rod in v}

    a = run(RodModel(pa, 6, variant=variant), **own("a"))
    b = run(RodModel(pb, 5, variant=variant), **own("b"))
    system = RodSystem([Rod(pa, 6, name="a"), Rod(pb, 5, name="b", position=POSITION_B)],
                       variant=variant)
    d = run(system, **NATURAL)
    assert np.allclose(vector(d, "a.tip_position"), vector(a, "tip_position"), rtol=0,
                       atol=1e-12)
    assert np.allclose(vector(d, "b.tip_position"), POSITION_B + vector(b, "tip_position"),
                       rtol=0, atol=1e-12)
    default = run(RodModel(pa, 6, variant=variant))
    assert np.linalg.norm(vector(a, "tip_position") - vector(default, "tip_position")) > 1e-2


def test_natural_strains_of_an_unknown_rod_are_refused():
    system = RodSystem([Rod(RodParameters(), 2, name="a"), Rod(RodParameters(), 2, name="b",
                                                              position=(1.0, 0.0, 0.0))])
    with pytest.raises(ValueError, match=r"natural_curvature\['c'\]: no rod of that name"):
        system.set_initial_state(natural_curvature={"c": (0.0, 0.0, 0.0)})
