"""The steppers by name, their tableaux, and the automatic choice of one.

Like scipy's ``METHODS``: each ``Stepper`` declares its order, whether it is symplectic,
and what structure of system it needs. The stepping loops themselves are the compiled
templates of ``systems.integrators.kernels``; this module only holds their coefficients.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache

import numpy as np

FAMILIES = ("composition", "gauss", "gauss_tt", "logh", "dop853", "scipy")


@dataclass(frozen=True)
class Stepper:
    """One integration method.

    Attributes
    ----------
    name, description : str
    order : int
        Global order of accuracy (error ~ dt**order for fixed steps).
    symplectic : bool
    needs_separable : bool
        Needs H = T(p) + V(q, t) (the ``separable`` kernels).
    adaptive : bool
        Chooses its own steps from a tolerance.
    time_transformed : bool
        Steps in a fictitious time (step sizes in t follow the dynamics).
    family : str
        Which compiled loop runs it: one of ``FAMILIES``.
    weights : tuple of float
        Composition weights of the leapfrog (composition and logh families).
    stages : int
        Stages of a Gauss-Legendre method.
    """

    name: str
    order: int
    symplectic: bool
    needs_separable: bool
    adaptive: bool
    time_transformed: bool
    description: str
    family: str
    weights: tuple[float, ...] = (1.0,)
    stages: int = 0
    stiff: bool = False
    wants: frozenset[str] = field(default_factory=frozenset)

    def kick_drift(self) -> tuple[np.ndarray, np.ndarray]:
        """Merged stage coefficients of the composed kick-drift-kick leapfrog.

        Returns
        -------
        kick : ndarray, shape (s + 1,)
        drift : ndarray, shape (s,)
        """
        w = np.array(self.weights, dtype=float)
        kick = np.empty(len(w) + 1)
        kick[0] = w[0] / 2
        kick[1:-1] = (w[:-1] + w[1:]) / 2
        kick[-1] = w[-1] / 2
        return kick, w.copy()


def _symmetric(outer_to_inner: tuple[float, ...]) -> tuple[float, ...]:
    """Weights ``(w_m, ..., w_1)`` -> the palindrome with ``w_0 = 1 - 2 sum`` in the middle."""
    w0 = 1.0 - 2.0 * sum(outer_to_inner)
    return (*outer_to_inner, w0, *reversed(outer_to_inner))


_CBRT2 = 2.0 ** (1.0 / 3.0)
TRIPLE_JUMP = _symmetric((1.0 / (2.0 - _CBRT2),))
# Yoshida (1990), Phys. Lett. A 150, 262: order 6 solution A and order 8 solution D,
# listed as (w_m, ..., w_1).
YOSHIDA6 = _symmetric((0.784513610477560, 0.235573213359357, -1.17767998417887))
YOSHIDA8 = _symmetric(
    (
        0.914844246229740,
        0.253693336566229,
        -1.44485223686048,
        -0.158240635368243,
        1.93813913762276,
        -1.96061023297549,
        0.102799849391985,
    )
)


@cache
def gauss_tableau(stages: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Gauss-Legendre collocation tableau and its stage extrapolation matrix.

    Returns
    -------
    A : ndarray, shape (s, s)
    b, c : ndarray, shape (s,)
    E : ndarray, shape (s, s)
        ``Z_next = E @ Z``: the collocation polynomial of a step (through 0 at node 0 and
        the increments ``Z`` at the nodes ``c``), continued to ``1 + c`` and taken
        relative to its value at 1. This is the starting guess of the next step.
    """
    x, _ = np.polynomial.legendre.leggauss(stages)
    c = (x + 1.0) / 2.0
    nodes = np.concatenate([[0.0], c])
    s = stages
    A = np.empty((s, s))
    b = np.empty(s)
    E = np.empty((s, s))
    P = np.polynomial.Polynomial
    for j in range(s):
        # Lagrange basis on the nodes c (for A, b) and on (0, c) (for the extrapolation)
        others = np.delete(c, j)
        ell = (P.fromroots(others) if len(others) else P([1.0])) / np.prod(c[j] - others)
        integral = ell.integ()
        b[j] = integral(1.0) - integral(0.0)
        A[:, j] = integral(c) - integral(0.0)
        others0 = np.delete(nodes, j + 1)
        L = P.fromroots(others0) / np.prod(c[j] - others0)
        E[:, j] = L(1.0 + c) - L(1.0)
    return A, b, c, E


def _stepper(name, order, family, description, **kw) -> Stepper:
    symplectic = family in ("composition", "gauss", "logh")
    needs_separable = family in ("composition", "logh")
    wants = {"rhs"}
    if needs_separable:
        wants = {"separable"}
    if family == "logh":
        wants = {"separable", "rhs"}
    return Stepper(
        name=name,
        order=order,
        symplectic=symplectic,
        needs_separable=needs_separable,
        adaptive=family in ("dop853", "scipy"),
        time_transformed=family in ("logh", "gauss_tt"),
        description=description,
        family=family,
        wants=frozenset(wants),
        **kw,
    )


STEPPERS: dict[str, Stepper] = {
    s.name: s
    for s in (
        _stepper("leapfrog", 2, "composition", "Störmer-Verlet (kick-drift-kick) leapfrog"),
        _stepper(
            "yoshida4",
            4,
            "composition",
            "Yoshida/Suzuki triple-jump leapfrog composition",
            weights=TRIPLE_JUMP,
        ),
        _stepper("yoshida6", 6, "composition", "Yoshida 7-stage composition (A)", weights=YOSHIDA6),
        _stepper(
            "yoshida8", 8, "composition", "Yoshida 15-stage composition (D)", weights=YOSHIDA8
        ),
        _stepper("implicit_midpoint", 2, "gauss", "implicit midpoint rule", stages=1),
        _stepper("gauss_legendre4", 4, "gauss", "2-stage Gauss-Legendre collocation", stages=2),
        _stepper("gauss_legendre6", 6, "gauss", "3-stage Gauss-Legendre collocation", stages=3),
        _stepper(
            "logh_leapfrog",
            2,
            "logh",
            "logarithmic-Hamiltonian time-transformed leapfrog (Mikkola-Tanikawa)",
        ),
        _stepper(
            "logh_yoshida4",
            4,
            "logh",
            "logarithmic-Hamiltonian leapfrog, triple jump",
            weights=TRIPLE_JUMP,
        ),
        _stepper(
            "logh_yoshida6",
            6,
            "logh",
            "logarithmic-Hamiltonian leapfrog, Yoshida order 6",
            weights=YOSHIDA6,
        ),
        _stepper(
            "logh_yoshida8",
            8,
            "logh",
            "logarithmic-Hamiltonian leapfrog, Yoshida order 8",
            weights=YOSHIDA8,
        ),
        _stepper(
            "gauss_legendre4_tt",
            4,
            "gauss_tt",
            "2-stage Gauss-Legendre on the Sundman-transformed system (steps follow |dy/dt|)",
            stages=2,
        ),
        _stepper(
            "gauss_legendre6_tt",
            6,
            "gauss_tt",
            "3-stage Gauss-Legendre on the Sundman-transformed system (steps follow |dy/dt|)",
            stages=3,
        ),
        _stepper("dop853", 8, "dop853", "compiled adaptive Dormand-Prince 8(5,3)"),
        _stepper("radau", 5, "scipy", "scipy Radau IIA (implicit, stiff)", stiff=True),
        _stepper("bdf", 5, "scipy", "scipy BDF (implicit multistep, stiff)", stiff=True),
        _stepper("lsoda", 12, "scipy", "scipy LSODA (switches stiff/non-stiff)", stiff=True),
    )
}


def get_stepper(name: str) -> Stepper:
    """The stepper called ``name``; ``KeyError`` lists the known names."""
    try:
        return STEPPERS[name]
    except KeyError:
        known = ", ".join(STEPPERS)
        raise KeyError(f"unknown method {name!r}; choose from {known}") from None
