"""Which link buckles: the mode of the most negative stiffness eigenvalue over the cycle, and the
link that carries most of it (named by a buckling critical speed and a Campbell diagram whose
bands reach below 0 Hz, where a new user read the crossings of a buckled band as resonances)."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..fe.assembler import Assembler
from ..fe.effects import linear_effects
from ..fe.model import FEModel
from ..motion.kinematics import kinematics
from .modal import eig_frequencies

__all__ = ["BuckledMode", "buckled_mode", "link_shares"]


@dataclass(frozen=True)
class BuckledMode:
    """The lowest mode where its stiffness eigenvalue is most negative over the cycle.

    Attributes
    ----------
    crank_angle : float
        Crank angle of that instant [rad] (absolute, as :attr:`PeriodicResult.crank_angle`).
    frequency : float
        Its signed frequency ``-sqrt(-lambda) / 2 pi`` [Hz] (negative).
    link : str
        The link with the largest share of the mode's kinetic energy ``phi_i (M phi)_i``.
    share : float
        That share [-], in ``(0, 1]``.
    """

    crank_angle: float
    frequency: float
    link: str
    share: float

    def describe(self) -> str:
        """One phrase: the link, its share, where in the cycle."""
        return (f"link '{self.link}' buckles ({self.share:.0%} of the mode, {self.frequency:.4g} Hz at absolute crank "
                f"angle {math.degrees(self.crank_angle) % 360.0:.1f} deg)")


def link_shares(model: FEModel, M: np.ndarray, phi: np.ndarray) -> dict[str, float]:
    """Share of a mass-normalised mode's kinetic energy per link, from the DOF labels.

    Parameters
    ----------
    model : FEModel
    M : ndarray, shape (N, N)
        Mass matrix [kg, kg m^2].
    phi : ndarray, shape (N,)
        Mode shape.

    Returns
    -------
    dict of str -> float
        Link name -> share [-] (the DOFs of a joint in the frame of a link, ``"A.u[crank]"``, count
        for that link; global joint DOFs for none).
    """
    e = phi * (M @ phi)
    total = float(np.sum(e))
    out: dict[str, float] = {}
    links = model.mech.links
    for label, ei in zip(model.dof_labels, e):
        name = label[label.index("[") + 1:label.index("]")] if "[" in label else label.split(".")[0]
        if name in links:
            out[name] = out.get(name, 0.0) + float(ei) / total
    return out


def buckled_mode(mechanism, effects, steps: int = 36, model: FEModel | None = None) -> BuckledMode | None:
    """The lowest mode at the instant of ``steps`` over the cycle where its stiffness eigenvalue is
    most negative, and the link that carries most of it (None: no negative eigenvalue).

    Parameters
    ----------
    mechanism : Mechanism
        At the speed in question.
    effects : sequence of str
        The scene's effects; the stiffness takes their linear part
        (:func:`kedfem.fe.effects.linear_effects`).
    steps : int
        Crank positions over the cycle.
    model : FEModel, optional
        The mechanism's model, where one is built already (a solve's).
    """
    model = FEModel(mechanism) if model is None else model
    motion = kinematics(mechanism, steps=steps)
    terms = Assembler(model, motion, linear_effects(effects), damping=None, frame=True).system()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        f, phi = eig_frequencies(terms.M, terms.K, 1, shapes=True, name=mechanism.name,
                                 labels=model.dof_labels)
    i = int(np.argmin(f[:, 0]))
    if not f[i, 0] < 0:
        return None
    shares = link_shares(model, np.asarray(terms.M[i]), np.asarray(phi[i, :, 0]))
    if not shares:
        return None
    link = max(shares, key=shares.get)
    return BuckledMode(float(motion.crank_angle[i]), float(f[i, 0]), link, min(float(shares[link]), 1.0))
