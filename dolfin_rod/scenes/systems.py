"""Scenes of several rods: ``[[rods]]`` and ``[[joints]]`` (rod/system.py, docs/systems.md).

    [[rods]]
    name = "column"                      # unique; prefixes the rod's output columns
    position = [0.0, 0.0, 0.0]           # where its s = 0 end starts
    orientation = [0.0, 0.0, 0.0]        # rotation vector turning e_3 into its tangent
    geometry = { length = 1.0, n_cells = 8 }          # per-rod tables: any key of
    boundary = { start = "clamped", end = "free" }    # [geometry], [section],
    loads = { end_force = { type = "step", value = [0, 0, -1] } }  # [material],
                                                      # [boundary], [loads],
    initial = { angular_velocity = [0, 1, 0] }       # [initial]: its starting state
    [[joints]]
    kind = "rigid"                       # rigid | ball | hinge
    rods = ["column", "beam"]
    point = [0.0, 0.0, 1.0]              # a node of both rods at t = 0
    name = "knee"                        # optional; names its reaction columns
    axis = [0.0, 1.0, 0.0]               # a hinge's axis (unit, at t = 0); hinges only

Each rod is the scene's own tables with the rod's tables laid over them key by key, and
is validated as a scene of its own (an error names ``rods[k].<table>.<key>``); the keys
every rod shares (``SHARED``) are given in the scene's tables only.  A rod's starting
state (its ``initial`` keys: rod/start.RodStarts) is in its placed frame.  A joint's point is
checked against the rods' nodes before any model is built.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from .scene import Scene, SceneError
from .values import BadValue, choice, run_name, string, type_name, vector3

ROD_TABLES = ("geometry", "section", "material", "boundary", "loads", "initial")
ROD_KEYS = ("name", "position", "orientation") + ROD_TABLES
SHARED = {("geometry", "rotations"): "the rotation unknowns",
          ("material", "model"): "the constitutive model",
          ("material", "variant"): "the evolution variant",
          ("material", "constraints"): "the constraint",
          ("material", "energy"): "the energy function",
          ("initial", "from_run"): "the run whose saved state starts the scene",
          ("initial", "from_time"): "the time of the saved state",
          ("initial", "continue_integration"): "continuing the saved time integration"}
JOINT_KEYS = ("kind", "rods", "point", "name", "axis")


@dataclass
class RodEntry:
    """One rod of a scene: its name, place and its scene (the tables laid over)."""

    name: str
    position: tuple
    orientation: tuple
    scene: Scene


@dataclass
class JointEntry:
    kind: str
    rods: tuple[str, str]
    point: tuple
    name: str
    axis: tuple | None = None


def validate_system(raw: dict, source: str, default_name: str,
                    validate_one: Callable[[Any, str, str, bool], Scene]) -> Scene:
    """A scene with ``[[rods]]``: the first rod's scene, carrying every rod (``rods``) and
    the joints (``joints``)."""
    entries, joints = raw.pop("rods"), raw.pop("joints", [])
    for key, value in (("rods", entries), ("joints", joints)):
        if not (isinstance(value, list) and all(isinstance(v, dict) for v in value)):
            raise SceneError(source, key, f"must be an array of tables ([[{key}]]), got "
                                          f"{type_name(value)}")
    if not entries:
        raise SceneError(source, "rods", "needs at least one [[rods]] table")
    names = [entry.get("name", f"rod{k}") for k, entry in enumerate(entries)]
    for k, name in enumerate(names):
        if names.index(name) != k:
            raise SceneError(source, f"rods[{k}].name", f"{name!r} is used twice: rod names "
                                                        "are unique")
    joint_entries = [_joint(entry, k, source, names) for k, entry in enumerate(joints)]
    joined = {name for joint in joint_entries for name in joint.rods}
    rods = [_rod(raw, entry, k, source, default_name, validate_one, names[k] in joined)
            for k, entry in enumerate(entries)]
    scene = copy.copy(rods[0].scene)
    scene.rods, scene.joints = rods, joint_entries
    _check_continuation(scene)
    _check_joint_points(scene)
    _check_rotation_held(scene)
    _check_equilibrium_held(scene)
    return scene


def _check_equilibrium_held(scene: Scene) -> None:
    """A system started in static equilibrium (initial.equilibrium) is held somewhere, as
    the model's static problem needs (rod/initial_state.supported); a rod held by joints
    only needs no support of its own (rules: each unjoined rod is checked alone)."""
    from ..checks import EQUILIBRIUM_NEEDS
    from .rules import held_at_rest
    settled = any(r.scene["initial"]["equilibrium"] for r in scene.rods)
    if settled and not any(held_at_rest(r.scene) for r in scene.rods):
        raise scene.error("initial.equilibrium", EQUILIBRIUM_NEEDS)


def shadowing_rod(raw: dict, table: str, key: str) -> str | None:
    """The first key of a [[rods]] table in ``raw`` that gives its own ``table.key`` (a
    rod's section with a shape: every section key), over which the scene's value of it
    is not used; None if no rod does."""
    rods = raw.get("rods")
    if table not in ROD_TABLES or not isinstance(rods, list):
        return None
    for k, entry in enumerate(rods):
        own = entry.get(table) if isinstance(entry, dict) else None
        if isinstance(own, dict) and (key in own or (table == "section" and "shape" in own)):
            return f"rods[{k}].{table}" + (f".{key}" if key in own else "")
    return None


def _check_rotation_held(scene: Scene) -> None:
    """A quasi-static system with joints holds a rotation somewhere, as the model needs
    (rod/model.py: joints take rotation-vector unknowns, whose quasi-static rod needs an
    end holding its rotation, a pinned-pinned rod's spin or a welded body's,
    checks.spin_free, welded_spin_end): else run refused it after check said OK."""
    from types import SimpleNamespace

    from ..checks import spin_free, welded_spin_end
    from .rules import rotation_obstacle
    if not scene.joints:
        return
    for k, entry in enumerate(scene.rods):       # what else keeps rotation vectors out
        why, key = rotation_obstacle(entry.scene)
        if why:
            own = key.split(".")[1] in entry.scene.given.get("material", {}) and k > 0
            raise SceneError(scene.source, f"rods[{k}].{key}" if own else key,
                             f"joints need rotation-vector unknowns, which rod "
                             f"{entry.name!r} cannot have: {why}")
    if scene["material"]["dynamic"]:
        return
    rods = []
    for entry in scene.rods:
        bnd = entry.scene["boundary"]
        given = [{end: bnd[f"{end}_{key}"] for end in ("start", "end") if bnd[f"{end}_{key}"]}
                 for key in ("rotation", "turn", "spring")]
        springs = [np.broadcast_to(spring.get("rotational", 0.0), 3)
                   for spring in given[2].values()]
        rods.append(SimpleNamespace(ends=(bnd["start"], bnd["end"]), end_rotation=given[0],
                                    end_turn=given[1], end_springs=given[2],
                                    held="clamped" in (bnd["start"], bnd["end"]) or bool(
                                        given[0]) or spin_free((bnd["start"], bnd["end"]),
                                                               *given)
                                    or any(np.all(k) for k in springs)))
    if any(rod.held for rod in rods) or welded_spin_end(
            rods, [joint.kind for joint in scene.joints]) is not None:
        return
    raise SceneError(scene.source, "rods[0].boundary.start", "a quasi-static system with "
                     "joints needs a rotation held somewhere: a clamped end, an end "
                     "rotation or rotational spring, a rod pinned at both ends, or rods "
                     "welded by rigid joints pinned at two ends (its joints' rotation-"
                     "vector unknowns have a free rotation otherwise)")


def _check_continuation(scene: Scene) -> None:
    """The continuation parameter names a load or end motion of any rod (the rods'
    own checks leave it to the system: Lee's frame loads its beam only)."""
    from .rules import check_continuation_parameter, continuation_loads
    loads = sorted({load for rod in scene.rods for load in continuation_loads(rod.scene)})
    check_continuation_parameter(scene, loads)


def _rod(raw: dict, entry: dict, k: int, source: str, default_name: str,
         validate_one, joined: bool) -> RodEntry:
    where = f"rods[{k}]"
    for key in entry:
        if key not in ROD_KEYS:
            raise SceneError(source, f"{where}.{key}",
                             f"unknown key (known in [[rods]]: {', '.join(ROD_KEYS)})")
    merged = copy.deepcopy(raw)
    for table in ROD_TABLES:
        own = entry.get(table, {})
        if not isinstance(own, dict):
            raise SceneError(source, f"{where}.{table}", f"must be a table, got "
                                                         f"{type_name(own)}")
        for key in own:
            if (table, key) in SHARED:
                raise SceneError(source, f"{where}.{table}.{key}",
                                 f"{SHARED[table, key]} is shared by every rod: give it in "
                                 f"[{table}]")
        if table == "section" and "shape" in own:
            merged[table] = dict(own)       # a shape of its own: the scene's dimensions go
        elif own:
            merged.setdefault(table, {}).update(own)
    try:
        scene = validate_one(merged, source, default_name, joined)
    except SceneError as err:
        own = entry.get(err.key.partition(".")[0], {})
        given = err.key.partition(".")[2].partition(".")[0] in own
        raise SceneError(source, f"{where}.{err.key}" if given else err.key,
                         err.reason if given else f"(rod {k}) {err.reason}") from None
    if not scene.is_rod_material:
        raise SceneError(source, f"{where}.material", "a rod of [[rods]] needs a 3-D rod "
                                                       "material (stiffness, or a section)")
    try:
        name = run_name(entry.get("name", f"rod{k}"))
        position, orientation = (vector3()(entry.get(key, [0.0, 0.0, 0.0]))
                                 for key in ("position", "orientation"))
    except BadValue as bad:
        raise SceneError(source, where, bad.reason) from None
    return RodEntry(name, position, orientation, scene)


def _joint(entry: dict, k: int, source: str, names: list[str]) -> JointEntry:
    where = f"joints[{k}]"
    for key in entry:
        if key not in JOINT_KEYS:
            raise SceneError(source, f"{where}.{key}",
                             f"unknown key (known in [[joints]]: {', '.join(JOINT_KEYS)})")
    for key in ("kind", "rods", "point"):
        if key not in entry:
            raise SceneError(source, f"{where}.{key}", "missing required key")
    from ..rod.joint_points import KINDS
    try:
        kind = choice(*KINDS)(entry["kind"])
    except BadValue as bad:
        raise SceneError(source, f"{where}.kind", bad.reason) from None
    rods = entry["rods"]
    if not (isinstance(rods, list) and len(rods) == 2 and all(r in names for r in rods)
            and rods[0] != rods[1]):
        raise SceneError(source, f"{where}.rods", f"must name two different rods of "
                                                  f"{names}, got {rods!r}")
    try:
        point = vector3()(entry["point"])
        name = string(entry.get("name", ""))
    except BadValue as bad:
        raise SceneError(source, f"{where}.point", bad.reason) from None
    axis = _joint_axis(entry, kind, where, source)
    return JointEntry(kind, tuple(rods), point, name, axis)


def _joint_axis(entry: dict, kind: str, where: str, source: str) -> tuple | None:
    """A hinge's axis (rod.joint_points.axis_problem), none for the other kinds."""
    from ..rod.joint_points import Joint, axis_problem
    axis = entry.get("axis")
    if axis is not None:
        try:
            axis = vector3()(axis)
        except BadValue as bad:
            raise SceneError(source, f"{where}.axis", bad.reason) from None
    problem = axis_problem(Joint(kind, ("", ""), (0.0, 0.0, 0.0), axis=axis))
    if problem:
        raise SceneError(source, f"{where}.axis", problem)
    return axis


def _check_joint_points(scene: Scene) -> None:
    """Every joint at a node of both its rods (rod.joint_points.locate) and the rods'
    starting states meeting there (check_joints_at_start), before any model: the rods
    as placed there (builders.placed_rods: no DOLFINx), split at their corners as the
    model splits them (rod/kinks.py)."""
    from ..rod.joint_points import check_joints_at_start, locate
    from ..rod.kinks import attach, split_placed, system_starts
    from ..rod.ring import closed_starts
    from .builders import placed_rods, rod_starts, scene_joints
    if not scene.joints:
        return
    placed = placed_rods(scene)
    splits = [split_placed(rod) for rod in placed]                # the model's pieces
    rods = [piece for split in splits for piece in split.rods]
    joints = attach(scene_joints(scene), splits)
    try:
        locate(rods, joints)
    except ValueError as err:
        key = str(err).partition(" ")[0].rstrip(":")
        raise SceneError(scene.source, key, str(err).partition(" ")[2]) from None
    try:
        check_joints_at_start(rods, joints, system_starts(
            closed_starts(placed, rod_starts(scene)) or {}, splits))
    except ValueError as err:
        raise SceneError(scene.source, "initial", str(err)) from None
