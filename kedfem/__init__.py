"""kedfem: finite-element Kineto-ElastoDynamics of planar elastic linkages."""

from .errors import (AccuracyWarning, ConvergenceWarning, InputError, InstabilityWarning, KedError,
                     KinematicsError, MobilityError, OptionalDependencyError, ResonanceError,
                     SingularMassError, UnboundedResponseError)
from .materials import Material, Section
from .mechanism import Mechanism
from .kinematics import Cycle, Motion, kinematics, kinematics_at, static_motion
from .assembly import FEModel
from .effects import EFFECTS, ModalDamping, Rayleigh
from .kinetostatics import kinetostatics
from .modal import ModalResult, global_matrices, natural_frequencies

__version__ = "0.1.0"
from .statics import StaticResult, static_response
from .scene import Scene
from .results import Frequencies, LinkPeaks, PeriodicResult, Stability
from .pipeline import solve
from . import periodic, nonlinear
from .expm import expm
from .validation import ValidationReport, validate, table3
from .defaults import default_scene
from .scenefile import SceneFileError, load_scene, scene_from_dict
from .reduction import CraigBampton
from .mesh_check import MeshError, mesh_error
