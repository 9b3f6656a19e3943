"""Time discretisations of the periodic solve: one contract, a registry by name.

In the style of ``scipy.integrate.solve_ivp``'s methods: every scheme says
where in the cycle it needs the equations' data (:meth:`Scheme.instants`),
solves the linear periodic problem from the data sampled there
(:meth:`Scheme.solve`), and returns a :class:`Discrete` solution that can be
read at any instant (dense output) and at its own instants (for the
state-dependent terms of a non-linear iteration). The pipeline
(:func:`kedfem.solve`) chooses a scheme by name from :data:`SCHEMES`; the
name ``"auto"`` resolves to :data:`AUTO`.

============= ========================================== ===== ======= =========
name          what                                       order between L-stable
============= ========================================== ===== ======= =========
``radau3``    Radau IIA collocation, 3 stages            5     4       yes
``radau2``    Radau IIA collocation, 2 stages            3     3       yes
``gauss3``    Gauss-Legendre collocation, 3 stages       6     4       no
``gauss2``    Gauss-Legendre collocation, 2 stages       4     3       no
``magnus2``   exponential, midpoint data (the paper's    2     2       exact
              method, second order)
``foh``       exponential, first-order-hold load         2*    2       exact
``zoh``       exponential, zero-order hold (the paper)   1     1       exact
``fourier``   trigonometric collocation, whole cycle     spectral      no
============= ========================================== ===== ======= =========

(* first order when the state matrix varies.) "Order" is the order at the
element ends, "between" that of the values read between them. The
exponential holds integrate each element exactly for frozen data; on closed
loops of flexible links they need thousands of elements (the held axial
stiffness of a link that turns relative to a joint's frame pushes on the
bending DOFs), while collocation evaluates the equations at the true data of
each instant (see ``docs/solver.md``).
"""

from __future__ import annotations

import abc
import dataclasses
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from . import collocation
from . import periodic
from ..errors import InputError

__all__ = ["Scheme", "Discrete", "SCHEMES", "AUTO", "get", "names"]

#: The scheme ``"auto"`` stands for (chosen by the accuracy-versus-cost study:
#: converges on every shipped mechanism, closed loops of flexible links included).
AUTO = "radau3"


@dataclass(frozen=True)
class Discrete:
    """One discretised periodic solution, scheme-neutral.

    Attributes
    ----------
    scheme : str
    n : int
        Number of time elements.
    period : float
        [s].
    U, V : ndarray, shape (n, N)
        Displacements and velocities at the element starts ``k T / n``.
    floquet_multipliers : ndarray of complex, shape (2N,)
        Of the discrete monodromy matrix.
    stable : bool
    residual : float
    method : str
        ``"condensation"`` or ``"cyclic-lu"``.
    raw : object
        The scheme's own solution object.
    """

    scheme: str
    n: int
    period: float
    U: np.ndarray
    V: np.ndarray
    floquet_multipliers: np.ndarray
    stable: bool
    residual: float
    method: str
    raw: Any
    _at: Callable = None
    _instant_states: Callable = None
    _velocities: Callable | None = None
    #: other loads on the same system (:class:`kedfem.solvers.collocation.Resolver`), when the
    #: solve was asked to keep its factorisations; None otherwise
    resolver: Any = field(default=None, repr=False, compare=False)
    #: made by a chord step (:meth:`kedfem.analysis.problem.PeriodicProblem.step`): the correction
    #: of a frozen tangent, whose multipliers are that tangent's
    chord: bool = False

    @property
    def spectral_radius(self) -> float:
        """Largest Floquet multiplier modulus."""
        mu = self.floquet_multipliers
        return float(np.abs(mu).max()) if mu.size else 0.0

    def at(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Displacements and velocities at instants ``t`` [s], each (k, N)."""
        return self._at(np.asarray(t, dtype=float))

    def velocities(self, t) -> np.ndarray:
        """Velocities (k, N) at instants ``t`` (k,) [s] (the second half of :meth:`at`, alone where
        the scheme reads it alone)."""
        t = np.asarray(t, dtype=float)
        if self._velocities is not None:
            return self._velocities(t)
        return self._at(t)[1]

    def instant_states(self) -> tuple[np.ndarray, np.ndarray]:
        """Displacements and velocities at the scheme's instants, each (n_i, N)."""
        return self._instant_states()


def with_state_terms(C, K, Q, dC, dK, dQ):
    """``C + dC``, ``K + dK``, ``Q + dQ`` (each term may be None)."""
    return (C if dC is None else C + dC, K if dK is None else K + dK, Q if dQ is None else Q + dQ)


class Scheme(abc.ABC):
    """Contract of a time discretisation (see the module docstring).

    Attributes
    ----------
    name : str
    order : int
        Convergence order at the element ends.
    dense_order : int
        Convergence order of values read between element ends.
    stages : int
        Data instants per element.
    l_stable : bool
        Damps modes the elements do not resolve.
    min_elements : int
    """

    name: str = ""
    order: int = 1
    dense_order: int = 1
    stages: int = 1
    l_stable: bool = False
    min_elements: int = periodic.MIN_NODES

    #: accepts non-uniform element edges (graded time elements)
    graded: bool = False
    #: elements (or nodes) per period of the highest mode a level must resolve
    per_period: float = 1.0

    def refine(self, n: int) -> int:
        """Time elements of the next finer level (about twice ``n``)."""
        return 2 * n

    @abc.abstractmethod
    def instants(self, n: int, period: float, edges=None) -> np.ndarray:
        """Instants (n * stages,) [s] where ``M, C, K, Q`` are needed, element by element.

        ``edges`` (n + 1,) [s]: non-uniform elements (schemes with :attr:`graded`).
        """

    @abc.abstractmethod
    def solve(self, M, C, K, Q, period: float, n: int, *, dC=None, dK=None, dQ=None,
              edges=None, **options) -> Discrete:
        """Periodic solution from data sampled at :meth:`instants`.

        Parameters
        ----------
        M, C, K : ndarray, shape (n_i, N, N) or (N, N), or callable
        Q : ndarray, shape (n_i, N), or callable
        period : float
            [s].
        n : int
            Number of time elements.
        dC, dK, dQ : ndarray, optional
            Linearised state-dependent terms at the same instants (tangent
            damping and stiffness, and the matching load).
        edges : ndarray, shape (n + 1,), optional
            Element edges [s] (schemes with :attr:`graded`).
        **options
            ``delta``, ``memory_budget``, ... of the underlying solver.
        """

    def check_elements(self, n: int) -> int:
        """Validate a number of time elements."""
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < self.min_elements:
            raise InputError(f"{self.name}: the number of time elements must be an integer >= "
                             f"{self.min_elements}, got {n!r}")
        return int(n)

    def __repr__(self):
        return f"<scheme {self.name}: order {self.order}, {self.stages} instant(s) per element>"


class ExponentialHold(Scheme):
    """The paper's state-space method: matrix exponentials of held data per element."""

    stages = 1
    l_stable = False

    def __init__(self, hold: str):
        self.name = hold
        self.hold = hold
        self.order = 1 if hold == "zoh" else 2
        self.dense_order = self.order

    def instants(self, n, period, edges=None):
        if edges is not None:
            raise InputError(f"{self.name}: the exponential holds take equal time elements only")
        return np.arange(n) * (period / n)

    def solve(self, M, C, K, Q, period, n, *, dC=None, dK=None, dQ=None, edges=None, stiff=None,
              **options):
        """As :meth:`Scheme.solve`; ``stiff`` (N,) bool: DOFs the exact stiff split
        (:mod:`kedfem.solvers.split`) carries as static response plus deviation (None: no split)."""
        if edges is not None:
            raise InputError(f"{self.name}: the exponential holds take equal time elements only")
        sp = None
        if stiff is not None and np.any(stiff) and not callable(K) and not callable(M) \
                and np.ndim(K) == 3 and np.ndim(M) == 3:
            from .split import build
            sp = build(np.asarray(M, float), np.asarray(K, float), period, stiff)
        if sp is not None:
            C = np.broadcast_to(C, K.shape)
            M, C, K, Q = sp.reduce(M, C, K, Q)
            dC, dK, dQ = sp.reduce_linearised(dC, dK, dQ)
        if self.hold == "zoh" or (dK is None and dC is None and dQ is None):
            C, K, Q = with_state_terms(C, K, Q, dC, dK, dQ)
            sol = periodic.solve(M, C, K, Q, period, hold=self.hold, n=n, **options)
        else:
            # a linearisation about node k held over element k: it cancels at the
            # node (see periodic.solve's Kz, Cz, Qz)
            sol = periodic.solve(M, C, K, Q, period, hold=self.hold, n=n, Kz=dK, Cz=dC, Qz=dQ,
                                 **options)
        U, V = (sol.U, sol.V) if sp is None else sp.recover(sol.U, sol.V)

        def at(t):
            return hermite(U, V, period, t)

        return Discrete(self.name, n, period, U, V, sol.floquet_multipliers, bool(sol.stable),
                        float(sol.residual), sol.method, sol, at, lambda: (U, V))


def hermite(U, V, period, t):
    """Cubic Hermite interpolation of nodal displacements and velocities, periodic.

    Parameters
    ----------
    U, V : ndarray, shape (n, N)
        At ``k T / n``.
    period : float
    t : ndarray, shape (k,)

    Returns
    -------
    U, V : ndarray, shape (k, N)
    """
    n = U.shape[0]
    h = period / n
    x = np.mod(np.asarray(t, dtype=float), period) / h
    k = np.minimum(np.floor(x).astype(int), n - 1)
    s = (x - k)[:, None]
    k1 = (k + 1) % n
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    u = h00 * U[k] + h10 * h * V[k] + h01 * U[k1] + h11 * h * V[k1]
    d00, d10, d01, d11 = 6 * s**2 - 6 * s, 3 * s**2 - 4 * s + 1, -6 * s**2 + 6 * s, 3 * s**2 - 2 * s
    v = (d00 * U[k] + d01 * U[k1]) / h + d10 * V[k] + d11 * V[k1]
    return u, v


class Collocation(Scheme):
    """Radau IIA or Gauss-Legendre collocation elements (:mod:`kedfem.solvers.collocation`)."""

    graded = True

    def __init__(self, name: str):
        tab = collocation.tableau(name)
        self.name = name
        self.tableau = tab
        self.order = tab.order
        self.dense_order = tab.stage_order + 1
        self.stages = tab.s
        self.l_stable = tab.l_stable

    def instants(self, n, period, edges=None):
        return collocation.instants(self.name, n, period, edges).ravel()

    def solve(self, M, C, K, Q, period, n, *, dC=None, dK=None, dQ=None, edges=None, stiff=None,
              **options):
        options.pop("delta", None)  # no exponentials
        C, K, Q = with_state_terms(C, K, Q, dC, dK, dQ)
        sol = collocation.solve(M, C, K, Q, period, self.name, n=n, edges=edges, **options)
        resolver = sol.resolver
        if resolver is not None:  # held by the Discrete only, not by the solution it reads
            sol = dataclasses.replace(sol, resolver=None)
        return self.discrete(sol, resolver)

    def discrete(self, sol, resolver=None) -> Discrete:
        """The :class:`Discrete` of a :class:`~kedfem.solvers.collocation.CollocationSolution`."""
        n, N = sol.U.shape
        s = self.stages
        return Discrete(self.name, n, sol.period, sol.U, sol.V, sol.floquet_multipliers,
                        bool(sol.stable), float(sol.residual), sol.method, sol, sol.at,
                        lambda: (sol.stage_U.reshape(n * s, N), sol.stage_V.reshape(n * s, N)),
                        sol.velocities, resolver)


class Fourier(Scheme):
    """Fourier (trigonometric) collocation over the whole cycle (:mod:`kedfem.solvers.fourier`).

    ``n`` is the number of nodes (odd). Spectrally accurate for smooth data
    once the nodes resolve the response; one dense system of size ``n N``
    (GMRES beyond :data:`kedfem.solvers.fourier.DENSE_LIMIT`), so it pays for small
    models and few nodes. Its Floquet multipliers come from the ``magnus2``
    monodromy on the same nodes (with the exact stiff split when given).
    """

    name = "fourier"
    order = 8           # spectral: faster than any power once resolved; 8 for the tables
    dense_order = 8
    stages = 1
    l_stable = False
    min_elements = 5
    per_period = 2.0    # two nodes per period of the highest harmonic (Nyquist)

    def refine(self, n):
        return 2 * n - 1  # odd stays odd

    def check_elements(self, n):
        n = super().check_elements(n)
        if n % 2 == 0:
            raise InputError(f"fourier: the number of nodes must be odd (every harmonic up to "
                             f"(n - 1) / 2 represented whole), got {n}")
        return n

    def instants(self, n, period, edges=None):
        if edges is not None:
            raise InputError("fourier: the nodes are equally spaced")
        return np.arange(n) * (period / n)

    def solve(self, M, C, K, Q, period, n, *, dC=None, dK=None, dQ=None, edges=None, stiff=None,
              **options):
        from . import fourier
        if edges is not None:
            raise InputError("fourier: the nodes are equally spaced")
        for X, name in ((M, "M"), (C, "C"), (K, "K"), (Q, "Q")):
            if callable(X):
                raise InputError(f"fourier: {name} must be sampled (the whole cycle is one system)")
        Ct = C if dC is None else C + dC
        Kt = K if dK is None else K + dK
        Qt = Q if dQ is None else Q + dQ
        sol = fourier.solve(M, Ct, Kt, Qt, period)
        # Floquet multipliers: the exponential monodromy on the same nodes (Fourier collocation has none)
        mono = SCHEMES["magnus2"].solve(M, Ct, Kt, np.zeros_like(np.asarray(Qt, float)), period, n,
                                        stiff=stiff, **{k: v for k, v in options.items() if k == "delta"})
        U, V = sol.U, sol.V
        return Discrete(self.name, n, period, U, V, mono.floquet_multipliers, mono.stable, sol.residual,
                        sol.method, sol, sol.at, lambda: (U, V))


SCHEMES: dict[str, Scheme] = {s.name: s for s in (
    Collocation("radau3"), Collocation("radau2"), Collocation("gauss3"), Collocation("gauss2"),
    ExponentialHold("magnus2"), ExponentialHold("foh"), ExponentialHold("zoh"), Fourier(),
)}


def names() -> tuple[str, ...]:
    """Registered scheme names, ``"auto"`` first."""
    return ("auto",) + tuple(SCHEMES)


def get(name: str) -> Scheme:
    """The scheme registered as ``name`` (``"auto"``: :data:`AUTO`)."""
    key = AUTO if name == "auto" else name
    if key not in SCHEMES:
        raise InputError(f"unknown time scheme {name!r}; valid: {', '.join(names())}")
    return SCHEMES[key]
