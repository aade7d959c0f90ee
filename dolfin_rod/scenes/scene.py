"""A validated scene (:class:`Scene`) and the one error a bad scene raises
(:class:`SceneError`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

# the material keys that make a scene a 3-D rod scene (RodModel)
ROD_KEYS = ("stiffness", "viscosity", "density", "section_inertia", "drag", "youngs_modulus",
            "shear_modulus", "poisson_ratio", "natural_stiffness_ratio", "relaxation_time",
            "rotational_drag", "fluid_viscosity")


class SceneError(ValueError):
    """A scene cannot be used: ``source`` (file), ``key`` (dotted path) and ``reason``."""

    def __init__(self, source: str, key: str, reason: str):
        self.source, self.key, self.reason = str(source), key, reason
        where = f"[{key}]: " if key else ""
        super().__init__(f"{self.source}: {where}{reason}")

    def __reduce__(self):                  # pickled to other ranks (mpi.agree)
        return (type(self), (self.source, self.key, self.reason))


@dataclass
class Scene:
    """A validated scene: ``data[table][key]`` with defaults filled in."""

    data: dict[str, dict[str, Any]]
    source: str = "<string>"
    text: str = ""
    given: dict[str, set[str]] = field(default_factory=dict)  # keys the file set
    rods: list = field(default_factory=list)     # [[rods]]: systems.RodEntry (none: one rod)
    joints: list = field(default_factory=list)   # [[joints]]: systems.JointEntry
    joined: bool = False      # a rod of [[rods]] held by a joint (its supports may be free)
    in_system: bool = False   # a rod of [[rods]]: the continuation parameter is the system's
    files: str | None = None  # the folder of the files it names (None: its source's)

    def __getitem__(self, table: str) -> dict[str, Any]:
        return self.data[table]

    @property
    def name(self) -> str:
        return self.data["scene"]["name"]

    @property
    def is_rod_material(self) -> bool:
        return any(self.data["material"][k] is not None for k in ROD_KEYS) or \
            self.data["section"]["shape"] is not None

    @property
    def folder(self) -> Path | None:
        """The folder of the files the scene names (a mesh obstacle's file, an energy
        module): ``files`` (a run folder's scene.toml read again: its scene's folder,
        summary.json's scene_folder), else its source's folder (None: no file)."""
        if self.files is not None:
            return Path(self.files)
        return Path(self.source).parent if Path(self.source).is_file() else None

    def error(self, key: str, reason: str) -> SceneError:
        return SceneError(self.source, key, reason)

    def physics(self) -> dict[str, dict[str, Any]]:
        """The validated keys that determine the computed states, as plain JSON data
        (what a checkpoint must match to be resumed): everything but the name and
        description, the outputs table, t_end (a run may be extended) and the requested
        model (the chosen model is compared instead)."""
        physics = {table: _plain(keys) if isinstance(keys, list) else
                   {k: _plain(v) for k, v in keys.items()
                    if not (table == "time" and k == "t_end")}
                   for table, keys in self.data.items() if table not in ("scene", "outputs")}
        if self.rods:
            physics["rods"] = [{"name": r.name, "position": _plain(r.position),
                                "orientation": _plain(r.orientation),
                                **r.scene.physics()} for r in self.rods]
            physics["joints"] = [_plain(j) for j in self.joints]
        return physics


def _plain(v: Any) -> Any:
    """Validated values (dataclasses, tuples, floats) as JSON data (lists, dicts)."""
    if hasattr(v, "__dataclass_fields__"):
        return {f: _plain(getattr(v, f)) for f in v.__dataclass_fields__}
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, np.ndarray):
        return v.tolist()
    return v
