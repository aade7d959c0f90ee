"""Scenes: a TOML file describing one run (geometry, material, loads, boundary conditions,
time, outputs), validated into a :class:`Scene`, mapped to the least model that can run it.

    scene = load_scene("scenes/torsion_relaxation.toml")   # SceneError on any problem
    choice = select_model(scene)                             # Choice(model, reason)
    sim = build(scene, choice.model)                         # a models.Simulation
"""

from .builders import MODELS, Simulation, build, register_model
from .schema import SCHEMA, Scene, SceneError, load_scene, parse_scene, validate
from .selection import Choice, select_model

__all__ = ["MODELS", "SCHEMA", "Choice", "Scene", "SceneError", "Simulation", "build",
           "load_scene", "parse_scene", "register_model", "select_model", "validate"]
