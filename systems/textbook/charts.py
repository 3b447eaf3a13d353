"""Chart singularities: configurations where the coordinates fail, not the physics.

At the pole of polar angles (theta = 0 on a sphere), at r = 0 of polar coordinates, at
the gimbal lock of Euler angles, the mass matrix M(q) is singular: a whole line of the
chart (theta = 0, every phi) is one configuration, and the Hessian of U there says
nothing about stability (for U = k x^2/2 on a sphere both K and M vanish at the pole).

Where the scene has particles, their positions r(q) embed the configuration space in
Cartesian space, and that embedding is a chart too: near the singular configuration r*
the projection of r(q) - r* on the tangent plane of the configuration space (mass
weighted) is a regular local chart ``u``, in which T = |u_dot|^2/2 to second order and U
is fitted as a quadratic form. Its eigenvalues are the squared frequencies, counted with
multiplicity (the spherical pendulum's two equal sqrt(g/l) at the bottom).

``local_chart`` does that numerically: it follows the fibre of the chart over r* (the
coordinates' directions that do not move any particle), samples q around it, finds the
tangent plane (SVD of the displacements) and fits U on it. A configuration space that is
itself singular there (the tip of a cone) has no tangent plane of the right dimension,
and a U that is not a smooth function of the configuration (U = phi^2 at the pole) does
not fit a quadratic: both are reported, never decided.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import sympy

from systems.mechanics import Mechanics
from systems.textbook._numeric import vectorize, with_parameters

FIBRE_SPAN = 2 * math.pi
"""How far along a direction that moves no particle the fibre is followed (both ways)."""
STEP = 1e-3
"""Size of the displacements about the fibre, in each coordinate's ``scales`` unit."""


@dataclass(frozen=True)
class LocalChart:
    """The quadratic motion about a singular configuration, in a regular local chart.

    Attributes
    ----------
    stiffness : ndarray, shape (d, d)
        d^2U/du^2 in mass-weighted tangent coordinates u (M = identity there): its
        eigenvalues are w^2. Empty when ``reason`` is set.
    reason : str
        Why no regular chart could be formed ("" when it was).
    """

    stiffness: np.ndarray
    reason: str = ""


def embedding(mechanics: Mechanics, parameters) -> Callable[[np.ndarray], np.ndarray] | None:
    """``f(q (n,)) -> (3N,)`` the particles' positions, each scaled by sqrt(mass) (so that
    T = |d f/dt|^2 / 2), or None where the scene has no particles, they move with t, or
    L has terms the particles do not give (a Hamiltonian-only scene)."""
    scene = mechanics.scene
    if mechanics.lagrangian is None or not scene.particles:
        return None
    if scene.transformation_depends_on_time:
        return None
    transformation = scene.transformation
    components = [
        sympy.sqrt(mass) * x
        for mass, position in zip(transformation.masses, transformation.positions, strict=True)
        for x in position
    ]
    components = [with_parameters(c, mechanics, parameters) for c in components]
    f = vectorize(components, mechanics.q)
    return lambda q: np.asarray(f(*q), dtype=float).reshape(-1)


def local_chart(
    position: Callable[[np.ndarray], np.ndarray],
    potential: Callable[[np.ndarray], float],
    q: np.ndarray,
    scales: np.ndarray,
) -> LocalChart:
    """U to second order about the configuration ``r* = position(q)`` in a regular chart.

    Parameters
    ----------
    position : callable
        q (n,) -> mass-weighted positions (``embedding``).
    potential : callable
        q (n,) -> U.
    q : ndarray, shape (n,)
        A point of the chart at the singular configuration.
    scales : ndarray, shape (n,)
        A length for each coordinate (the displacements are ``STEP`` of it).
    """
    n = len(q)
    centre = position(q)
    size = max(1.0, float(np.max(np.abs(centre))))
    # the fibre: directions of q that move no particle to first order, followed as far as
    # the configuration stays r*
    h = 1e-6 * scales
    J = np.column_stack([(position(q + h[j] * e) - position(q - h[j] * e)) / (2 * h[j])
                         for j, e in enumerate(np.eye(n))])  # fmt: skip
    if not np.all(np.isfinite(J)):  # a position that is not real there (sqrt of a mass < 0)
        return LocalChart(np.zeros((0, 0)), "the particles' positions are not finite near it")
    _, singular, Vt = np.linalg.svd(J / np.maximum(1.0, np.abs(J).max()))
    rank = int(np.count_nonzero(singular > 1e-8))
    kernel = Vt[rank:]
    fibre = [q]
    for direction, s in itertools.product(kernel, np.linspace(-FIBRE_SPAN, FIBRE_SPAN, 25)):
        point = q + s * direction * scales
        if s != 0 and np.linalg.norm(position(point) - centre) <= 1e-9 * size:
            fibre.append(point)
    rng = np.random.default_rng(11)
    directions = rng.normal(size=(8 * n + 8, n))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    samples = np.array(
        [f + radius * STEP * d * scales for f in fibre for d in directions for radius in (1, 2, 3)]
    )
    with np.errstate(all="ignore"):
        moved = np.array([position(s) for s in samples]) - centre
        level = potential(q)
        change = np.array([potential(s) for s in samples]) - level
    if not (np.all(np.isfinite(moved)) and np.all(np.isfinite(change))):
        return LocalChart(np.zeros((0, 0)), "U or the positions cannot be evaluated near it")
    _, spread, axes = np.linalg.svd(moved, full_matrices=False)
    if len(spread) < n or spread[n - 1] <= 0:
        return LocalChart(np.zeros((0, 0)), "the particles cannot move in every direction there")
    if len(spread) > n and spread[n] > 0.05 * spread[n - 1]:
        return LocalChart(
            np.zeros((0, 0)),
            "the configuration space itself is not smooth there (no tangent plane: the "
            "tip of a cone)",
        )
    u = moved @ axes[:n].T  # tangent coordinates (mass weighted)
    pairs = [(i, j) for i in range(n) for j in range(i, n)]
    powers = [list(itertools.combinations_with_replacement(range(n), order)) for order in (3, 4)]
    columns = [u[:, i] for i in range(n)]
    columns += [u[:, i] * u[:, j] * (0.5 if i == j else 1.0) for i, j in pairs]
    columns += [np.prod(u[:, list(term)], axis=1) for terms in powers for term in terms]
    A = np.column_stack(columns)
    coefficients, *_ = np.linalg.lstsq(A, change, rcond=None)
    misfit = float(np.linalg.norm(A @ coefficients - change))
    if misfit > 1e-4 * max(float(np.linalg.norm(change)), 1e-300):
        return LocalChart(np.zeros((0, 0)), "U is not a smooth function of the configuration there")
    K = np.zeros((n, n))
    for (i, j), c in zip(pairs, coefficients[n : n + len(pairs)], strict=True):
        K[i, j] = K[j, i] = c
    # at an equilibrium the linear term is nothing beside the quadratic one
    reach = float(np.median(np.linalg.norm(u, axis=1)))
    if float(np.linalg.norm(coefficients[:n])) * reach > 1e-3 * float(np.median(np.abs(change))):
        return LocalChart(np.zeros((0, 0)), "U has a slope there in the regular chart")
    return LocalChart(K)


def covariant_limit(
    mass: Callable[[np.ndarray], np.ndarray],
    mass_derivatives: Callable[[np.ndarray], np.ndarray],
    gradient: Callable[[np.ndarray], np.ndarray],
    hessian: Callable[[np.ndarray], np.ndarray],
    q: np.ndarray,
    scales: np.ndarray,
) -> tuple[np.ndarray, str]:
    """The squared frequencies at a chart singularity from the chart itself, or a reason.

    At an equilibrium the Hessian of U is a tensor, and away from one the covariant
    Hessian ``U_;ij = U_,ij - Gamma^k_ij U_,k`` (Christoffel symbols of M) is; the
    eigenvalues of ``M^-1 U_;ij`` are the same in every chart and vary smoothly over a
    smooth configuration space. They are computed at regular points ``q + s d`` on rays
    leaving the singular line (``d`` across the kernel of M) and extrapolated to s = 0;
    rays whose limits disagree mean a configuration space that is not smooth there.

    ``mass_derivatives(q)`` is dM/dq, shape (n, n, n) with ``[k, i, j] = dM_ij/dq_k``.
    Returns ``(omega_squared ascending (n,), "")`` or ``(empty, reason)``.
    """
    n = len(q)
    _, values, vectors = np.linalg.svd(mass(q))
    kernel = vectors[values <= 1e-13 * max(float(values[0]), 1e-300)]
    across = _complement(kernel, n) if kernel.size else np.eye(n)
    rng = np.random.default_rng(13)
    rays = [across @ c for c in rng.normal(size=(6, across.shape[1]))]
    steps = np.array([4e-3, 2e-3, 1e-3])
    limits = []
    for ray in rays:
        length = np.linalg.norm(ray)
        if not length > 0.0:  # M vanishes in every direction: no ray leaves the point
            continue
        ray = ray / length * scales
        spectra = []
        for s in steps:
            point = q + s * ray
            M, dM = mass(point), mass_derivatives(point)
            g, K = gradient(point), hessian(point)
            try:
                inverse = np.linalg.inv(M)
            except np.linalg.LinAlgError:
                break
            # Gamma^k_ij = M^kl (dM_li/dq_j + dM_lj/dq_i - dM_ij/dq_l) / 2
            first = np.einsum("jli->lij", dM) + np.einsum("ilj->lij", dM) - dM
            gamma = 0.5 * np.einsum("kl,lij->kij", inverse, first)
            covariant = K - np.einsum("kij,k->ij", gamma, g)
            covariant = (covariant + covariant.T) / 2
            w2 = np.sort(np.linalg.eigvals(inverse @ covariant).real)
            if not np.all(np.isfinite(w2)):
                break
            spectra.append(w2)
        if len(spectra) == len(steps):
            spectra = np.array(spectra)
            # the quadratic through the three steps, at s = 0 (Neville)
            s0, s1, s2 = steps
            limit = (
                spectra[0] * s1 * s2 / ((s0 - s1) * (s0 - s2))
                + spectra[1] * s0 * s2 / ((s1 - s0) * (s1 - s2))
                + spectra[2] * s0 * s1 / ((s2 - s0) * (s2 - s1))
            )
            limits.append(limit)
    if len(limits) < 2:
        return np.zeros(0), "no regular points of the chart were found around it"
    limits = np.array(limits)
    spread = float(np.max(np.ptp(limits, axis=0)))
    size = max(float(np.max(np.abs(limits))), 1e-300)
    if spread > 1e-4 * size:
        return np.zeros(0), (
            "the limits of the frequencies differ with the direction of approach: the "
            "configuration space itself is not smooth there (the tip of a cone)"
        )
    return np.median(limits, axis=0), ""


def _complement(rows: np.ndarray, n: int) -> np.ndarray:
    """An orthonormal basis (n, n - rank) of the vectors orthogonal to ``rows``."""
    _, singular, vt = np.linalg.svd(np.atleast_2d(rows), full_matrices=True)
    rank = int(np.count_nonzero(singular > 1e-12 * max(float(singular[0]), 1e-300)))
    return vt[rank:].T
