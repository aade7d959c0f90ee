"""One rod of a model: its data (material, cells, ends, loads, place in space) and the
checks of a list of them (RodModel: one rod; system.RodSystem: several)."""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..checks import (END_KEYED, N_CELLS, check_n_cells, deprecated_names, end_keyed,
                      old_keywords)
from .boundary_conditions import check_supports
from .external_forces import DistributedLoad, EndLoad, PointLoad, check_loads
from .material import RodParameters, check_parameters, is_zero
from .start import shape_problem

NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*$")


@dataclass
class Rod:
    """A rod of a system: its parameters (length, material, reference strains), cells,
    ends and their motions, loads (end loads at its own "start" s = 0 and "end" s = L;
    distributed loads, point loads and coefficients as functions of its own arc
    length), and where it starts: ``position`` of its start and ``orientation``, the rotation
    vector (axis times angle) that turns e_3 into its initial tangent and e_1, e_2 into
    its initial directors d_1, d_2 there."""

    params: RodParameters
    n_cells: int = N_CELLS
    start: str = "clamped"               # the support at s = 0 (a scene's boundary.start);
                                         # (start, end) here: the deprecated ends
    end_loads: Sequence[EndLoad] = ()
    distributed_loads: Sequence[DistributedLoad] = ()
    end_displacement: dict | None = None
    end_rotation: dict | None = None
    end_slide: dict | None = None
    position: Sequence[float] = (0.0, 0.0, 0.0)
    orientation: Sequence[float] = (0.0, 0.0, 0.0)
    name: str = "rod"
    end_springs: dict | None = None      # {end: EndSpring} (boundary_conditions.py)
    end_turn: dict | None = None         # {end: axis}: a clamped end turning freely
    end: str = "free"                    # the support at s = L: clamped | pinned | free
    point_loads: Sequence[PointLoad] = ()   # at points s of its own arc length
    closed: bool = False                 # a ring: its end welded to its start (ring.py)
    excess_link: float = 0.0             # a ring's turns of twist beyond its natural twist

    def __post_init__(self):
        self.end_loads, self.distributed_loads = list(self.end_loads), list(self.distributed_loads)
        self.point_loads = list(self.point_loads)
        self.start, self.end = positional_ends("Rod", self.start, self.end, stacklevel=6)
        for key, value in end_keyed("Rod", {key: getattr(self, key) for key in END_KEYED},
                                    stacklevel=4).items():    # "left", "right": deprecated
            setattr(self, key, value)

    @property
    def ends(self) -> tuple[str, str]:
        """The supports (start, end) of both ends, in the order of checks.ENDS."""
        return self.start, self.end

    @property
    def placed(self) -> bool:
        """Moved away from the origin along e_3 (position or orientation given)."""
        return bool(np.any(np.asarray(self.position, float))
                    or np.any(np.asarray(self.orientation, float)))


# keywords before they took the scene's names (deprecated, docs/rod.md "One vocabulary")
OLD_ENDS = {"ends": "start=..., end=..."}
OLD_CONSTRAINT = {"constraint": "constraints"}


def new_keywords(old: dict) -> dict:
    """The keywords of the deprecated ends=(start, end) and constraint."""
    new = {"constraints": old["constraint"]} if "constraint" in old else {}
    if "ends" in old:
        new["start"], new["end"] = old["ends"]
    return new


def positional_ends(owner: str, start, end, stacklevel: int) -> tuple:
    """(start, end); a pair in start's place is the deprecated ends=(start, end) given
    by position (the place ``ends`` had), with its DeprecationWarning."""
    if isinstance(start, (tuple, list)) and len(start) == 2:
        deprecated_names(owner, {"ends": start}, OLD_ENDS, stacklevel)
        return tuple(start)
    return start, end


Rod.__init__ = old_keywords("Rod", OLD_ENDS, new_keywords)(Rod.__init__)


def check_rods(rods: list[Rod], model: str, variant: str) -> None:
    """Each rod's own rules; across rods: one kind of dynamics, one energy, names unique.
    A ValueError names the rod (``rods[k] 'name'``) when there are several."""
    if not rods:
        raise ValueError("rods: a model needs at least one rod")
    several = len(rods) > 1
    for k, rod in enumerate(rods):
        try:
            _check_rod(rod, model, variant)
        except ValueError as err:
            raise ValueError(f"rods[{k}] {rod.name!r}: {err}" if several else str(err)) from err
    if not several:
        return
    names = [rod.name for rod in rods]
    for k, name in enumerate(names):
        if not (isinstance(name, str) and NAME.match(name)):
            raise ValueError(f"rods[{k}].name must be letters, digits, '_', '-' (not first), "
                             f"got {name!r}")
        if names.index(name) != k:
            raise ValueError(f"rods[{k}].name {name!r} is used twice: names must be unique")
    dynamic = [not is_zero(rod.params.density) for rod in rods]
    if any(dynamic) and not all(dynamic):
        k = dynamic.index(not dynamic[0])
        raise ValueError(f"rods[{k}].params.density: every rod of a system is dynamic "
                         "(density > 0) or every rod quasi-static (density = 0)")
    if any(rod.params.energy is not rods[0].params.energy for rod in rods):
        raise ValueError("rods[k].params.energy: the rods of a system share one energy "
                         "function (its parameters may differ per rod through A, B, ...)")


def _check_rod(rod: Rod, model: str, variant: str) -> None:
    check_n_cells(rod.n_cells)
    check_supports(rod.ends, rod.end_displacement, rod.end_rotation,
                   not is_zero(rod.params.density), rod.end_slide, rod.end_springs,
                   rod.end_turn)
    check_parameters(rod.params, model == "evolving", model != "hyperelastic", variant)
    _check_reference_shape(rod.params)
    check_loads(rod.end_loads, rod.distributed_loads, rod.point_loads, rod.params.length)
    for name in ("position", "orientation"):
        value = np.asarray(getattr(rod, name), dtype=float)
        if value.shape != (3,) or not np.all(np.isfinite(value)):
            raise ValueError(f"{name} must be a finite 3-vector, got {getattr(rod, name)!r}")


def _check_reference_shape(params: RodParameters) -> None:
    """A stress-free curve (rod/start.py) that fits the rod, given instead of the
    reference strains: a ValueError naming ``reference_shape``."""
    if params.reference_shape is None:
        return
    if np.any(np.asarray(params.reference_curvature, float)) or \
            not np.array_equal(np.asarray(params.reference_stretch, float), (0.0, 0.0, 1.0)):
        raise ValueError("reference_shape: the stress-free shape is a curve or the helix of "
                         "reference_curvature/reference_stretch, not both")
    problem = shape_problem(params.reference_shape, params.length)
    if problem:
        raise ValueError(f"reference_shape{problem[0]}: {problem[1]}")
