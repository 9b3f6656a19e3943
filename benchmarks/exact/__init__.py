"""Geometrically exact reference model for flexible planar linkages (benchmark code, not kedfem).

Planar ANCF cable elements (Gerstmayr & Shabana), rigid bodies, joints as
Lagrange-multiplier constraints, generalised-alpha (Arnold & Bruls 2007)
index-3 integration cycle after cycle to the periodic steady state.

Independent of kedfem's formulation: it reads a ``kedfem.Mechanism`` for the
data and uses ``kedfem.motion.kinematics`` only for the rigid-body state at t = 0.
"""

from .ancf import ElementSet, gauss01, hermite, mass_matrix
from .model import Builder, Model, State, from_mechanism
from .integrator import GeneralizedAlpha, NewtonFailure
from .simulate import ExactResult, initial_state, simulate
from .analysis import beam, modal, static, rotating_modal, EB_ROOTS

__all__ = ["ElementSet", "gauss01", "hermite", "mass_matrix", "Builder", "Model", "State", "from_mechanism",
           "GeneralizedAlpha", "NewtonFailure", "ExactResult", "initial_state", "simulate", "beam", "modal",
           "static", "rotating_modal", "EB_ROOTS"]
