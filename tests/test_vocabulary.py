"""One vocabulary (issue 29 item 1, docs/rod.md): the API's keywords are the scene's keys;
each old keyword still works for one release, with a DeprecationWarning naming the new
one, and gives the same model: the reference is the same model built with the new
names, whose runs must agree to the bit (the same numbers reach the same forms)."""

from __future__ import annotations

import csv
import dataclasses
import inspect
import shutil
import warnings

import numpy as np
import pytest
from PIL import Image

from dolfin_rod import (ContactLaw, EndLoad, EndSpring, Obstacle, Rod, RodModel,
                        RodParameters, RodSystem, TimeStepper, choose_integrator, loads, run,
                        sections)
from dolfin_rod.checks import END_KEYED, ENDS
from dolfin_rod.cli import main
from dolfin_rod.output.redraw import read_rows
from dolfin_rod.rod.contact import NP_OPS, Pose, signed_distance
from dolfin_rod.scenes.schema import SCHEMA
from quick_scenes import ROOT, quick_scene

STIFF = dict(A=(1.0, 1.0, 1.0), B=(100.0, 100.0, 100.0))


def _old(call, new_name: str):
    """call() under a DeprecationWarning that names ``new_name``; its result."""
    with pytest.warns(DeprecationWarning, match=new_name) as seen:
        result = call()
    assert all(w.filename == __file__ for w in seen if w.category is DeprecationWarning), \
        "the warning must point at the caller's line"
    return result


def _new(call):
    """call() without any DeprecationWarning; its result."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        return call()


def test_rod_parameters_take_the_scene_names():
    """density = rho_A; section_inertia = (I11, I22) (one number: both); the old fields
    read back the new ones."""
    assert _old(lambda: RodParameters(rho_A=2.5), "density") == \
        _new(lambda: RodParameters(density=2.5))
    assert _old(lambda: RodParameters(I11=0.01, I22=0.02), "section_inertia") == \
        _new(lambda: RodParameters(section_inertia=(0.01, 0.02)))
    assert _old(lambda: RodParameters(I11=0.03), "section_inertia").section_inertia == \
        (0.03, 0.0)
    assert _new(lambda: RodParameters(section_inertia=0.04)).section_inertia == (0.04, 0.04)
    params = RodParameters(density=3.0, section_inertia=(0.1, 0.2))
    assert (_old(lambda: params.rho_A, "density"), _old(lambda: params.I11, "section_inertia"),
            _old(lambda: params.I22, "section_inertia")) == (3.0, 0.1, 0.2)
    steel = sections.Material(youngs_modulus=2e11, poisson_ratio=0.3, density=7850.0)
    keys = _new(lambda: sections.section_parameters(sections.circle(0.01), steel))
    area, I = np.pi * 1e-4, np.pi * 1e-8 / 4          # a circle of radius 1 cm
    assert keys["density"] == pytest.approx(7850.0 * area, rel=1e-14)
    assert keys["section_inertia"] == pytest.approx((7850.0 * I, 7850.0 * I), rel=1e-14)


def test_old_and_new_names_together_or_unknown_are_refused():
    with pytest.raises(TypeError, match="density or the deprecated rho_A"):
        with pytest.warns(DeprecationWarning):
            RodParameters(rho_A=1.0, density=1.0)
    with pytest.raises(TypeError, match="start or the deprecated ends"):
        with pytest.warns(DeprecationWarning):
            RodModel(RodParameters(), 4, ends=("clamped", "free"), start="pinned")
    with pytest.raises(TypeError, match="unexpected keyword argument 'rho'"):
        RodParameters(rho=1.0)
    with pytest.raises(ValueError, match="section_inertia must be one value"):
        RodParameters(section_inertia=(1.0, 2.0, 3.0))


def test_rod_and_system_take_start_end_and_constraints():
    params = RodParameters(**STIFF)
    assert _old(lambda: Rod(params, 4, ends=("pinned", "clamped")), "start=") == \
        _new(lambda: Rod(params, 4, start="pinned", end="clamped"))
    assert _old(lambda: Rod(params, 4, ("pinned", "clamped")), "start=") == \
        _new(lambda: Rod(params, 4, "pinned", end="clamped"))      # ends by its position
    rod = Rod(params, 4, start="pinned", end="free")
    assert rod.ends == ("pinned", "free")
    by_position = _old(lambda: RodModel(params, 4, "hyperelastic", "local", None,
                                        ("clamped", "pinned")), "start=")
    assert by_position.rods[0] == Rod(params, 4, start="clamped", end="pinned")
    old = _old(lambda: RodSystem([Rod(params, 4)], constraint="unshearable"), "constraints")
    new = _new(lambda: RodSystem([Rod(params, 4)], constraints="unshearable"))
    assert old.problem.structure == new.problem.structure is not None


def _quasi_static(**names):
    model = RodModel(RodParameters(**STIFF), n_cells=4, model="hyperelastic",
                     end_loads=[EndLoad("couple", (0.0, 0.3, 0.0), loads.ramp(1.0, 1.0))],
                     **names)
    model.set_initial_state()
    return model


def _dynamic(**inertia):
    model = RodModel(RodParameters(**STIFF, **inertia), n_cells=4, model="hyperelastic",
                     end_loads=[EndLoad("force", (0.1, 0.0, 0.0), loads.ramp(1.0, 1.0))])
    model.set_initial_state()
    return model


def _same_state(a, b) -> None:
    """Every field of the two models equal to the bit, and the rod moved."""
    for name in a.f:
        assert np.array_equal(a.f[name].x.array, b.f[name].x.array), name
    assert np.abs(a.f["displacement"].x.array).max() > 1e-4     # well above round-off


def test_old_names_give_the_same_runs_to_the_bit():
    """A quasi-static clamped-pinned rod, unshearable (ends, constraint), stepped by
    TimeStepper(max_cuts); a dynamic one with rho_A, I11, I22 by choose_integrator
    (max_cuts): the same states as with the new names after 4 steps."""
    old = _old(lambda: _quasi_static(ends=("clamped", "pinned"), constraint="unshearable"),
               "start=|constraints")
    new = _new(lambda: _quasi_static(start="clamped", end="pinned",
                                     constraints="unshearable"))
    _old(lambda: TimeStepper(old.problem, "bdf2", max_cuts=3), "max_step_cuts").run(
        0.0, 0.2, 0.05)
    stepper = _new(lambda: TimeStepper(new.problem, "bdf2", max_step_cuts=3))
    stepper.run(0.0, 0.2, 0.05)
    assert stepper.max_cuts == 3
    _same_state(old, new)
    old = _old(lambda: _dynamic(rho_A=1.0, I11=0.01, I22=0.02), "density|section_inertia")
    new = _new(lambda: _dynamic(density=1.0, section_inertia=(0.01, 0.02)))
    _old(lambda: choose_integrator(old.problem, max_cuts=2), "max_step_cuts").run(
        0.0, 0.2, 0.05)
    _new(lambda: choose_integrator(new.problem, max_step_cuts=2)).run(0.0, 0.2, 0.05)
    _same_state(old, new)


# --- the ends: "start" and "end", as the scene's boundary.start_* / end_* keys -----------

# the API's end-keyed keywords and the scene's keys of one end (boundary.<end>_<part>)
SCENE_PART = {"end_displacement": "displacement", "end_rotation": "rotation",
              "end_slide": "slide", "end_springs": "spring", "end_turn": "turn"}


def test_api_end_names_and_keywords_are_the_scene_keys():
    """Fails if an API name and the scene key of the same thing differ: the API's ends
    (checks.ENDS) are the scene's boundary.start/end, each end-keyed keyword of RodModel
    and Rod has a scene key boundary.<end>_<part> for every end, and an end load's end is
    a loads.<end>_force/couple of the scene; the table of docs/rod.md names them."""
    assert ENDS == ("start", "end")
    assert set(ENDS) <= set(SCHEMA["boundary"])
    assert set(END_KEYED) == set(SCENE_PART)
    model_keywords = inspect.signature(RodModel.__init__).parameters
    rod_fields = {f.name for f in dataclasses.fields(Rod)}
    for keyword, part in SCENE_PART.items():
        assert keyword in model_keywords and keyword in rod_fields, keyword
        for end in ENDS:
            assert f"{end}_{part}" in SCHEMA["boundary"], (keyword, end)
    for end in ENDS:
        for kind in ("force", "couple"):
            assert f"{end}_{kind}" in SCHEMA["loads"]
    assert EndLoad("force", (1.0, 0.0, 0.0)).end == "end"     # as the scene's end_force
    docs = (ROOT / "docs/rod.md").read_text()
    for name in list(END_KEYED) + ["reaction_force_start_x", "reaction_couple_end_z"]:
        assert name in docs, name


def _end_names_model(names: dict, start: str, end: str) -> RodModel:
    """Pinned at s = 0 with a rotational spring, a clamp at s = L that slides and turns
    about e_3 while an end couple about e_2 and an axial force act on it: 4 cells,
    hyperelastic, quasi-static; every end-keyed keyword given with the names ``start``,
    ``end`` (the new or the deprecated ones)."""
    model = RodModel(RodParameters(**STIFF), n_cells=4, model="hyperelastic",
                     start="pinned", end="clamped",
                     end_loads=[EndLoad("force", (0.0, 0.0, 0.5), loads.ramp(1.0, 1.0),
                                        end=end),
                                EndLoad("couple", (0.0, 0.3, 0.0), loads.ramp(1.0, 1.0),
                                        end=end)],
                     end_slide={end: (0.0, 0.0, 1.0)}, end_turn={end: (0.0, 0.0, 1.0)},
                     end_springs={start: EndSpring(rotational=(50.0, 50.0, 50.0))},
                     rotations="rotation_vector", **names)
    model.set_initial_state()
    return model


def test_old_end_names_give_the_same_runs_to_the_bit():
    """"left" and "right" still work (EndLoad's end, the keys of end_slide, end_turn,
    end_springs, end_displacement, end_rotation) with a DeprecationWarning at the
    caller's line naming "start" or "end", and give the same model: the same states after
    4 steps.  A Rod takes them the same way."""
    old = _old(lambda: _end_names_model({}, "left", "right"), "'end'|'start'")
    new = _new(lambda: _end_names_model({}, "start", "end"))
    assert [load.end for load in old.rods[0].end_loads] == ["end", "end"]
    for key in END_KEYED:
        assert (getattr(old.rods[0], key) or {}).keys() == \
            (getattr(new.rods[0], key) or {}).keys(), key
    for model in (old, new):
        TimeStepper(model.problem, "bdf2").run(0.0, 0.2, 0.05)
    _same_state(old, new)
    d = new.diagnostics(0.2)
    assert {f"reaction_force_{end}_z" for end in ENDS} <= set(d)      # the columns' names
    assert abs(d["reaction_force_start_z"] + 0.1) < 1e-10     # the axial force at t = 0.2
    motion = {"start": lambda t: (0.0, 0.0, t)}
    rod = _old(lambda: Rod(RodParameters(**STIFF), 4, end_displacement={"left": motion[
        "start"]}, end_rotation={"right": motion["start"]}), "'start'|'end'")
    assert rod.end_displacement == motion and set(rod.end_rotation) == {"end"}
    assert _old(lambda: EndLoad("couple", (1.0, 0.0, 0.0), end="left"), "'start'") == \
        _new(lambda: EndLoad("couple", (1.0, 0.0, 0.0), end="start"))
    with pytest.raises(ValueError, match="EndLoad end must be 'start' .* got 'top'"):
        RodModel(RodParameters(), 4, end_loads=[EndLoad("force", (1.0, 0.0, 0.0), end="top")])
    with pytest.raises(ValueError, match="end_slide: unknown end 'top'"):
        RodModel(RodParameters(), 4, end="clamped", end_slide={"top": (0.0, 0.0, 1.0)})


# --- contact: [[obstacles]] and [contact] keys are Obstacle's and ContactLaw's fields -----


def test_obstacle_and_contact_law_take_the_scene_keys():
    """Fails if a key of [[obstacles]] or [contact] is not the field of the same name;
    a plane's normal and a sphere's or cylinder's centre were ``axis`` and ``point``
    (deprecated, with a warning naming the new key): the same signed distances (the
    closed forms of tests/test_contact.py) to the bit; ContactLaw's self_contact is
    self."""
    for table, api in (("obstacles", Obstacle), ("contact", ContactLaw)):
        fields = {f.name for f in dataclasses.fields(api)}
        assert set(SCHEMA[table]) <= fields, (table, set(SCHEMA[table]) - fields)
    p = np.array([[0.0, 0.0, 2.0], [3.0, 0.0, 0.0], [0.0, 0.5, 0.0], [3.0, 0.0, 4.0]])
    pairs = [(lambda: Obstacle("plane", point=(0.0, 0.0, 1.0), axis=(0.0, 0.0, 2.0)),
              lambda: Obstacle("plane", point=(0.0, 0.0, 1.0), normal=(0.0, 0.0, 2.0)),
              "normal", [1.0, -1.0, -1.0, 3.0]),
             (lambda: Obstacle("sphere", point=(0.0, 0.0, 0.0), radius=1.0),
              lambda: Obstacle("sphere", centre=(0.0, 0.0, 0.0), radius=1.0),
              "centre", [1.0, 2.0, -0.5, 4.0]),
             (lambda: Obstacle("cylinder", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 1.0, 2.0),
              lambda: Obstacle("cylinder", centre=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0),
                               radius=1.0, length=2.0),
              "centre", [1.0, 2.0, -0.5, np.sqrt(13.0)])]    # by position: the old order
    for old, new, name, distances in pairs:
        old, new = _old(old, name), _new(new)
        assert old == new
        assert np.array_equal(signed_distance(Pose(old), p, NP_OPS),
                              signed_distance(Pose(new), p, NP_OPS))
        assert signed_distance(Pose(new), p, NP_OPS) == pytest.approx(distances, abs=1e-15)
    with pytest.raises(TypeError, match="give centre or the deprecated point"):
        Obstacle("sphere", point=(0.0, 0.0, 0.0), centre=(0.0, 0.0, 0.0), radius=1.0)
    assert _old(lambda: ContactLaw(0.1, 0.01, 1.0, self_contact=True), "use self") == \
        _new(lambda: ContactLaw(0.1, 0.01, 1.0, self=True))
    with pytest.raises(TypeError, match="give self or the deprecated self_contact"):
        ContactLaw(0.1, 0.01, 1.0, self=True, self_contact=True)


# --- the reaction columns: written as reaction_*_start/end_*; old run folders read -------


def _old_release(folder, copy):
    """``folder`` copied to ``copy`` with the CSV's end columns named as before this
    release (reaction_force_start_x -> reaction_force_left_x, ...): an older run folder."""
    shutil.copytree(folder, copy)
    path = copy / "timeseries.csv"
    header, rest = path.read_text().split("\n", 1)
    old = header.replace("_start_", "_left_").replace("_end_", "_right_")
    assert "reaction_force_left_z" in old and "_start_" not in old
    path.write_text(old + "\n" + rest)


@pytest.fixture(scope="module")
def cantilever(tmp_path_factory):
    """The bundled gravity cantilever, 8 cells, 4 steps (a checkpoint after step 4), and
    the same folder as an older release wrote it."""
    base = tmp_path_factory.mktemp("vocabulary")
    scene = quick_scene(ROOT / "scenes/gravity_cantilever.toml", 4, geometry__n_cells=8,
                        outputs__checkpoint_every=4)
    result = run(scene, out=base / "new", quiet=True)
    _old_release(result.folder, base / "old")
    return result.folder, base / "old"


def _same_rows(a: list[dict], b: list[dict]) -> None:
    """The same columns in the same order, the same values to the bit (NaN as NaN)."""
    assert [list(r) for r in a] == [list(r) for r in b]
    assert np.array_equal([list(r.values()) for r in a], [list(r.values()) for r in b],
                          equal_nan=True)


def _pixels(path):
    return np.asarray(Image.open(path).convert("RGB"))


def test_an_old_run_folder_is_redrawn_under_the_new_names(cantilever, capsys):
    """`dolfin-rod plot OLD` reads reaction_force_left_* as reaction_force_start_*: the
    same rows as the new folder's and the same histories.png to the pixel; an old column
    named on the command line is drawn (the same picture as the new name's) with a
    warning naming the new one, also when the new one is then refused (no such column)."""
    new, old = cantilever
    _same_rows(read_rows(old), read_rows(new))
    for folder in (new, old):
        assert main(["plot", str(folder), "--to", str(folder / "again.png")]) == 0
    assert np.array_equal(_pixels(new / "again.png"), _pixels(old / "again.png"))
    capsys.readouterr()
    assert main(["plot", str(old), "reaction_force_left_z", "--to", str(old / "z.png")]) == 0
    err = capsys.readouterr().err
    assert "warning: quantity 'reaction_force_left_z' is deprecated" in err
    assert "use 'reaction_force_start_z'" in err
    assert main(["plot", str(new), "reaction_force_start_z", "--to", str(new / "z.png")]) == 0
    assert np.array_equal(_pixels(new / "z.png"), _pixels(old / "z.png"))
    assert main(["plot", str(old), "reaction_couple_right_y"]) == 2   # a free end: none
    err = capsys.readouterr().err              # the warning too, before the error naming
    assert "use 'reaction_couple_end_y'" in err and "reaction_couple_end_y is neither" in err


def test_an_old_run_folder_resumes_under_the_new_names(cantilever, tmp_path):
    """--resume of an older release's folder: the kept rows' values under the new column
    names (to the bit), the later rows' reactions written (none empty)."""
    old = tmp_path / "old"
    shutil.copytree(cantilever[1], old)
    before = read_rows(old)
    scene = quick_scene(ROOT / "scenes/gravity_cantilever.toml", 6, geometry__n_cells=8,
                        outputs__checkpoint_every=4)
    run(scene, out=old, resume=True, quiet=True)
    with (old / "timeseries.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 7 and "reaction_force_start_z" in rows[0]
    assert not any("_left_" in c or "_right_" in c for c in rows[0])
    assert all(r[f"reaction_force_start_{c}"] != "" for r in rows for c in "xyz")
    _same_rows(read_rows(old)[:5], before)
