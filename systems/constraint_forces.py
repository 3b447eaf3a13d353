"""Constraint forces: the multipliers, the particles' reaction forces, their virtual work
and their power.

Two kinds of scene have constraint forces:

- **explicit constraints** (``[constraints]``: holonomic, nonholonomic and unilateral rows,
  ``constraints.rows``): with A the rows (Phi_q, a, G = g_q) the force of the constraints
  on the coordinates is ``Q_c = -A^T lambda`` (``systems.constraints``; a unilateral row
  out of contact has lambda = 0, one in contact pushes with lambda <= 0). It does no
  virtual work on a displacement ``delta q`` tangent to the acting rows (``A delta q =
  0``: for a nonholonomic row ``a . delta q = 0``, D'Alembert's principle for
  nonholonomic constraints), which holds by construction: Q_c lies in the row space of
  the acting rows. Its actual power is ``Q_c . qdot = lambda^T c`` with c the
  velocity-free part of each row (Phi_t, b, g_t; ``A qdot + c = 0`` along the motion):
  zero for constraints without t (and nonholonomic ones without b), not for a moving one.
- **particles** (``[particles]``) whose transformation r_i(q, t) eliminates constraints
  (d N Cartesian components described by fewer coordinates): the reaction force on each
  particle is what Newton's law needs beyond the applied forces,

      R_i = m_i r_i'' - F_i,
      r_i'' = sum_j dr_i/dq_j qddot_j + sum_j dv_i/dq_j qdot_j + dv_i/dt,

  with qddot from the equations of motion and F_i = m_i g the gravity of
  ``[system] gravity``, the one applied Cartesian force a scene names exactly. D'Alembert's
  principle, sum_i R_i . dr_i/dq_j = 0 for every j (the Lagrange equations in another
  form), is checked numerically, and the power sum_i R_i . v_i = sum_i R_i . dr_i/dt is
  zero for a transformation without t. A scene with forces that are not Cartesian forces
  on the particles (a ``potential`` beyond gravity, ``[effects]``) gets no R: ``note``
  says why, and nothing wrong is shown.

The work of the constraint forces, ``W(t)`` (the power integrated, ``WorkIntegral``),
closes the energy balance ``E(t) - E(0) = W(t)`` where nothing else does work: E = T + V
of the particles with gravity only, or Jacobi's energy function h for explicit
constraints on a Lagrangian without t and without effects (``balance``).

Impacts on unilateral constraints are not forces lambda: Newton's restitution law makes
the velocity jump, an impulse with no finite value at any time. W is the work of the
multipliers only, and the balance does not hold across impacts (each takes a fraction
1 - e**2 of the kinetic energy of the normal motion off a fixed wall): for a scene with
unilateral constraints ``balance`` is False, ``impacts`` True, and the energy is still
formed, so that E - E(0) - W, what the impacts changed, can be reported as such.

Everything is made once per ``Mechanics`` (sympy, then ``sympy.lambdify`` to numpy
functions of many states at once, the parameters an argument) and evaluated on arrays of
states; nothing here imports Qt. A ``ConstraintForces`` pickles, its functions as their
source (``systems.lambdified``): the window makes it in a worker process and evaluates it
in its own (``remember`` files it under the window's ``Mechanics``).
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import sympy

from systems import constraints
from systems.expressions import as_expr
from systems.lambdified import lambdify
from systems.particles import depends_on_time, gravity_vector

_ANALYSES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()

RESOLVED = 1e-3
"""An interval between two rows is followed by the quintic through them when its
acceleration at the middle is within this fraction of the equations' there; its work is
unknown (NaN) otherwise. For the variable-length pendulum and the hoop the intervals
this keeps are within 1e-4 of W's span of the exact work (rows 0.1 apart: 1e-7, all
kept; 0.3 apart: 6e-5, a tenth kept; 0.5 apart: none)."""


@dataclass(frozen=True)
class Forces:
    """The constraint forces at N states.

    Attributes
    ----------
    t : ndarray, shape (N,)
    multipliers : ndarray, shape (N, k), or None
        lambda of the explicit constraints, in row order (holonomic, nonholonomic,
        unilateral; 0 for a unilateral row out of contact); None without them.
    acting : ndarray of bool, shape (N, k), or None
        The rows that act at each state: every bilateral one, a unilateral one in contact
        (``constraints.Numeric.contacts``); None without explicit constraints.
    generalized : ndarray, shape (N, n)
        The constraint force on the coordinates: ``-A^T lambda`` for explicit
        constraints alone, ``sum_i R_i . dr_i/dq`` for particles (then it equals
        ``-A^T lambda``, or zero without explicit constraints).
    reactions : ndarray, shape (N, particles, d), or None
        R_i on each particle (None where not computed).
    virtual_work : ndarray, shape (N,)
        The largest relative virtual work over a basis of the displacements tangent to
        the acting constraints (``A u = 0``): ``|G . u| / scale`` with ``scale = |Q_c|
        |u|`` for explicit constraints and ``sum_i m_i (|r_i''| + |g|) |dr_i/dq . u|``
        (the size of the terms that cancel) for particles; round-off where D'Alembert's
        principle holds.
    power : ndarray, shape (N,)
        The actual power of the constraint forces.
    power_scale : ndarray, shape (N,)
        What a power of round-off size is measured against: ``|Q_c| |qdot|`` or
        ``sum_i m_i (|r_i''| + |g|) |v_i|``.
    energy : ndarray, shape (N,), or None
        The energy of the balance (T + V, or h): its change is the work where
        ``balance`` holds, the work plus what the impacts changed where ``impacts``;
        None where no energy is formed.
    velocities, accelerations : ndarray, shape (N, n)
        qdot and qddot of the motion (the accelerations with the multipliers).
    """

    t: np.ndarray
    multipliers: np.ndarray | None
    acting: np.ndarray | None
    generalized: np.ndarray
    reactions: np.ndarray | None
    virtual_work: np.ndarray
    power: np.ndarray
    power_scale: np.ndarray
    energy: np.ndarray | None
    velocities: np.ndarray
    accelerations: np.ndarray


@dataclass(frozen=True, eq=False)
class ConstraintForces:
    """What the constraint forces of one derived system are, and functions to compute them.

    Attributes
    ----------
    applies : bool
        The scene has constraint forces: explicit constraints, or particles with fewer
        coordinates than Cartesian components.
    reason : str
        Why it has none (when ``applies`` is False).
    k : int
        Explicit constraints (multipliers), every kind: ``constraints.rows``.
    kinds : tuple of k str
        ``"holonomic"``, ``"nonholonomic"`` or ``"unilateral"``, in row order.
    descriptions : tuple of k str
        What each multiplier belongs to, for labels: ``"holonomic"``,
        ``"nonholonomic"``, or the unilateral constraint itself (``"y ≥ 0"``).
    particles : tuple of str
        The particles whose reaction force is computed (empty if none is).
    dimension : int
        Components of each particle's position (0 without particles).
    note : str
        What is not computed and why (empty when everything is).
    rheonomic : bool
        The constraint forces can have power: a holonomic or unilateral constraint with
        t, a nonholonomic one with a velocity-free part b, or a transformation with t.
    balance : bool
        ``E(t) - E(0) = W(t)`` holds: nothing but the constraint forces changes E.
    impacts : bool
        Unilateral constraints: the velocity jumps at impacts change E too, and are not
        forces lambda (``balance`` is False; the energy is formed where it would hold
        without them).
    energy_name : str
        ``"T + V"`` or ``"h"`` (Jacobi's energy function) where the energy is formed
        (``balance`` or ``impacts``); empty otherwise.
    points : tuple of (str, int, int)
        Drawn points whose x and y are coordinates (index of each): the force on those
        coordinates is the Cartesian force on the point (explicit constraints only).
    """

    applies: bool
    reason: str = ""
    k: int = 0
    kinds: tuple[str, ...] = ()
    descriptions: tuple[str, ...] = ()
    particles: tuple[str, ...] = ()
    dimension: int = 0
    note: str = ""
    rheonomic: bool = False
    balance: bool = False
    impacts: bool = False
    energy_name: str = ""
    points: tuple[tuple[str, int, int], ...] = ()
    _functions: dict = field(default_factory=dict, repr=False)

    @property
    def multiplier_names(self) -> list[str]:
        """``lambda_1`` .. ``lambda_k``: the CSV columns (``constraints.multiplier_names``)."""
        return [f"lambda_{i + 1}" for i in range(self.k)]

    @property
    def multiplier_labels(self) -> list[str]:
        """Each multiplier's name with what it belongs to: ``lambda_1 (nonholonomic)``,
        ``lambda_2 (y ≥ 0)``."""
        return [
            f"{name} ({what})"
            for name, what in zip(self.multiplier_names, self.descriptions, strict=True)
        ]

    @property
    def unilateral(self) -> np.ndarray:
        """Which multipliers belong to unilateral constraints: bool, shape (k,)."""
        return np.array([kind == "unilateral" for kind in self.kinds], dtype=bool)

    @property
    def computes(self) -> bool:
        """Something is computed: multipliers or reaction forces."""
        return self.applies and (self.k > 0 or bool(self.particles))

    def evaluate(
        self, compiled, t: np.ndarray | float, Y: np.ndarray, acting: np.ndarray | None = None
    ) -> Forces:
        """The constraint forces at states ``Y`` (N, 2n) at times ``t`` (scalar or (N,)).

        Parameters
        ----------
        compiled : CompiledSystem
            Of the mechanics this was made for; its parameter values are used.
        acting : ndarray of bool, shape (N, k), optional
            The rows that act, where the caller knows them better than the states tell
            (states between two rows in contact, off the constraint by the
            interpolation's error, more than a contact's tolerance); by default every
            bilateral row and the unilateral ones a state is in contact with
            (``constraints.Numeric``).

        Raises
        ------
        ValueError
            If nothing is computed for this scene (``computes`` is False).
        """
        if not self.computes:
            raise ValueError(f"no constraint forces are computed here: {self.reason or self.note}")
        f = self._functions
        mech = compiled.mechanics
        n = mech.n
        Y = np.ascontiguousarray(np.atleast_2d(Y), dtype=float)
        N = len(Y)
        ts = np.ascontiguousarray(np.broadcast_to(np.asarray(t, dtype=float), (N,)))
        P = np.asarray(compiled.parameters, dtype=float)
        if N == 0:
            return _empty(self, n)
        with np.errstate(all="ignore"):
            Qd = _velocities(compiled, f, ts, Y)
            args = (ts, *Y[:, :n].T, *Qd.T, *P)
            lam = J = None
            rhs = _stack(f["forcing"], args, N, (n,))
            if self.k:
                J = _stack(f["jacobian"], args, N, (self.k, n))
                # lam is 0 for a unilateral row out of contact
                lam, acting = compiled.constraints().solve(ts, Y, acting)
                rhs = rhs - np.einsum("nkj,nk->nj", J, lam)
            else:
                acting = None
            qdd = _solve(_stack(f["mass"], args, N, (n, n)), rhs)
            basis = _tangent_directions(J, acting, N, n)
            if self.particles:
                result = self._particle_forces(f, args, N, n, Qd, qdd, P, basis)
            else:
                result = self._explicit_forces(Qd, lam, J, basis)
            energy = _stack(f["energy"], args, N, ()) if "energy" in f else None
        generalized, reactions, virtual_work, power, scale = result
        return Forces(
            ts, lam, acting, generalized, reactions, virtual_work, power, scale, energy, Qd, qdd
        )

    def interval_work(
        self, compiled, t: np.ndarray, Y: np.ndarray, known: Forces | None = None
    ) -> np.ndarray:
        """The work of the constraint forces over each interval between two rows.

        Between the rows i and i + 1 the motion is the quintic through q, qdot and
        qddot at both ends (Hermite), and its power is integrated by Gauss-Legendre's
        three-point rule: sixth order in the step, so the sparse rows a window keeps
        (where the orbit moves, not where the power changes) still give W to about
        1e-8 of its size. An interval whose quintic does not follow the motion (its
        acceleration at the middle misses the equations' by more than ``RESOLVED``: rows
        a period or more apart) gets NaN, like a gap. With unilateral constraints the
        states between two rows act on the contacts both rows act on, and an interval
        across which a contact begins or ends, or that ends on a constraint it does not
        act on (the state after an impact: the velocity jumped), gets NaN: the quintic
        cannot follow a jump. Where no constraint moves
        (``rheonomic`` False) the power is zero identically and the rows' round-off is
        integrated by the trapezoid rule.

        Parameters
        ----------
        t : ndarray, shape (N,)
        Y : ndarray, shape (N, 2n)
            Rows of one trajectory; a gap row (NaN) has no state.
        known : Forces, optional
            ``evaluate`` of the rows that are not gaps, in order, if the caller has it
            (only its velocities, accelerations, power and acting rows are used).

        Returns
        -------
        ndarray, shape (N - 1,)
            NaN for an interval with a gap row at either end, or not resolved.
        """
        t = np.asarray(t, dtype=float)
        Y = np.ascontiguousarray(np.atleast_2d(Y), dtype=float)
        out = np.full(max(len(t) - 1, 0), np.nan)
        if len(t) < 2 or "momenta" not in self._functions:
            return out
        n = compiled.n
        good = np.all(np.isfinite(Y), axis=1) & np.isfinite(t)
        pair = good[:-1] & good[1:] & (t[1:] >= t[:-1])
        if not pair.any():
            return out
        rows = np.flatnonzero(good)
        kin = known if known is not None else self.evaluate(compiled, t[rows], Y[rows])
        if not self.rheonomic:
            # the power vanishes identically on the constraints; states between the rows
            # would be off them by the interpolation's error, the rows are not
            where = np.flatnonzero(pair)
            power = np.full(len(t), np.nan)
            power[rows] = kin.power
            out[pair] = (t[where + 1] - t[where]) * (power[where] + power[where + 1]) / 2
            return out
        where = np.full(len(t), -1)
        where[rows] = np.arange(len(rows))
        a = where[np.flatnonzero(pair)]
        b = where[np.flatnonzero(pair) + 1]
        h = (t[1:] - t[:-1])[pair]
        q = Y[rows, :n]
        v, acc = kin.velocities, kin.accelerations
        hh = h[:, None]
        ends = (q[a], hh * v[a], hh**2 * acc[a], q[b], hh * v[b], hh**2 * acc[b])
        times, positions, velocities = [], [], []
        for s in 0.5 + np.array([-1.0, 0.0, 1.0]) * math.sqrt(15.0) / 10.0:
            value, slope = _quintic(s)
            times.append(t[:-1][pair] + s * h)
            positions.append(sum(c * e for c, e in zip(value, ends, strict=True)))
            velocities.append(sum(c * e for c, e in zip(slope, ends, strict=True)) / hh)
        ts, qs, vs = np.concatenate(times), np.concatenate(positions), np.concatenate(velocities)
        P = np.asarray(compiled.parameters, dtype=float)
        with np.errstate(all="ignore"):
            momenta = _stack(self._functions["momenta"], (ts, *qs.T, *vs.T, *P), len(ts), (n,))
        nodes = np.concatenate([qs, momenta], axis=1)
        jumps = np.zeros(len(h), dtype=bool)
        if self.impacts:
            act = np.asarray(kin.acting, dtype=bool)
            jumps = (
                np.any(act[a] != act[b], axis=1)
                | _touching_free(compiled, t[rows], Y[rows], act)[b]
            )
            at_nodes = self.evaluate(compiled, ts, nodes, acting=np.tile(act[a], (3, 1)))
        else:
            at_nodes = self.evaluate(compiled, ts, nodes)
        weights = np.array([5.0, 8.0, 5.0]) / 18.0  # Gauss-Legendre on [0, 1]
        work = h * (weights @ at_nodes.power.reshape(3, len(h)))
        # rows too far apart for the quintic to follow the motion (a window's sparse rows
        # at full speed): its acceleration at the middle is not the equations' there
        middle = at_nodes.accelerations[len(h) : 2 * len(h)]
        quintic = 1.5 * (v[b] - v[a]) / hh - (acc[a] + acc[b]) / 4
        scale = np.maximum(np.abs(middle), np.maximum(np.abs(acc[a]), np.abs(acc[b])))
        with np.errstate(all="ignore"):
            miss = np.max(np.abs(quintic - middle), axis=1) / np.max(scale, axis=1)
        resolved = (miss <= RESOLVED) | (np.max(np.abs(quintic - middle), axis=1) == 0)
        out[pair] = np.where(resolved & ~jumps, work, np.nan)
        return out

    def work(self, compiled, t: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """W at each row of one trajectory without gaps: the work from the first row,
        shape (N,) (``interval_work`` summed)."""
        return np.concatenate([[0.0], np.cumsum(self.interval_work(compiled, t, Y))])

    def _explicit_forces(self, Qd, lam, J, basis):
        generalized = -np.einsum("nkj,nk->nj", J, lam)
        size = np.linalg.norm(generalized, axis=1)
        along = np.abs(np.einsum("nj,njr->nr", generalized, basis))
        virtual_work = _ratio(along.max(axis=1), size)
        power = np.einsum("nj,nj->n", generalized, Qd)
        scale = size * np.linalg.norm(Qd, axis=1)
        return generalized, None, virtual_work, power, scale

    def _particle_forces(self, f, args, N, n, Qd, qdd, P, basis):
        d, count = self.dimension, len(self.particles)
        D = _stack(f["columns"], args, N, (count, d, n))  # dr_i/dq_j
        rates = _stack(f["rates"], args, N, (count, d))  # explicit dr_i/dt
        bias = _stack(f["bias"], args, N, (count, d))  # r_i'' without the qddot part
        masses = np.asarray(f["masses"](*P), dtype=float).reshape(count)
        g = np.asarray(f["gravity"](*P), dtype=float).reshape(d)
        acceleration = np.einsum("npdj,nj->npd", D, qdd) + bias
        reactions = masses[None, :, None] * (acceleration - g[None, None, :])
        generalized = np.einsum("npd,npdj->nj", reactions, D)
        along = np.abs(np.einsum("nj,njr->nr", generalized, basis))
        moved = np.linalg.norm(np.einsum("npdj,njr->npdr", D, basis), axis=2)  # |dr_i/dq . u|
        # the size of what cancels: m r'' and F of each particle, not R (R is small
        # where they nearly cancel, and round-off in them is not)
        sizes = masses[None, :] * (np.linalg.norm(acceleration, axis=2) + np.linalg.norm(g))
        terms = np.einsum("np,npr->nr", sizes, moved)
        virtual_work = np.max(_ratio(along, terms), axis=1)
        v = np.einsum("npdj,nj->npd", D, Qd) + rates
        power = np.einsum("npd,npd->n", reactions, v)
        scale = np.einsum("np,np->n", sizes, np.linalg.norm(v, axis=2))
        return generalized, reactions, virtual_work, power, scale


def analyse(mechanics) -> ConstraintForces:
    """The constraint forces of ``mechanics``' scene: what applies, what is computed and
    the functions that compute it (made once per ``Mechanics``)."""
    try:
        return _ANALYSES[mechanics]
    except KeyError:
        pass
    result = _analyse(mechanics)
    _ANALYSES[mechanics] = result
    return result


def known(mechanics) -> ConstraintForces | None:
    """The analysis of ``mechanics`` if it was made already, else None (never makes it)."""
    return _ANALYSES.get(mechanics)


def remember(mechanics, analysis: ConstraintForces) -> None:
    """File ``analysis``, made elsewhere (in a worker process, from a copy of
    ``mechanics``), as the analysis of ``mechanics``: ``known`` and ``analyse`` return it."""
    _ANALYSES[mechanics] = analysis


def presence(scene) -> str | None:
    """Why ``scene`` has no constraint forces, or None if it has some (explicit
    constraints, or particles with fewer coordinates than Cartesian components).

    Read off the scene's tables alone, without sympy: cheap enough to decide at once
    whether a panel is offered.
    """
    if constraints.constrained(scene):
        return None
    if not scene.particles:
        return "the scene has no constraints: [constraints] and [particles] are absent"
    n = len(scene.coordinates)
    components = sum(len(particle.position) for particle in scene.particles)
    if components > n:
        return None
    return (
        f"no constraints: the {n} coordinates describe the particles' {components} "
        "Cartesian components one to one"
    )


def restitution(compiled) -> float:
    """Newton's coefficient of restitution e of ``compiled``'s unilateral constraints: the
    value of its ``restitution`` parameter, 1 (elastic) without one."""
    at = constraints.restitution_index(compiled.mechanics.scene)
    return 1.0 if at is None else float(compiled.parameters[at])


def _analyse(mechanics) -> ConstraintForces:
    scene = mechanics.scene
    t = mechanics.t
    reason = presence(scene)
    if reason is not None:
        return ConstraintForces(applies=False, reason=reason)
    pieces = constraints.rows(mechanics)  # every kind: holonomic, nonholonomic, unilateral
    k = pieces.k if pieces is not None else 0
    kinds = pieces.kinds if pieces is not None else ()
    impacts = "unilateral" in kinds
    transformation = scene.transformation if scene.particles else None
    dimension = len(transformation.positions[0]) if transformation is not None else 0

    notes = []
    effects = scene.enabled_effects()
    given_potential = _given_potential(scene)
    reactions_ok = transformation is not None and mechanics.mass_matrix is not None
    if transformation is not None:
        why = []
        if given_potential is not None:
            why.append(
                "the potential given beyond gravity is a function of the coordinates, and "
                "the Cartesian forces it puts on each particle are not known"
            )
        if effects:
            why.append(
                f"the effects ({', '.join(effects)}) are forces on the coordinates, not "
                "Cartesian forces on named particles"
            )
        if mechanics.mass_matrix is None:
            why.append("there is no mass matrix for the accelerations")
        if why:
            reactions_ok = False
            notes.append(
                "the particles' reaction forces R = m r'' - F are not computed: " + "; ".join(why)
            )
    rheonomic = pieces is not None and _moving(pieces, t)
    if reactions_ok:  # the power shown is the particles' reactions'
        rheonomic = rheonomic or transformation.depends_on_time
    functions: dict = {}
    params = tuple(mechanics.params[name] for name, _ in scene.parameters)
    arguments = (t, *mechanics.q, *mechanics.qdot, *params)

    def lam(exprs) -> Callable:
        return lambdify(arguments, [as_expr(e) for e in exprs], modules="numpy", cse=True)

    if k:
        functions["jacobian"] = lam(list(pieces.jacobian))
    if mechanics.mass_matrix is not None:  # the accelerations, with the multipliers
        functions["mass"] = lam(list(mechanics.mass_matrix))
        functions["forcing"] = lam(list(mechanics.forcing))
    if mechanics.momenta is not None:  # states between two rows (``interval_work``)
        functions["momenta"] = lam(list(mechanics.momenta))
    if mechanics.matrix_form is None:  # for a system compiled without its velocities
        q_p = (t, *mechanics.q, *mechanics.p, *params)
        functions["velocities"] = lambdify(
            q_p, [as_expr(e) for e in mechanics.velocities], modules="numpy"
        )
    energy_name, energy = "", None
    if reactions_ok:
        _particle_functions(functions, mechanics, transformation, lam, params)
        energy_name = "T + V"
        energy = mechanics.kinetic + mechanics.potential
    elif k:
        L = mechanics.lagrangian
        if effects:
            notes.append(f"no energy balance: the effects ({', '.join(effects)}) do work too")
        elif L is None or scene.kind == "hamiltonian":
            notes.append("no energy balance: the scene has no Lagrangian to form h from")
        elif depends_on_time([[L]], t):
            notes.append("no energy balance: the Lagrangian depends on t, so h changes anyway")
        else:
            energy = mechanics.energy_function()
            energy_name = "h" if energy is not None else ""
    if energy is not None:
        functions["energy"] = lam([energy])
    # the impacts' velocity jumps change the energy too (no force lambda describes them):
    # the energy is kept, to say what they changed, but the balance E - E0 = W is not
    balance = energy is not None and not impacts
    particles = transformation.names if reactions_ok else ()
    if not k and not particles:
        return ConstraintForces(
            applies=True,
            note="; ".join(notes),
            particles=(),
            dimension=dimension,
            _functions=functions,
        )
    points = () if particles or not k else _cartesian_points(scene)
    return ConstraintForces(
        applies=True,
        k=k,
        kinds=kinds,
        descriptions=_descriptions(scene, kinds),
        particles=particles,
        dimension=dimension,
        note="; ".join(notes),
        rheonomic=rheonomic,
        balance=balance,
        impacts=impacts,
        energy_name=energy_name,
        points=points,
        _functions=functions,
    )


def _particle_functions(functions, mechanics, transformation, lam, params) -> None:
    q, qd, t = mechanics.q, mechanics.qdot, mechanics.t
    columns, rates, bias = [], [], []
    for position in transformation.positions:
        for component in position:
            derivatives = [sympy.diff(component, x) for x in q]
            rate = sympy.diff(component, t)
            velocity = sum((c * v for c, v in zip(derivatives, qd, strict=True)), rate)
            rest = sum(
                (sympy.diff(velocity, x) * v for x, v in zip(q, qd, strict=True)),
                sympy.diff(velocity, t),
            )
            columns.extend(derivatives)
            rates.append(rate)
            bias.append(rest)
    functions["columns"] = lam(columns)
    functions["rates"] = lam(rates)
    functions["bias"] = lam(bias)
    functions["masses"] = lambdify(params, list(transformation.masses), modules="numpy")
    scene = mechanics.scene
    dimension = len(transformation.positions[0])
    if isinstance(scene.gravity, tuple):
        field_ = tuple(scene.expression(f"system.gravity[{i}]") for i in range(dimension))
    elif scene.gravity is not None:
        field_ = scene.expression("system.gravity")
    else:
        field_ = sympy.S.Zero
    g = gravity_vector(field_, dimension)
    functions["gravity"] = lambdify(params, [as_expr(c) for c in g], modules="numpy")


def _moving(pieces: constraints.Rows, t: sympy.Symbol) -> bool:
    """True if the constraint forces can have power: a holonomic or unilateral constraint
    with t, or a nonholonomic one whose velocity-free part b is not zero (its power is
    lambda^T b; a(q, t) with t alone gives none)."""
    positions = [
        v for kind, v in zip(pieces.kinds, pieces.values, strict=True) if kind != "nonholonomic"
    ]
    if depends_on_time([positions], t):
        return True
    free = [
        as_expr(b)
        for kind, b in zip(pieces.kinds, pieces.time_derivative, strict=True)
        if kind == "nonholonomic"
    ]
    return any(b != 0 and sympy.simplify(b) != 0 for b in free)


def _descriptions(scene, kinds: Sequence[str]) -> tuple[str, ...]:
    """What each multiplier belongs to: its kind, or a unilateral constraint itself."""
    walls = iter(scene.unilateral_constraints)
    return tuple(
        f"{' '.join(next(walls).split())} ≥ 0" if kind == "unilateral" else kind for kind in kinds
    )


def _given_potential(scene) -> sympy.Expr | None:
    """The ``potential`` a particle scene gives beyond gravity, or None (none, or zero)."""
    if scene.potential is None or not scene.particles:
        return None
    given = sympy.expand(scene.expression("system.potential") - scene.transformation.potential)
    return None if given == 0 else given


def _cartesian_points(scene) -> tuple[tuple[str, int, int], ...]:
    """Drawn points whose x and y are two of the coordinates, with their indices."""
    if scene.drawing is None:
        return ()
    names = list(scene.coordinates)
    found = []
    for name, x, y in scene.drawing.points:
        x, y = x.strip(), y.strip()
        if x in names and y in names and x != y:
            found.append((name, names.index(x), names.index(y)))
    return tuple(found)


# -- numerics ------------------------------------------------------------------------------


def _stack(function, args, N: int, shape: tuple[int, ...]) -> np.ndarray:
    """A lambdified list of expressions at N states, as an array (N, *shape)."""
    values = function(*args)
    if not isinstance(values, list | tuple):
        values = [values]
    columns = [np.broadcast_to(np.asarray(v, dtype=float), (N,)) for v in values]
    if not columns:
        return np.zeros((N, *shape))
    return np.stack(columns, axis=-1).reshape((N, *shape))


def _velocities(compiled, functions, ts, Y) -> np.ndarray:
    """qdot at the states, shape (N, n): the compiled kernel where it was built."""
    n = compiled.n
    if "velocities" in compiled.wanted:
        return compiled.velocities(ts, Y)
    function = functions.get("velocities")
    if function is not None:
        return _stack(function, (ts, *Y.T, *compiled.parameters), len(Y), (n,))
    raise ValueError("the velocities were not compiled (ask compile_system for 'velocities')")


def _solve(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with A x = b for each row, NaN where A is singular or not finite."""
    out = np.full(b.shape, np.nan)
    good = np.all(np.isfinite(A), axis=(1, 2)) & np.all(np.isfinite(b), axis=1)
    if good.any():
        try:
            out[good] = np.linalg.solve(A[good], b[good][..., None])[..., 0]
        except np.linalg.LinAlgError:
            for row in np.flatnonzero(good):
                try:
                    out[row] = np.linalg.solve(A[row], b[row])
                except np.linalg.LinAlgError:
                    pass
    return out


def _touching_free(compiled, t: np.ndarray, Y: np.ndarray, acting: np.ndarray) -> np.ndarray:
    """Rows (N,) on a unilateral constraint they do not act on (g = 0 to a contact's
    tolerance, ``constraints.CONTACT_GAP``): the state right after an impact, or a
    contact released."""
    numeric = compiled.constraints()
    g = numeric.values(t, Y)
    scale = np.maximum(1.0, np.max(np.abs(Y[:, : compiled.n]), axis=1))[:, None]
    unilateral = numeric.unilateral[None, :]
    return np.any(unilateral & ~acting & (np.abs(g) <= constraints.CONTACT_GAP * scale), axis=1)


def _tangent_directions(J: np.ndarray | None, acting: np.ndarray | None, N: int, n: int):
    """Orthonormal directions spanning the displacements tangent to the acting rows.

    Parameters
    ----------
    J : ndarray, shape (N, k, n), or None
        The rows A (None: no explicit constraint, every direction is tangent).
    acting : ndarray of bool, shape (N, k), or None

    Returns
    -------
    ndarray, shape (N, n, n)
        Columns: an orthonormal basis of null(A_acting) at each state (the right singular
        vectors past the rank), the other columns zero (they do no virtual work and move
        nothing, so they never count); NaN where the rows are not finite. The rank is
        counted, as a unilateral row in contact may depend on the others.
    """
    if J is None:
        return np.broadcast_to(np.eye(n), (N, n, n))
    k = J.shape[1]
    Ja = np.where(acting[:, :, None], J, 0.0)
    out = np.full((N, n, n), np.nan)
    good = np.all(np.isfinite(Ja), axis=(1, 2))
    if good.any():
        _, s, Vt = np.linalg.svd(Ja[good], full_matrices=True)
        largest_ = s[:, :1] if k else np.zeros((len(s), 1))
        rank = np.sum(s > constraints.RANK_TOLERANCE * largest_, axis=1)
        tangent = np.arange(n)[None, :] >= rank[:, None]
        out[good] = np.transpose(Vt * tangent[:, :, None], (0, 2, 1))
    return out


def _tangent_basis(J: np.ndarray, n: int) -> np.ndarray:
    """An orthonormal basis of the null space of each Phi_q (N, k, n): shape (N, n, n - k).

    The constraints are independent (``constraints.check``), so the last n - k right
    singular vectors span it; rows that are not finite give NaN.
    """
    N, k, _ = J.shape
    out = np.full((N, n, n - k), np.nan)
    good = np.all(np.isfinite(J), axis=(1, 2))
    if good.any():
        _, _, Vt = np.linalg.svd(J[good], full_matrices=True)
        out[good] = np.transpose(Vt[:, k:, :], (0, 2, 1))
    return out


def _quintic(s: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Quintic Hermite weights at s in [0, 1] of (q0, h v0, h**2 a0, q1, h v1, h**2 a1),
    for the value and for its derivative in s."""
    value = (
        1 - 10 * s**3 + 15 * s**4 - 6 * s**5,
        s - 6 * s**3 + 8 * s**4 - 3 * s**5,
        (s**2 - 3 * s**3 + 3 * s**4 - s**5) / 2,
        10 * s**3 - 15 * s**4 + 6 * s**5,
        -4 * s**3 + 7 * s**4 - 3 * s**5,
        (s**3 - 2 * s**4 + s**5) / 2,
    )
    slope = (
        -30 * s**2 + 60 * s**3 - 30 * s**4,
        1 - 18 * s**2 + 32 * s**3 - 15 * s**4,
        (2 * s - 9 * s**2 + 12 * s**3 - 5 * s**4) / 2,
        30 * s**2 - 60 * s**3 + 30 * s**4,
        -12 * s**2 + 28 * s**3 - 15 * s**4,
        (3 * s**2 - 8 * s**3 + 5 * s**4) / 2,
    )
    return value, slope


def _ratio(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a / b, and 0 where both are 0 (no force: nothing to compare)."""
    return np.where((a == 0) & (b == 0), 0.0, a / np.where(b == 0, np.nan, b))


def _empty(analysis: ConstraintForces, n: int) -> Forces:
    none = np.empty(0)
    return Forces(
        t=none,
        multipliers=np.empty((0, analysis.k)) if analysis.k else None,
        acting=np.empty((0, analysis.k), dtype=bool) if analysis.k else None,
        generalized=np.empty((0, n)),
        reactions=np.empty((0, len(analysis.particles), analysis.dimension))
        if analysis.particles
        else None,
        virtual_work=none,
        power=none,
        power_scale=none,
        energy=none if analysis.energy_name else None,
        velocities=np.empty((0, n)),
        accelerations=np.empty((0, n)),
    )


# -- the work ---------------------------------------------------------------------------------


class WorkIntegral:
    """The work of the constraint forces along one trajectory handed over in pieces.

    ``add(t, Y, energy)`` takes the next rows (gap rows included: rows were left out
    there) and returns W at each of them, carrying on from the last row seen by
    ``ConstraintForces.interval_work``. Over a gap the motion is not known: where the
    energy balance holds (``analysis.balance``) the work across it is the change of the
    energy, E(after) - E(before), exact by the balance; where no constraint moves
    (``analysis.rheonomic`` False) it is zero, the power vanishing identically (impacts
    or not: they are not forces lambda); otherwise W is unknown (NaN) from the gap on,
    never a wrong number.

    Parameters
    ----------
    analysis : ConstraintForces
    compiled : CompiledSystem
    """

    def __init__(self, analysis: ConstraintForces, compiled):
        self.analysis = analysis
        self.compiled = compiled
        self.bridge = analysis.balance
        self.reset()

    def reset(self) -> None:
        self.work = 0.0
        self.gaps = 0
        self._last: tuple[float, np.ndarray, _Rows] | None = None
        self._last_energy = math.nan
        self._started = False
        self._pending = False

    def add(
        self,
        t: np.ndarray,
        Y: np.ndarray,
        energy: np.ndarray | None = None,
        forces: Forces | None = None,
    ) -> np.ndarray:
        """W at the rows ``Y`` (k, 2n) at times ``t`` (k,).

        ``energy`` (k,) is the energy of the balance at each row (NaN at gap rows), needed
        to carry W over a gap; ``forces`` is ``evaluate`` of the rows that are not gaps,
        if the caller has it (it is not computed again).
        """
        t = np.asarray(t, dtype=float)
        Y = np.atleast_2d(np.asarray(Y, dtype=float))
        gap = ~np.all(np.isfinite(Y), axis=1)
        E = np.full(len(t), np.nan) if energy is None else np.asarray(energy, dtype=float)
        out = np.full(len(t), np.nan)
        if not len(t):
            return out
        if forces is None and (~gap).any():
            forces = self.analysis.evaluate(self.compiled, t[~gap], Y[~gap])
        if self._last is not None:
            times = np.concatenate([[self._last[0]], t])
            states = np.concatenate([self._last[1][None, :], Y])
            known = _joined(self._last[2], forces)
            increments = self.analysis.interval_work(self.compiled, times, states, known)
        else:
            increments = np.concatenate(
                [[np.nan], self.analysis.interval_work(self.compiled, t, Y, forces)]
            )
        for i in range(len(t)):
            if gap[i]:
                self._pending = self._pending or self._started
                continue
            if not self._started:  # the first state: W = 0 there
                self._started = True
            elif self._pending or not math.isfinite(increments[i]):
                self._pending = False
                self.gaps += 1
                if self.bridge and math.isfinite(self._last_energy) and math.isfinite(E[i]):
                    self.work += float(E[i]) - self._last_energy
                elif self.analysis.rheonomic:
                    self.work = math.nan
                # else: no power anywhere, no work across the gap
            else:
                self.work += float(increments[i])
            out[i] = self.work
            if math.isfinite(E[i]):
                self._last_energy = float(E[i])
        finite = np.flatnonzero(~gap)
        if len(finite):
            row = finite[-1]
            last = _Rows(
                forces.velocities[-1:].copy(),
                forces.accelerations[-1:].copy(),
                forces.power[-1:],
                None if forces.acting is None else forces.acting[-1:].copy(),
            )
            self._last = (float(t[row]), Y[row].copy(), last)
        return out


@dataclass(frozen=True)
class _Rows:
    """What ``interval_work`` uses of ``Forces``, for rows kept from one call to the next."""

    velocities: np.ndarray
    accelerations: np.ndarray
    power: np.ndarray
    acting: np.ndarray | None = None


def _joined(first: _Rows, rest: Forces | None) -> _Rows:
    if rest is None:
        return first
    acting = None
    if first.acting is not None and rest.acting is not None:
        acting = np.concatenate([first.acting, rest.acting])
    return _Rows(
        np.concatenate([first.velocities, rest.velocities]),
        np.concatenate([first.accelerations, rest.accelerations]),
        np.concatenate([first.power, rest.power]),
        acting,
    )


def tangent_basis(J: np.ndarray) -> np.ndarray:
    """An orthonormal basis of the displacements tangent to the constraints.

    Parameters
    ----------
    J : ndarray, shape (N, k, n)
        Phi_q at N states, of rank k.

    Returns
    -------
    ndarray, shape (N, n, n - k)
    """
    J = np.asarray(J, dtype=float)
    return _tangent_basis(J, J.shape[2])


def largest(values: Sequence[float] | np.ndarray) -> float:
    """The largest finite value (NaN if none)."""
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    return float(values.max()) if len(values) else float("nan")
