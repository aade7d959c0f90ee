"""The 3-D special Cosserat rod (Sections 2-4): ``RodModel`` composed in model.py."""

from .boundary_conditions import END_TYPES
from .constitutive import MODELS
from .external_forces import DistributedLoad, EndLoad
from .material import RodParameters
from .model import RodModel
from .start import Arc, Helix, Polyline, StartingState, Straight

__all__ = ["RodModel", "RodParameters", "EndLoad", "DistributedLoad", "MODELS", "END_TYPES",
           "StartingState", "Straight", "Arc", "Helix", "Polyline"]
