"""What a fit reads: the measured time series (CSV), the parameters to fit (scene key
paths) and the scene rewritten for one trial parameter set with the measured load.

**Data (CSV).** A header row with the columns ``time``, ``load``, ``response`` (any
order, other columns ignored), then one row per sample: finite numbers, times strictly
increasing and >= 0.  What load and response mean depends on the scene (``Experiment``):

    torsion, end = "rotation" (relaxation)  load: end rotation Phi(t) (boundary.end_rotation)
                                             response: end torsion m(1, t) (reaction)
    torsion, free end (creep)               load: end torsion m(t) (loads.end_torsion)
                                             response: end rotation phi(1, t)
    3-D rod with loads.end_force            load: the force's magnitude along the scene's
                                             end_force direction e
                                             response: tip displacement (r(L,t) - r(L,0)).e
    3-D rod, boundary.end_displacement      load: the displacement along its direction e
                                             response: reaction force at s = L, along e
    3-D rod, boundary.end_rotation          load: the rotation angle about its axis e
                                             response: reaction couple at s = L, about e

The model is at rest for t < 0; the load is the CSV's column interpolated linearly
between rows (constant before the first row and after the last), so a load equal on
every row is a step at t = 0 (then the ODE model uses the closed forms).

**Parameters.** A parameter is a scene key path: tables and keys joined by ``.``, array
entries by ``[i]``: ``material.mu_d``, ``material.viscosity.M_d[2]`` (a diagonal
tensor ``[a, b, c]``: its third entry), ``material.stiffness.A[0][1]`` (a full 3x3
tensor: the entry and, symmetric, A[1][0]).  Short forms: a torsion coefficient alone
(``alpha``, ``alpha_d``, ``mu``, ``mu_d``, ``nu``) means ``material.<name>``; a rod
tensor entry alone (``M_d[2]``, ``A[0]``) means ``material.stiffness.<...>`` (A, B,
A_d, B_d) or ``material.viscosity.<...>`` (M, N, M_d, N_d).  Its value in the scene (or
the schema's default for a torsion coefficient not in the file) is the initial guess and
must be a number > 0: parameters are fitted as log p, so they stay positive.
"""

from __future__ import annotations

import csv
import io
import math
import re
import tomllib
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..checks import DATA_BYTES, read_regular_file
from ..scenes import Scene, validate
from ..scenes.physical import SOURCES

__all__ = ["FitInputError", "Parameter", "Experiment", "MeasuredSeries", "read_series",
           "parse_parameters", "experiment_of"]

COLUMNS = ("time", "load", "response")
TORSION_COEFFICIENTS = ("alpha", "alpha_d", "mu", "mu_d", "nu")
TENSORS = {"stiffness": ("A", "B", "A_d", "B_d"), "viscosity": ("M", "N", "M_d", "N_d")}
TORSION_DEFAULTS = {"alpha": 1.0, "alpha_d": 1.0, "mu": 0.0, "mu_d": 1.0, "nu": 0.0}


class FitInputError(ValueError):
    """Bad fit input (a parameter, the CSV, the scene's load): exit status 2."""


@dataclass(frozen=True)
class MeasuredSeries:
    """The CSV's columns as float arrays."""

    time: np.ndarray
    load: np.ndarray
    response: np.ndarray
    source: str = "<data>"


def read_series(path: str | Path) -> MeasuredSeries:
    """Read and check the CSV; FitInputError names the file, column and row (row 1 is
    the header, so the first sample is row 2).  The rows are parsed by numpy (1e6 rows in
    about a second); a file numpy cannot parse is read again row by row, to name the
    first bad entry."""
    path = Path(path)
    try:
        text = read_regular_file(path, DATA_BYTES).decode("utf-8-sig")
        header_line, _, body = text.partition("\n")
        rows = list(csv.reader(io.StringIO(header_line, newline="")))
    except (OSError, ValueError, csv.Error) as err:     # (UnicodeDecodeError: ValueError)
        raise _unreadable(path, err) from None
    if not rows:
        raise FitInputError(f"{path}: empty file (need a header {','.join(COLUMNS)})")
    header = [h.strip() for h in rows[0]]
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise FitInputError(f"{path}: missing column(s) {', '.join(missing)} (header: "
                            f"{','.join(header)}; need {','.join(COLUMNS)})")
    twice = [c for c in COLUMNS if header.count(c) > 1]
    if twice:
        raise FitInputError(f"{path}: column {twice[0]!r} appears {header.count(twice[0])} "
                            "times in the header: which one is meant?")
    index = [header.index(c) for c in COLUMNS]
    _check_row_lengths(path, body, len(header))
    try:
        with warnings.catch_warnings():          # no rows: check_series says so
            warnings.simplefilter("ignore", UserWarning)
            table = np.loadtxt(io.StringIO(body), delimiter=",", usecols=index, ndmin=2,
                               comments=None, quotechar='"', dtype=float)
    except ValueError:
        table = _rows_one_by_one(path, body, index)
    columns = dict(zip(COLUMNS, table.T))
    return check_series(MeasuredSeries(**columns, source=str(path)))


def _check_row_lengths(path: Path, body: str, width: int) -> None:
    """Every row has the header's number of values (numpy reads the named columns only:
    "0.5,1,1,000.5", a thousands separator, was read as response 1): FitInputError at the
    first row that has another.  The commas counted first (one pass in C); rows parsed
    one by one only where they do not add up (quoted commas, or such a row)."""
    commas, lines = body.count(","), body.count("\n") + (not body.endswith("\n"))
    if commas != (width - 1) * lines:      # blank lines, quoted commas or a row at fault
        lines -= sum(1 for line in body.splitlines() if not line.strip())
    if commas == (width - 1) * lines:
        return
    try:
        for k, row in enumerate(csv.reader(io.StringIO(body, newline=""))):
            if any(x.strip() for x in row) and len(row) != width:
                hint = ("a thousands separator or a decimal comma? (commas separate values)"
                        if len(row) > width else "a value is missing")
                raise FitInputError(f"{path}: row {k + 2} has {len(row)} values, the header "
                                    f"{width}: {hint}")
    except csv.Error as err:
        raise _unreadable(path, err) from None


def _unreadable(path: Path, err: Exception) -> FitInputError:
    return FitInputError(f"{path}: cannot read the data: "
                         f"{getattr(err, 'strerror', None) or err}")


def _rows_one_by_one(path: Path, body: str, index: list[int]) -> np.ndarray:
    """The rows numpy refused, parsed one by one: FitInputError at the first bad entry
    (or the table, should each row be readable after all)."""
    try:
        rows = list(csv.reader(io.StringIO(body, newline="")))
    except csv.Error as err:
        raise _unreadable(path, err) from None
    return np.array([[_number(path, r, i, c, k + 2) for i, c in zip(index, COLUMNS)]
                     for k, r in enumerate(rows) if any(x.strip() for x in r)],
                    float).reshape(-1, len(COLUMNS))


def _number(path, row: list[str], index: int, column: str, line: int) -> float:
    text = row[index].strip() if index < len(row) else ""
    try:
        x = float(text)
    except ValueError:
        raise FitInputError(f"{path}: row {line}, column {column}: not a number: "
                            f"{text!r}") from None
    if not math.isfinite(x):
        raise FitInputError(f"{path}: row {line}, column {column}: must be finite, got {text}")
    return x


def check_series(data: MeasuredSeries) -> MeasuredSeries:
    """Finite values, times >= 0 and strictly increasing, at least 2 samples."""
    where = data.source
    for c in COLUMNS:
        values = np.asarray(getattr(data, c), float)
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise FitInputError(f"{where}: row {bad[0] + 2}, column {c}: must be finite, "
                                f"got {values[bad[0]]}")
    t = np.asarray(data.time, float)
    if t.size < 2:
        raise FitInputError(f"{where}: need at least 2 rows of data, got {t.size}")
    if t[0] < 0.0:
        raise FitInputError(f"{where}: row 2, column time: must be >= 0 (the model starts "
                            f"from rest at t = 0), got {t[0]:g}")
    back = np.flatnonzero(np.diff(t) <= 0.0)
    if back.size:
        k = back[0] + 1
        raise FitInputError(f"{where}: row {k + 2}, column time: times must be strictly "
                            f"increasing, got {t[k]:g} after {t[k - 1]:g}")
    return data


# --- parameters: scene key paths -------------------------------------------------------

_INDEX = re.compile(r"\[(\d+)\]")
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*(\[\d+\])*$")


@dataclass(frozen=True)
class Parameter:
    """A fitted parameter: its name as given, the key path and array indices."""

    name: str
    keys: tuple[str, ...]
    indices: tuple[int, ...]
    initial: float

    @property
    def path(self) -> str:
        return ".".join(self.keys) + "".join(f"[{i}]" for i in self.indices)


def parse_parameters(names: list[str], scene: Scene, raw: dict) -> list[Parameter]:
    """Parameters of ``names`` in the scene (raw: its TOML dict); FitInputError names the
    first bad one (unknown, not a number, <= 0, given twice)."""
    if not names:
        raise FitInputError("--params: no parameter named (e.g. --params alpha_d,mu_d)")
    out = []
    for name in names:
        p = _parameter(name.strip(), scene, raw)
        if any(q.path == p.path for q in out):
            raise FitInputError(f"parameter {name!r}: given twice (as {p.path})")
        out.append(p)
    return out


def _parameter(name: str, scene: Scene, raw: dict) -> Parameter:
    if not _NAME.match(name):
        raise FitInputError(f"parameter {name!r}: not a key path like material.mu_d or "
                            "material.viscosity.M_d[2]")
    head = name.split("[", 1)[0]
    indices = tuple(int(i) for i in _INDEX.findall(name))
    keys = tuple(_long_form(head, scene).split("."))
    try:
        value = _value_at(raw, keys, indices, scene)
    except FitInputError as err:
        raise FitInputError(f"parameter {name!r}: {err}") from None
    if value is None and keys[-1] in (scene["material"].get("derived") or {}):
        source = f"material.{SOURCES.get(keys[-1], 'youngs_modulus')}"
        raise FitInputError(f"parameter {name!r}: {'.'.join(keys)} is derived from this "
                            f"scene's physical input ({source} with the [section]): fit "
                            f"{source} instead")
    if value is None:
        raise FitInputError(f"parameter {name!r}: {'.'.join(keys)} is not a key of this "
                            f"{'rod' if scene.is_rod_material else 'torsion'} scene "
                            f"(torsion: {', '.join(TORSION_COEFFICIENTS)}; rod: tensor "
                            "entries such as material.viscosity.M_d[2])")
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise FitInputError(f"parameter {name!r}: the scene's value is not a number "
                            f"(got {value!r}); name one entry, e.g. {name}[0]")
    if isinstance(value, int) and not _takes_reals(keys):
        raise FitInputError(f"parameter {name!r}: {'.'.join(keys)} is an integer (a count, "
                            "not a quantity): only real-valued keys can be fitted")
    if not value > 0.0:
        raise FitInputError(f"parameter {name!r}: its initial value must be > 0 (fitted as "
                            f"log p), got {value}")
    return Parameter(name, keys, indices, float(value))


def _takes_reals(keys: tuple[str, ...]) -> bool:
    """The schema accepts a non-integer value at this key (table.key; deeper keys are
    entries of tensors and histories, which are real)."""
    from ..scenes.schema import SCHEMA
    from ..scenes.values import BadValue
    key = SCHEMA.get(keys[0], {}).get(keys[1]) if len(keys) == 2 else None
    if key is None:
        return True
    try:
        key.check(1.5)
    except BadValue:
        return False
    return True


def _long_form(head: str, scene: Scene) -> str:
    if "." in head:
        return head
    if head in TORSION_COEFFICIENTS and not scene.is_rod_material:
        return f"material.{head}"
    for table, names in TENSORS.items():
        if head in names and scene.is_rod_material:
            return f"material.{table}.{head}"
    return head


def _value_at(raw: dict, keys: tuple[str, ...], indices: tuple[int, ...], scene: Scene):
    node = raw
    for k in keys:
        if not isinstance(node, dict) or k not in node:
            node = None
            break
        node = node[k]
    if node is None and len(keys) == 2 and keys[0] == "material" and not indices \
            and keys[1] in TORSION_DEFAULTS and not scene.is_rod_material:
        return TORSION_DEFAULTS[keys[1]]                 # the schema's default
    for depth, i in enumerate(indices):
        where = ".".join(keys) + "".join(f"[{j}]" for j in indices[:depth])
        if node is None or isinstance(node, dict):
            return None
        if not isinstance(node, list):
            raise FitInputError(f"{where} is a number in this scene, not an array: drop "
                                f"the index [{i}] (a diagonal tensor [a, b, c] takes one)")
        if i >= len(node):
            raise FitInputError(f"{where} has {len(node)} entries in this scene (indices "
                                f"0 to {len(node) - 1}), got [{i}]")
        node = node[i]
    return node


def set_parameter(raw: dict, p: Parameter, value: float) -> None:
    """Write ``value`` at p's path in the raw scene dict (both entries of an off-diagonal
    pair of a full 3x3 tensor)."""
    node = raw
    for k in p.keys[:-1]:
        node = node.setdefault(k, {})
    if not p.indices:
        node[p.keys[-1]] = value
        return
    node = node[p.keys[-1]]
    for i in p.indices[:-1]:
        node = node[i]
    node[p.indices[-1]] = value
    i, j = p.indices[-2:] if len(p.indices) >= 2 else (0, 0)
    if len(p.indices) == 2 and i != j and p.keys[1] in TENSORS:
        tensor = raw
        for k in p.keys:
            tensor = tensor[k]
        tensor[j][i] = value


# --- the experiment: which load the CSV drives and which response it measures ------------

# the rod experiments: scene key of the load -> (response, its diagnostics, what it is)
ROD_EXPERIMENTS = {
    "loads.end_force": ("tip_displacement", "tip_position_",
                        "load: end force along its direction e; response: tip displacement "
                        "along e"),
    "boundary.end_displacement": ("reaction_force", "reaction_force_end_",
                                  "load: end displacement along its direction e; response: "
                                  "reaction force at s = L along e"),
    "boundary.end_rotation": ("reaction_couple", "reaction_couple_end_",
                              "load: end rotation angle about its axis e; response: "
                              "reaction couple at s = L about e"),
}
TORSION_EXPERIMENTS = {
    "boundary.end_rotation": "load: end rotation Phi(t); response: end torsion",
    "loads.end_torsion": "load: end torsion m(t); response: end rotation phi(1)",
}
ROD_OTHER_LOADS = ("loads.end_couple", "loads.start_force", "loads.start_couple",
                   "loads.distributed_force", "loads.distributed_couple", "loads.gravity",
                   "boundary.start_displacement", "boundary.start_rotation")


@dataclass(frozen=True)
class Experiment:
    """The scene key the CSV's load drives and the response measured: a diagnostics key
    (torsion), or for a rod the prefix of x, y, z diagnostics projected on the unit
    vector ``direction`` of the scene's load (``from_rest``: minus the value at rest)."""

    load_key: str
    response: str
    description: str
    direction: tuple[float, float, float] | None = None
    from_rest: bool = False


def experiment_of(scene: Scene) -> Experiment:
    """The experiment a scene describes (see the module docstring)."""
    if not scene.is_rod_material:
        key = ("boundary.end_rotation" if scene["boundary"]["end"] == "rotation"
               else "loads.end_torsion")
        response = "end_torsion" if key == "boundary.end_rotation" else "end_rotation"
        return Experiment(key, response, TORSION_EXPERIMENTS[key])
    given = [k for k in (*ROD_EXPERIMENTS, *ROD_OTHER_LOADS) if _scene_value(scene, k)]
    key = given[0] if len(given) == 1 and given[0] in ROD_EXPERIMENTS else None
    spec = _scene_value(scene, key) if key else None
    if spec is None or spec.type == "table":
        raise FitInputError(f"{scene.source}: a rod fit needs exactly one of "
                            f"{', '.join(ROD_EXPERIMENTS)} (a step, ramp or constant with "
                            "value = [x, y, z], whose direction the CSV's load scales) and "
                            f"no other load or end motion (the scene has: "
                            f"{', '.join(given) or 'none'})")
    e = np.asarray(spec.value, float)
    if not np.linalg.norm(e) > 0.0:
        raise FitInputError(f"{scene.source}: [{key}]: value must be non-zero (it gives "
                            "the direction of the CSV's load)")
    name, prefix, description = ROD_EXPERIMENTS[key]
    return Experiment(key, prefix, description, tuple(e / np.linalg.norm(e)),
                      from_rest=name == "tip_displacement")


def _scene_value(scene: Scene, key: str):
    table, name = key.split(".")
    return scene[table][name]


def raw_scene(scene: Scene) -> dict:
    """The scene's TOML as a dict (the text as run, overrides included)."""
    if not scene.text:
        raise FitInputError(f"{scene.source}: the scene has no TOML text to rewrite (load "
                            "it with load_scene or parse_scene)")
    return tomllib.loads(scene.text)


def trial_scene(base: dict, scene: Scene, params: list[Parameter], values,
                experiment: Experiment, data: MeasuredSeries, dt: float) -> Scene:
    """The scene with the parameter values, the CSV's load and the time span of the data
    (t_end the last time, step dt), without the stability check; SceneError if a trial
    value breaks a scene rule."""
    import copy
    raw = copy.deepcopy(base)
    for p, v in zip(params, values):
        set_parameter(raw, p, float(v))
    table, key = experiment.load_key.split(".")
    raw.setdefault(table, {})[key] = _load_history(data, experiment)
    if experiment.load_key == "boundary.end_rotation" and experiment.direction is None:
        raw["boundary"]["end"] = "rotation"             # torsion: the end is turned
    raw["time"].update({"t_end": float(data.time[-1]), "dt": float(dt)})
    # no inertia count after every step: the fit reads only the response (issue 30)
    if scene.is_rod_material:
        raw["stability"] = {"check": False}
    out = validate(raw, scene.source, scene.name)
    out.text = scene.text
    return out


def _load_history(data: MeasuredSeries, experiment: Experiment) -> dict:
    """A step at t = 0 if the load is the same on every row, else a table of the rows
    where the piecewise-linear load has a kink (the same function: the ODE integrates
    between kinks only)."""
    e = np.asarray(experiment.direction if experiment.direction is not None else [1.0])
    scale = (lambda x: [float(x * c) for c in e]) if experiment.direction else float
    t, f = data.time, data.load
    if np.all(f == f[0]):
        return {"type": "step", "value": scale(f[0])}
    slopes = np.diff(f) / np.diff(t)
    bends = np.abs(np.diff(slopes)) > 1e-12 * np.abs(slopes).max()
    keep = np.concatenate(([True], bends, [True]))
    return {"type": "table", "times": [float(x) for x in t[keep]],
            "values": [scale(x) for x in f[keep]]}
