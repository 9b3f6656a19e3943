"""The collocation schemes: Butcher tableaux, collocation instants and collocation polynomials.

:func:`tableau` computes the tableau of a scheme of :data:`SCHEMES` (Radau IIA, Gauss-Legendre)
from its nodes; :func:`instants` gives the collocation instants of the elements of a period,
:func:`locate` the element of any instant and the fraction of it, and :func:`dense` evaluates
the collocation polynomials between the element ends. The schemes are described in
:mod:`kedfem.solvers.collocation`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.polynomial import Polynomial
from numpy.polynomial import legendre as npleg

from ..errors import InputError

#: Collocation schemes: name -> (family, stages).
SCHEMES = {"radau2": ("radau", 2), "radau3": ("radau", 3), "gauss2": ("gauss", 2),
           "gauss3": ("gauss", 3)}


@dataclass(frozen=True)
class Tableau:
    """Butcher tableau of a collocation method.

    Attributes
    ----------
    name : str
    family : {"radau", "gauss"}
    c : ndarray, shape (s,)
        Collocation nodes as fractions of the element.
    A : ndarray, shape (s, s)
        ``A_ij = int_0^{c_i} l_j``, ``l_j`` the Lagrange basis on ``c``.
    b : ndarray, shape (s,)
        ``b_j = int_0^1 l_j``.
    order : int
        Classical order at the element ends (``2s - 1`` Radau IIA, ``2s`` Gauss).
    stage_order : int
        Order of the collocation polynomial between the ends (``s``).
    l_stable : bool
    """

    name: str
    family: str
    c: np.ndarray
    A: np.ndarray
    b: np.ndarray
    order: int
    stage_order: int
    l_stable: bool

    @property
    def s(self) -> int:
        """Number of stages."""
        return int(self.c.size)

    @property
    def A2(self) -> np.ndarray:
        """``A @ A``: the double integral of the stage accelerations."""
        return self.A @ self.A

    @property
    def bA(self) -> np.ndarray:
        """``b @ A``."""
        return self.b @ self.A


@lru_cache(maxsize=None)
def tableau(name: str) -> Tableau:
    """Tableau of a collocation scheme (see :data:`SCHEMES`), computed from its nodes.

    Gauss nodes are the zeros of the shifted Legendre polynomial ``P_s(2x-1)``;
    Radau IIA nodes the zeros of ``P_s(2x-1) - P_{s-1}(2x-1)`` (the last is 1).
    """
    if name not in SCHEMES:
        raise InputError(f"unknown collocation scheme {name!r}; valid: {', '.join(SCHEMES)}")
    family, s = SCHEMES[name]
    coef = np.zeros(s + 1)
    coef[s] = 1.0
    if family == "radau":
        coef[s - 1] = -1.0
    x = np.sort(npleg.legroots(coef).real)
    c = 0.5 * (x + 1.0)
    if family == "radau":
        c[-1] = 1.0
    A = np.empty((s, s))
    b = np.empty(s)
    for j in range(s):
        others = np.delete(c, j)
        lj = Polynomial.fromroots(others) / np.prod(c[j] - others)
        Lj = lj.integ()
        A[:, j] = Lj(c) - Lj(0.0)
        b[j] = Lj(1.0) - Lj(0.0)
    order = 2 * s - 1 if family == "radau" else 2 * s
    return Tableau(name, family, c, A, b, order, s, family == "radau")


def instants(name: str, n: int, period: float, edges=None) -> np.ndarray:
    """Collocation instants ``t_k + c_j h_k`` of ``n`` elements, shape (n, s) [s].

    ``edges`` (n + 1,) [s] gives non-uniform elements (default ``k T / n``).
    For Radau IIA the last instant of the last element is ``period`` itself.
    """
    tab = tableau(name)
    if edges is None:
        h = period / n
        return (np.arange(n)[:, None] + tab.c[None, :]) * h
    e = np.asarray(edges, dtype=float)
    return e[:-1, None] + tab.c[None, :] * np.diff(e)[:, None]


def dense(name: str, Z: np.ndarray, stages: np.ndarray, period: float, t, edges=None) -> np.ndarray:
    """Evaluate the collocation polynomials at instants ``t``.

    Parameters
    ----------
    name : str
        Scheme.
    Z : ndarray, shape (n, m)
        States at the element starts.
    stages : ndarray, shape (n, s, m)
        States at the collocation instants.
    period : float
        [s].
    t : array_like, shape (k,)
        Instants [s], taken modulo ``period``.
    edges : array_like, shape (n + 1,), optional
        Element edges [s] (default uniform).

    Returns
    -------
    ndarray, shape (k, m)
    """
    tab = tableau(name)
    k, theta = locate(t, Z.shape[0], period, edges)
    nodes = np.concatenate([[0.0], tab.c])
    # Lagrange weights on (0, c_1 .. c_s), shape (k, s + 1)
    diff = theta[:, None] - nodes[None, :]
    w = np.empty((theta.size, nodes.size))
    for j in range(nodes.size):
        others = np.delete(np.arange(nodes.size), j)
        w[:, j] = np.prod(diff[:, others], axis=1) / np.prod(nodes[j] - nodes[others])
    return w[:, :1] * Z[k] + np.einsum("ks,ksm->km", w[:, 1:], stages[k])


def locate(t, n: int, period: float, edges=None) -> tuple[np.ndarray, np.ndarray]:
    """Element (k,) of int and fraction in it (k,) of instants ``t`` [s] (taken modulo
    ``period``) on ``n`` elements, uniform or with ``edges`` (n + 1,) [s]."""
    tt = np.mod(np.asarray(t, dtype=float), period)
    if edges is None:
        x = tt * (n / period)
        k = np.minimum(np.floor(x).astype(int), n - 1)
        return k, x - k
    e = np.asarray(edges, dtype=float)
    k = np.clip(np.searchsorted(e, tt, side="right") - 1, 0, n - 1)
    return k, (tt - e[k]) / (e[k + 1] - e[k])
