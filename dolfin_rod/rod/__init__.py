"""The 3-D special Cosserat rod (Sections 2-4): ``RodModel`` composed in model.py."""

from . import sections
from .boundary_conditions import END_TYPES
from .constitutive import MODELS
from .external_forces import DistributedLoad, EndLoad
from .material import RodParameters
from .model import RodModel

__all__ = ["RodModel", "RodParameters", "EndLoad", "DistributedLoad", "MODELS", "END_TYPES",
           "sections"]
