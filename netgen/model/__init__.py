"""The model stage: the MacroModel, the one data object between the physics and the emitters
(netgen.model.macromodel), its contact model (netgen.model.contact) and its figures
(netgen.model.plots)."""

from .inertial import Inertial
from .macromodel import ACCEL_PORT, FIT_FIX, PORT_UNITS, Coordinate, Electrode, MacroModel, finite

__all__ = ["ACCEL_PORT", "FIT_FIX", "PORT_UNITS", "Coordinate", "Electrode", "Inertial", "MacroModel", "finite"]
