"""Refuse a start where the equations of motion are singular, before any integration.

A derivation holds for symbolic parameters; a zero mass, a zero length or a start at a
coordinate singularity (r = 0 in polar coordinates) only shows when numbers go in. Found
after a run, it surfaced as a division by zero in H; found here, it is a message naming
what is singular, given before a single step.
"""

from __future__ import annotations

import numpy as np

from systems.mechanics import DerivationError

SINGULAR_RATIO = 1e-13
"""A mass matrix whose smallest |eigenvalue| is below this times its largest is singular."""


class SingularStart(DerivationError):
    """The equations cannot be integrated from this start with these parameters."""


def check_start(compiled, y0: np.ndarray | None = None, t0: float = 0.0) -> np.ndarray:
    """The canonical start (q, p), shape (2n,), once it is known to be regular.

    Checks, at the initial state and the current parameter values: the initial state can
    be formed and is finite; the mass matrix d2L/dqdot2 is regular (and positive definite
    where the scene gives T, which must be); the velocities qdot(q, p) give the momenta
    back (``_round_trip``); H and Hamilton's equations are finite and real.

    Raises
    ------
    SingularStart
        Saying what is singular, with the state and the parameters that are zero.
    """
    mechanics = compiled.mechanics
    scene = mechanics.scene
    fail = _Failer(compiled)
    if y0 is None:
        try:
            with np.errstate(all="ignore"):
                y0 = compiled.initial_state(t0)
        except (ArithmeticError, ValueError, TypeError) as exc:
            raise fail(f"the initial momenta cannot be formed ({exc})") from None
    y0 = np.asarray(y0, dtype=float)
    if not np.all(np.isfinite(y0)):
        bad = [name for name, v in zip(fail.state_names, y0, strict=True) if not np.isfinite(v)]
        raise fail(f"the initial state is not finite ({', '.join(bad)})")
    if mechanics.mass_matrix is not None:
        matrix = _mass_matrix(compiled, t0, y0)
        if matrix is None or not np.all(np.isfinite(matrix)):
            raise fail("the mass matrix d2L/dqdot2 is not finite")
        eigenvalues = np.linalg.eigvalsh((matrix + matrix.T) / 2)
        largest = float(np.max(np.abs(eigenvalues)))
        if largest == 0.0 or float(np.min(np.abs(eigenvalues))) <= SINGULAR_RATIO * largest:
            raise fail(
                "the mass matrix d2L/dqdot2 is singular (eigenvalues "
                f"{_numbers(eigenvalues)}): the kinetic energy gives some direction no "
                "inertia, as a zero mass or length does, or polar coordinates at r = 0"
            )
        if scene.kind == "energies" and float(np.min(eigenvalues)) < 0:
            raise fail(
                "the kinetic energy is not positive definite (mass matrix eigenvalues "
                f"{_numbers(eigenvalues)}): a mass or moment of inertia is negative"
            )
    problem = _round_trip(compiled, t0, y0)
    if problem is not None:
        raise fail(problem)
    for label, values in _equations(compiled, t0, y0):
        bad = [(name, v) for name, v in zip(label, values, strict=True) if not np.isfinite(v)]
        if bad:
            raise fail(", ".join(f"{name} is {_kind(v)}" for name, v in bad))
    return y0


class _Failer:
    def __init__(self, compiled):
        self.compiled = compiled
        scene = compiled.mechanics.scene
        self.state_names = (*scene.coordinates, *scene.momentum_names)

    def __call__(self, what: str) -> SingularStart:
        compiled = self.compiled
        scene = compiled.mechanics.scene
        values = dict(scene.initial)
        start = ", ".join(f"{k} = {v:g}" for k, v in values.items()) or "all zero"
        pairs = zip(compiled.parameter_names, compiled.parameters, strict=True)
        zero = [name for name, value in pairs if value == 0]
        hint = f"; zero parameters: {', '.join(zero)}" if zero else ""
        return SingularStart(
            f"the equations of motion are singular at the start ({start}){hint}: {what}. "
            "Change the initial state or the parameters",
            source=scene.source,
            field="initial",
        )


def _kind(value: float) -> str:
    if np.isnan(value):
        return "not a number (0/0, or a square root or logarithm of a negative number)"
    return "infinite (a division by zero)"


def _numbers(values) -> str:
    return "[" + ", ".join(f"{v:.3g}" for v in values) + "]"


def _mass_matrix(compiled, t0: float, y0: np.ndarray) -> np.ndarray | None:
    """d2L/dqdot2 at the start, or None where it cannot be evaluated.

    For a system in matrix form ``velocities`` are the velocity symbols themselves (their
    values come from solving with this very matrix), and L is quadratic in them, so M is
    evaluated at any velocity: zero.
    """
    mech = compiled.mechanics
    n = compiled.n
    try:
        with np.errstate(all="ignore"):
            if mech.matrix_form is not None:
                qdot = np.zeros(n)
            else:
                v = compiled._lambdified("velocities", (mech.t, mech.q, mech.p), mech.velocities)
                qdot = np.array(v(t0, y0[:n], y0[n:]), dtype=float).reshape(n)
            f = compiled._lambdified("mass_matrix", (mech.t, mech.q, mech.qdot), mech.mass_matrix)
            raw = np.array(f(t0, y0[:n], qdot), dtype=complex).reshape(n, n)
    except (ArithmeticError, ValueError, TypeError):
        return None
    if np.any(np.abs(raw.imag) > 0):
        return None
    return raw.real


def _round_trip(compiled, t0: float, y0: np.ndarray) -> str | None:
    """Why p(q, qdot(q, p)) is not p at the start, or None.

    The closed-form inverse of a square-root Lagrangian (``systems.legendre``) is formed
    for the signs the parameters have in the scene (m c**2 > 0: H = c sqrt(c**2 m**2 +
    p**2)); a parameter moved to the other sign afterwards (the window changes values
    without deriving again) would run the dynamics of the other sign. Only a Lagrangian
    that is not quadratic is checked (a quadratic one is inverted for any values); a
    value that cannot be evaluated is left to the checks of the equations.
    """
    mech = compiled.mechanics
    if mech.lagrangian is None or mech.momenta is None or mech.matrix_form is not None:
        return None
    if not any(a.has(*mech.qdot) for row in mech.mass_matrix.tolist() for a in row):
        return None  # L quadratic in the velocities: M q̇ + a = p is solved exactly
    n = compiled.n
    q, p0 = y0[:n], y0[n:]
    v = compiled._lambdified("velocities", (mech.t, mech.q, mech.p), mech.velocities)
    # the start's momenta, and nudged ones: at rest (p = 0) any sign gives p back
    for p in (p0, p0 + 1e-3 * (1.0 + np.abs(p0))):
        try:
            with np.errstate(all="ignore"):
                qdot = np.array(v(t0, q, p), dtype=float).reshape(n)
                back = compiled.momenta_from_velocities(t0, q, qdot)
        except (ArithmeticError, ValueError, TypeError):
            continue
        if not (np.all(np.isfinite(qdot)) and np.all(np.isfinite(back))):
            continue
        scale = max(1.0, float(np.max(np.abs(p))))
        if np.allclose(back, p, rtol=1e-8, atol=1e-12 * scale):
            continue
        values = dict(zip(compiled.parameter_names, compiled.parameters, strict=True))
        signs = ", ".join(f"{name} = {value:g}" for name, value in values.items())
        return (
            "the velocities q̇(q, p) do not give the momenta back (p = ∂L/∂q̇ at them is "
            f"{_numbers(back)}, not {_numbers(p)}): the Legendre transform was solved for "
            f"the signs the parameters have in the scene, not for {signs}; change the "
            "scene's values so that it is derived again"
        )
    return None


def _equations(compiled, t0: float, y0: np.ndarray):
    """(names, values) of dy/dt and H at the start; a raising or complex value is nan."""
    scene = compiled.mechanics.scene
    rates = [f"d{name}/dt" for name in (*scene.coordinates, *scene.momentum_names)]
    with np.errstate(all="ignore"):
        try:
            yield rates, compiled.rhs(t0, y0)
        except (ArithmeticError, ValueError, TypeError):
            yield ["Hamilton's equations"], [np.nan]
        if "hamiltonian" in compiled.wanted:
            try:
                yield ["H"], compiled.hamiltonian(t0, y0[None, :])
            except (ArithmeticError, ValueError, TypeError):
                yield ["H"], [np.nan]
