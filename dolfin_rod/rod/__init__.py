"""The 3-D special Cosserat rod (Sections 2-4): ``RodModel`` composed in model.py;
several rods in one model: ``RodSystem`` (system.py).  Names load on first use, so that
the pure-Python parts (sections.py, rotation_choice.py) stay cheap to import."""

from importlib import import_module

_WHERE = {"RodModel": "model", "RodSystem": "system", "Rod": "rods", "Joint": "joint_points",
          "RodParameters": "material", "EndLoad": "external_forces",
          "DistributedLoad": "external_forces", "PointLoad": "external_forces",
          "TravellingWave": "external_forces", "EndSpring": "boundary_conditions",
          "MODELS": "constitutive", "END_TYPES": "boundary_conditions",
          "Obstacle": "contact", "ContactLaw": "contact", "StartingState": "start",
          "Straight": "start", "Arc": "start", "Helix": "start", "Polyline": "start"}

__all__ = [*_WHERE, "sections"]


def __getattr__(name: str):
    if name == "sections":
        return import_module(".sections", __name__)
    if name in _WHERE:
        return getattr(import_module(f".{_WHERE[name]}", __name__), name)
    raise AttributeError(f"module 'dolfin_rod.rod' has no attribute {name!r}")
