"""A scene that starts where a previous run left off: ``[initial] from_run = "<run
folder>"`` (and ``from_time``, default the last saved state).

The state is a checkpoint of that run (checkpoints.py: written with
``outputs.final_checkpoint`` or ``checkpoint_every``; ``keep_checkpoints`` keeps every
one for ``from_time``).  :func:`previous_state` picks it and checks it before any model is
built (rank 0 reads, every rank raises the same SceneError naming initial.from_run): the
folder, its scene.toml and checkpoint exist and are intact, and the previous scene has
this scene's discretisation and model (:func:`structure`: the model, the rods and their
names, their joints, geometry, material model and variant, constraints, rotation
unknowns, inertia: a rigid joint keeps the angle its rods have at the placement, and a
joint's node links snap a state whose rods were not joined there).
:func:`start_from` reads it into the built model (any number of ranks, either way):
the unknowns (positions, rotations, velocities, natural strains, a uniform model's
global unknowns), the stored rotations of rotation vectors and the integrator's rates;
with the same integrator and dt also the rest of its history (multistep values,
generalized-alpha's accelerations) if ``continue_integration`` asks for it, so that the
two runs are the one run whose loads change after the state's time, to round-off;
otherwise the integrator starts as at any run's start (a multistep scheme's startup
step, generalized-alpha's consistent accelerations with the new loads).  Time starts at
0 again: the new scene's loads, supports and outputs are its own, its ends start where
the state has them.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from ..scenes.scene import Scene, SceneError
from .checkpoints import (content_problem, differences, global_size, integrity_problem,
                          read_functions)
from .run_folders import scene_folder

KEY = "initial.from_run"


@dataclass(frozen=True)
class PreviousState:
    """The checkpoint a run starts from: its folder, its meta.json, the run folder."""

    folder: Path
    meta: dict
    run: Path
    t_end: float | None = None     # the previous scene's, if the state was not picked

    @property
    def unfinished(self) -> str | None:
        """Why the state is not the previous run's end state (its last saved one, taken
        by default, lies before its t_end: the run was interrupted, stopped or failed, or
        saved no state at its end), None if it is or ``from_time`` picked it."""
        if self.t_end is None or self.meta["time"] >= self.t_end * (1 - 1e-12):
            return None
        return (f"the last state {self.run} saved, at t = {self.meta['time']:g}, is not its "
                f"end state (t_end = {self.t_end:g}: the run was interrupted, stopped or "
                "failed, or saved no state at its end, outputs.final_checkpoint); "
                "initial.from_time picks a state without this warning")

    def summary(self, continued: bool) -> dict:
        """summary.json's ``from_run`` entry."""
        return {"folder": str(self.run), "time": self.meta["time"],
                "step": self.meta["step"], "continued": continued}


def structure(scene: Scene, model: str) -> dict:
    """What a saved state must share with the scene that starts from it: the model, and
    for the FE models the discretisation and the kind of unknowns (JSON data)."""
    def geometry(entry: Scene) -> dict:     # the rotations chosen are compared instead
        return {k: v for k, v in entry.physics()["geometry"].items() if k != "rotations"}

    def rod(entry: Scene) -> dict:
        mat = entry["material"]
        return {"geometry": geometry(entry),
                "material.model": mat["model"], "material.variant": mat["variant"],
                "material.constraints": mat["constraints"],
                "inertia": bool(mat["dynamic"])}
    if model != "rod":
        mat = scene["material"]
        return {"model": model, "geometry": geometry(scene),
                "material.variant": mat["variant"], "inertia": mat["nu"].constant != 0.0
                if mat["nu"].is_constant else True}
    from ..scenes.rules import rod_rotations
    data = {"model": model, "rotations": rod_rotations(scene)}
    if not scene.rods:
        return {**data, **rod(scene)}
    rods = {r.name: {**rod(r.scene), "position": r.position, "orientation": r.orientation}
            for r in scene.rods}
    joints = {f"joints[{k}]": {"kind": j.kind, "rods": list(j.rods), "point": j.point,
                               "axis": j.axis} for k, j in enumerate(scene.joints)}
    data |= {"rods": list(rods), **{f"rods.{name}": value for name, value in rods.items()},
             **joints}
    return json.loads(json.dumps(data, default=list))


def previous_state(scene: Scene, model: str, comm,
                   missing_ok: bool = False) -> PreviousState | None:
    """Collective: the checkpoint ``[initial] from_run`` names (None without it, or if
    ``missing_ok`` and no such folder exists yet: ``dolfin-rod check`` of a second
    stage), checked against ``scene`` run by ``model`` (module docstring); reads only."""
    ini = scene["initial"]
    if ini["from_run"] is None:
        return None
    run = Path(ini["from_run"])
    if missing_ok and not comm.bcast(run.exists() if comm.rank == 0 else None, root=0):
        return None
    try:
        folder, meta, t_end = _on_root(comm, lambda: _saved_state(scene, model, run,
                                                                  ini["from_time"]))
    except StateProblem as err:
        raise scene.error(err.key, err.reason) from None
    return PreviousState(folder, meta, run, t_end if ini["from_time"] is None else None)


def check_out(scene: Scene, previous: PreviousState | None, out: Path | None) -> None:
    """Refuse an ``--out`` folder that is the previous run's or holds it: preparing it
    (--overwrite) would delete the saved state the run starts from."""
    if previous is None or out is None:
        return
    run, folder = previous.run.resolve(), Path(out).resolve()
    if run == folder or folder in run.parents:
        raise scene.error(KEY, f"{previous.run} is inside --out {out}, which this run "
                               "replaces: write the new run to another folder")


def _on_root(comm, read):
    """``read()`` on rank 0, its result on every rank; its StateProblem raised on every
    rank."""
    result, problem = None, None
    if comm.rank == 0:
        try:
            result = read()
        except StateProblem as err:
            problem = (err.key, err.reason)
    result, problem = comm.bcast((result, problem), root=0)
    if problem is not None:
        raise StateProblem(*problem)
    return result


class StateProblem(ValueError):
    """Why a run folder's saved state cannot be used: ``key`` the scene key it is about."""

    def __init__(self, key: str, reason: str):
        self.key, self.reason = key, reason
        super().__init__(reason)


def _checkpoint(run: Path, at: float | None) -> tuple[Path, dict]:
    """Rank 0: the checkpoint folder of ``run`` at time ``at`` (None: the last) and its
    meta.json, intact (checksums, content); StateProblem otherwise."""
    def problem(reason: str) -> StateProblem:
        return StateProblem(KEY, f"{run}: {reason}")
    if not (run / "scene.toml").is_file():
        raise problem("not a run folder (no such folder)" if not run.is_dir() else
                      "not a run folder of dolfin-rod (it has no scene.toml)")
    root = run / "checkpoint"
    saved = sorted(p for p in root.glob("step-*") if p.suffix != ".partial"
                   and (p / "meta.json").is_file()) if root.is_dir() else []
    if not saved:
        raise problem("the run saved no state (run its scene with outputs.final_checkpoint "
                      "= true, or checkpoint_every > 0)")
    metas = []
    for folder in saved:
        try:
            meta = json.loads((folder / "meta.json").read_bytes())
        except (OSError, ValueError) as err:
            raise problem(f"{folder.name}/meta.json cannot be read ({err})") from None
        metas.append((folder, meta))
    if at is None:
        folder, meta = metas[-1]
    else:
        times = [m.get("time") for _, m in metas]
        near = [k for k, t in enumerate(times) if isinstance(t, (int, float))
                and math.isclose(t, at, rel_tol=1e-9, abs_tol=1e-12)]
        if not near:
            listed = ", ".join(f"{t:g}" for t in times if isinstance(t, (int, float)))
            raise StateProblem("initial.from_time", (
                f"{run} saved no state at t = {at:g} (it has t = {listed}; "
                "outputs.keep_checkpoints = true keeps every checkpoint)"))
        folder, meta = metas[near[0]]
    broken = integrity_problem(folder, meta) or content_problem(meta)
    if broken:
        raise problem(f"its checkpoint {folder.name} cannot be used: {broken}")
    return folder, meta


def _saved_state(scene: Scene, model: str, run: Path, at: float | None):
    """Rank 0: (checkpoint folder, meta, its scene's t_end) of ``run`` at time ``at``
    (None: the last),
    checked against ``scene`` run by ``model``; StateProblem naming the key otherwise
    (previous_state raises it on every rank as a SceneError)."""
    from ..scenes import parse_scene
    folder, meta = _checkpoint(run, at)
    try:
        theirs = parse_scene((run / "scene.toml").read_text(), str(run / "scene.toml"),
                             files=scene_folder(run))
    except (OSError, SceneError) as err:
        raise StateProblem(KEY, f"{run}: its scene.toml is not a valid scene ({err})") from None
    diffs = differences(structure(theirs, meta["model"]), structure(scene, model))
    if diffs:
        path, a, b = diffs[0]
        hint = (f": set geometry.rotations = {a!r}, 'auto' chooses by the supports and "
                "loads" if path == "rotations" else "")
        raise StateProblem(KEY, f"{run}: it has another {path} ({_shown(a)} there, "
                                f"{_shown(b)} here{hint}); a state starts only a scene of "
                                "the same rods, joints, discretisation and model")
    units = (theirs["scene"]["units"], scene["scene"]["units"])
    if None not in units and units[0] != units[1]:
        raise StateProblem(KEY, f"{run}: its numbers are in {units[0]}, this scene's in "
                                f"{units[1]} (scene.units): a state is read as it was "
                                "saved, so a scene starting from it keeps its units")
    dt = (meta.get("integrator") or {}).get("dt")
    if scene["initial"]["continue_integration"] and dt != scene["time"]["dt"]:
        raise StateProblem("initial.continue_integration", (
            f"{run} was integrated with time.dt = {_shown(dt)}, this scene has "
            f"{scene['time']['dt']:g}: a continued integration keeps the step"))
    return folder, meta, theirs["time"]["t_end"]


def _shown(value) -> str:
    return "none" if value is None else repr(value)


def start_from(sim, previous: PreviousState, scene: Scene) -> bool:
    """Collective: the built and started ``sim`` put in the saved state (module
    docstring); whether its integrator continues the previous run's history
    (initial.continue_integration).  A state whose unknowns do not fit the model
    (another layout) or an integrator that cannot continue is a SceneError."""
    meta = previous.meta
    continues = scene["initial"]["continue_integration"]
    method = (meta.get("integrator") or {}).get("method")
    if continues and method != sim.describe():
        raise scene.error("initial.continue_integration", (
            f"{previous.run} was integrated by {_shown(method)}, this scene by "
            f"{sim.describe()!r}: only the same integrator and scheme continue"))
    named = model_functions(sim.model)
    if continues:     # the integrator's history besides the rates
        named |= sim.stepper.checkpoint_state()["functions"]
    try:
        _read(previous.folder, meta, named, previous.run)
    except StateProblem as err:
        raise scene.error(err.key, err.reason) from None
    _check_overlaps(sim.model, previous, scene)
    sim.restart(meta["sim"] if continues else None)
    sim.model.problem.start_loaded = True   # an equilibrium with the run's loads
    return continues


def _check_overlaps(model, previous: PreviousState, scene: Scene) -> None:
    """Collective: a SceneError naming the obstacle (or contact key) that the state read
    cuts into (a scene adding an obstacle where the saved rod lies: its start diverged,
    blamed on the loads, its row 0 inside the obstacle)."""
    from ..rod.obstacle_shapes import InitialOverlap
    from ..rod.segments import PairOverlap
    check = getattr(model, "check_overlaps", None)
    if check is None:
        return
    try:
        check()
    except InitialOverlap as err:
        raise scene.error(f"obstacles[{err.obstacle}]", f"the state of {previous.run} at t = "
                          f"{previous.meta['time']:g} cuts into it: {err}") from None
    except PairOverlap as err:
        raise scene.error(err.key, f"the state of {previous.run} at t = "
                          f"{previous.meta['time']:g}: {err}") from None


def model_functions(model) -> dict:
    """A model's state by checkpoint name: its unknowns (``field_i``), its own functions
    (rotation vectors' stored rotations) and their rates (``rate_i``, the integrators'
    name for them)."""
    problem = model.problem
    return ({f"field_{i}": f for i, f in enumerate(problem.fields)}
            | getattr(model, "checkpoint_state", dict)().get("functions", {})
            | {f"rate_{i}": r for i, r in enumerate(problem.rates)})


def _read(folder: Path, meta: dict, named: dict, run: Path) -> None:
    """Collective: ``named`` from the checkpoint, after its sizes were compared (a state
    of another layout is a StateProblem)."""
    sizes = meta["fingerprint"].get("dofs", {})
    for name, f in named.items():
        if sizes.get(name) != global_size(f):
            raise StateProblem(KEY, f"{run}: its state has {sizes.get(name)} values of "
                                    f"{name}, this model {global_size(f)}")
    read_functions(folder, meta, named)


def load_state(model, run: str | Path, time: float | None = None) -> float:
    """Collective: a model built in Python (RodModel, RodSystem, TorsionModel, after its
    ``set_initial_state``) put in the state the run in folder ``run`` saved at ``time``
    (default its last; module docstring): its unknowns, stored rotations and rates; a
    rod's ends held there (``hold_ends``).  An integrator made after this starts from
    it, as a scene's ``[initial] from_run`` does; returns the saved state's time.  A
    folder without such a state, or a state of another layout, is a ValueError (no
    check of the scene: the model is the caller's)."""
    run = Path(run)
    try:
        folder, meta = _on_root(model.problem.comm, lambda: _checkpoint(run, time))
        _read(folder, meta, model_functions(model), run)
    except StateProblem as err:
        raise ValueError(err.reason) from None
    if hasattr(model, "hold_ends"):
        model.hold_ends()
    model.problem.start_loaded = True       # an equilibrium with the run's loads
    return float(meta["time"])
