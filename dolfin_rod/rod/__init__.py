"""The 3-D special Cosserat rod (Sections 2-4): ``RodModel`` composed in model.py;
several rods in one model: ``RodSystem`` (system.py)."""

from . import sections
from .boundary_conditions import END_TYPES, EndSpring
from .constitutive import MODELS
from .contact import ContactLaw, Obstacle
from .external_forces import DistributedLoad, EndLoad
from .material import RodParameters
from .model import RodModel
from .joints import Joint
from .rods import Rod
from .start import Arc, Helix, Polyline, StartingState, Straight
from .system import RodSystem

__all__ = ["RodModel", "RodSystem", "Rod", "Joint", "RodParameters", "EndLoad", "DistributedLoad",
           "EndSpring", "MODELS", "END_TYPES", "sections", "Obstacle", "ContactLaw",
           "StartingState", "Straight", "Arc", "Helix", "Polyline"]
