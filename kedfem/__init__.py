"""kedfem: finite-element Kineto-ElastoDynamics of planar elastic linkages."""

from .errors import (AccuracyWarning, ConvergenceWarning, CostWarning, EffectWarning, InputError, InstabilityWarning, KedError,
                     KinematicsError, LengthWarning, MobilityError, NonlinearSolveError, OptionalDependencyError, PlausibilityWarning, ResonanceError,
                     SingularMassError, UnboundedResponseError)
from .model.materials import Material, Section
from .model.mechanism import Mechanism
from .model.profiles import Profile
from .motion.kinematics import Cycle, Motion, kinematics, kinematics_at, static_motion
from .motion.stroke import Stroke, stroke
from .fe.model import FEModel
from .fe.effects import EFFECTS, ModalDamping, Rayleigh
from .motion.kinetostatics import kinetostatics
from .analysis.modal import ModalResult, global_matrices, natural_frequencies

__version__ = "0.1.0"
from .analysis.statics import StaticResult, static_response
from .analysis.scene import Scene
from .analysis.results import Frequencies, LinkPeaks, PeriodicResult, Stability
from .analysis.pipeline import solve
from .solvers.expm import expm
from .analysis.validation import ValidationReport, validate, table3
from .analysis.defaults import default_scene
from .io.scenefile import SceneFileError, load_scene, scene_family, scene_from_dict
from .fe.reduction import CraigBampton
from .analysis.mesh_check import MeshError, mesh_error
from .analysis.campbell import CampbellResult, Crossing, campbell
from .analysis.critical import CriticalSpeed, critical_speed
from .io.design_plots import StabilityMap, stability_map
from .analysis.continuation import Bifurcation, Branch, BranchPoint, continuation
from .io.branch_files import read as read_branch, write as write_branch

# the io wing's writers and readers, handed to the analysis wing (which never imports the io wing):
# res.write, res.summary, a Campbell result's files, critical_speed of a scene dictionary
from .analysis import hooks as _hooks  # noqa: E402
from .io import design_plots as _design_plots, report as _report, scenefile as _scenefile  # noqa: E402

def _late(module, name):
    """``module.name`` looked up at each call (a patched or reloaded io function takes effect)."""
    def call(*args, **kwargs):
        return getattr(module, name)(*args, **kwargs)
    call.__name__ = call.__qualname__ = name
    return call


_hooks.provide(write_result=_late(_report, "write_result"), format_summary=_late(_report, "format_summary"),
               campbell_csv=_late(_design_plots, "write_campbell_csv"),
               crossings_csv=_late(_design_plots, "write_crossings_csv"),
               campbell_chart=_late(_design_plots, "campbell_chart"),
               scene_from_dict=_late(_scenefile, "scene_from_dict"))
