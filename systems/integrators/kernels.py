# ruff: noqa: F821
# The templates below use the named codes of ``systems.integrators.codes`` (``STATUS_*``,
# ``CLOCK_*``, ``INFO_*``) by global name. ``systems.codegen`` copies everything after the
# marker line into one generated module, the same for every scene, next to those
# constants, and wraps every top-level function in ``numba.njit`` (cached on disk).
"""Kernel templates: one step function per method family, one driver for all of them.

This module is imported only for its source text (``systems.codegen.template_source``);
the functions are never called from here. They are compiled once per installation, not
once per scene: a scene's own functions (``rhs``, ``grad_potential``, ``c_project``, ...,
compiled by ``systems.compiled``) come in as the tuple ``fns`` of numba first-class
functions, in the order the family declares (``Family.functions`` in
``systems.integrators.registry``).

A family ``X`` provides two functions:

- ``X_work(coef, m)``: a tuple of arrays the steps keep between calls (stage guesses, a
  first-same-as-last gradient) and use as scratch space, for a state of size ``m``. Its
  last array is a flag: the driver zeroes its first entry when it undoes a step, and the
  step then recomputes what it would have carried over;
- ``X_step(fns, y, comp, clock, P, coef, work) -> (status, evaluations)``: one step from the
  state ``y`` (shape ``(m,)``, advanced in place, with Kahan compensation terms ``comp``
  where ``coef`` asks for them) at ``clock[CLOCK_T]`` with step ``clock[CLOCK_H]``; it
  advances the clock itself (fixed steps as ``T0 + K H``, others by compensated sums).
  ``coef`` is the family's tuple of constants (tableau, tolerances, switches);
- ``X_sample(fns, prev, state, s, P, coef, work, swork, scratch, first) -> (status,
  evaluations)``: the state at time ``s`` inside the step just taken (from ``prev =
  (y, comp, clock)`` at its start to ``state`` at its end) into ``scratch[0]``, as
  accurate as the step itself, without changing ``state`` or ``work`` (``work`` is only
  read: what the step carried over stays); ``swork = X_sample_work(coef, m)`` and
  ``scratch = (y, comp, clock)`` are its own scratch. ``first``: the first sample inside
  this step (what is shared between the samples of a step is computed then).

The driver templates ``DRIVER_run``, ``DRIVER_ensemble_parallel``,
``DRIVER_ensemble_adaptive_parallel`` and ``DRIVER_fictitious`` (the samples of the
families that step in a fictitious time) are instantiated per family by
``systems.codegen`` (``DRIVER_`` -> ``X_``, ``STEP`` -> ``X_step``, ``WORK`` ->
``X_work``, ``SAMPLE`` -> ``X_sample``, ``SAMPLE_WORK`` -> ``X_sample_work``), so numba
compiles each as a plain function calling globals (which it can cache on disk); the
``fns`` argument is the same type for every scene, so the machine code is too. The
driver owns what every
method shares: rollback of a step that failed or went non-finite, the end time (never
passed) and the pause time, section crossings, strided output, the states at requested
times (``X_sample``) and the counters.
"""

import math

import numpy as np
from numba import prange

# --- kernels ---


def _finite(y):
    acc = 0.0
    for k in range(y.shape[0]):
        acc += y[k] * 0.0
    return acc == 0.0


def _add(x, comp, k, d, kahan):
    """x[k] += d, with Kahan compensation in comp[k] when ``kahan``."""
    if kahan:
        dd = d - comp[k]
        s = x[k] + dd
        comp[k] = (s - x[k]) - dd
        x[k] = s
    else:
        x[k] += d


def _tick_fixed(clock):
    clock[CLOCK_K] += 1.0
    clock[CLOCK_T] = clock[CLOCK_T0] + clock[CLOCK_K] * clock[CLOCK_H]


def _tick(clock, dt):
    dd = dt - clock[CLOCK_TC]
    s = clock[CLOCK_T] + dd
    clock[CLOCK_TC] = (s - clock[CLOCK_T]) - dd
    clock[CLOCK_T] = s


def _crossed(before, after, direction):
    if direction >= 0 and before < 0.0 and after >= 0.0:
        return True
    if direction <= 0 and before > 0.0 and after <= 0.0:
        return True
    return False


def _combine(M, Z, out):
    """out = M @ Z for M (s, s) and Z (s, m)."""
    for j in range(M.shape[0]):
        for k in range(Z.shape[1]):
            acc = 0.0
            for l in range(M.shape[1]):
                acc += M[j, l] * Z[l, k]
            out[j, k] = acc


def _restart(prev, s, scratch):
    """Copy the state at the start of the last step (``prev = (y, comp, clock)``) into
    ``scratch`` with its clock set for one fixed step from there to the time ``s``."""
    yprev, cprev, kprev = prev
    ys, cs, ks = scratch
    for k in range(yprev.shape[0]):
        ys[k] = yprev[k]
        cs[k] = cprev[k]
    for k in range(kprev.shape[0]):
        ks[k] = kprev[k]
    ks[CLOCK_T0] = kprev[CLOCK_T]
    ks[CLOCK_K] = 0.0
    ks[CLOCK_H] = s - kprev[CLOCK_T]


def _elapsed(kprev, ks):
    """The physical time from ``kprev`` to ``ks`` of clocks advanced by ``_tick``
    (compensated sums: the true time is T - TC)."""
    return (ks[CLOCK_T] - kprev[CLOCK_T]) - (ks[CLOCK_TC] - kprev[CLOCK_TC])


TT_ITERATIONS = 40


def _illinois(bracket, sigma, f):
    """One regula falsi (Illinois) update of ``bracket = [lo, f(lo), hi, f(hi), side]``
    with the value ``f`` at ``sigma``; returns the next trial."""
    if f > 0.0:
        bracket[2] = sigma
        bracket[3] = f
        if bracket[4] == 1.0:
            bracket[1] *= 0.5
        bracket[4] = 1.0
    else:
        bracket[0] = sigma
        bracket[1] = f
        if bracket[4] == -1.0:
            bracket[3] *= 0.5
        bracket[4] = -1.0
    lo, flo, hi, fhi = bracket[0], bracket[1], bracket[2], bracket[3]
    nxt = lo - flo * (hi - lo) / (fhi - flo)
    if not (lo < nxt and nxt < hi):
        nxt = 0.5 * (lo + hi)
    return nxt


# -- explicit Runge-Kutta (Euler, classical RK4: teaching methods) -----------------------


def _rk_stages(rhs, t, y, P, h, tableau, buffers, stages):
    """Explicit stages ``first`` .. ``last - 1`` (``stages``) of a Runge-Kutta step with
    ``tableau = (A, c)`` into the rows of ``K``, for ``buffers = (K, Yst)``."""
    A, c = tableau
    K, Yst = buffers
    first, last = stages
    for i in range(first, last):
        for k in range(y.shape[0]):
            acc = 0.0
            for j in range(i):
                acc += A[i, j] * K[j, k]
            Yst[k] = y[k] + h * acc
        rhs(t + c[i] * h, Yst, P, K[i])


def _rk_sum(K, b, k):
    """Component ``k`` of the weighted sum of the stages, sum_j b_j K[j, k]."""
    acc = 0.0
    for j in range(b.shape[0]):
        acc += b[j] * K[j, k]
    return acc


def erk_work(coef, m):
    s = coef[0].shape[0]
    return (np.empty((s, m)), np.empty(m), np.zeros(1))


def erk_step(fns, y, comp, clock, P, coef, work):
    """An explicit Runge-Kutta step with tableau ``(A, b, c)`` on ``rhs``."""
    A, b, c, kahan = coef
    K, Yst, _ = work
    s = b.shape[0]
    m = y.shape[0]
    t = clock[CLOCK_T]
    h = clock[CLOCK_H]
    _rk_stages(fns[0], t, y, P, h, (A, c), (K, Yst), (0, s))
    for k in range(m):
        _add(y, comp, k, h * _rk_sum(K, b, k), kahan)
    _tick_fixed(clock)
    return STATUS_RUNNING, s


def erk_sample_work(coef, m):
    return erk_work(coef, m)


def erk_sample(fns, prev, state, s, P, coef, work, swork, scratch, first):
    """The state at ``s``: one step of the same method from the start of the last step,
    of length ``s - t`` (the method's own accuracy)."""
    _restart(prev, s, scratch)
    return erk_step(fns, scratch[0], scratch[1], scratch[2], P, coef, swork)


# -- compositions of the kick-drift-kick leapfrog, H = T(p) + V(q, t) ----------------------


def compose_work(coef, m):
    n = m // 2
    return (np.empty(n), np.empty(n), np.zeros(1))


def compose_step(fns, y, comp, clock, P, coef, work):
    """Leapfrog composition with merged stage coefficients ``kick`` (s + 1,), ``drift`` (s,).

    One gradient of V per stage: the last of a step is the first of the next (kept in
    ``work``). Time advances with the drifts, so V may depend on t.
    """
    grad_kinetic, grad_potential = fns
    kick, drift, kahan = coef
    F, G, valid = work
    n = y.shape[0] // 2
    h = clock[CLOCK_H]
    tau = clock[CLOCK_T]
    evals = 0
    if valid[0] == 0.0:
        grad_potential(tau, y, P, F)
        evals += 1
        valid[0] = 1.0
    ns = drift.shape[0]
    for j in range(ns + 1):
        a = kick[j] * h
        for k in range(n):
            _add(y, comp, n + k, -a * F[k], kahan)
        if j < ns:
            a = drift[j] * h
            grad_kinetic(y, P, G)
            for k in range(n):
                _add(y, comp, k, a * G[k], kahan)
            tau += a
            grad_potential(tau, y, P, F)
            evals += 1
    _tick_fixed(clock)
    return STATUS_RUNNING, evals


def compose_sample_work(coef, m):
    return compose_work(coef, m)


def compose_sample(fns, prev, state, s, P, coef, work, swork, scratch, first):
    """The state at ``s``: one composition step of length ``s - t`` from the start of the
    last step (its gradient computed afresh in ``swork``)."""
    _restart(prev, s, scratch)
    swork[-1][0] = 0.0
    return compose_step(fns, scratch[0], scratch[1], scratch[2], P, coef, swork)


# The same compositions with the stage loop in the scene's own code: ``fns =
# (grad_potential, compose_stages)``, the second written by the LLVM backend
# (``systems.llvm_kernels``) with both gradients inline, so a step makes one call of the
# scene's code instead of two per stage (4-5 ns each on the pendulum: a call through a
# function pointer cannot be inlined). ``compose_stages(tau, h, y, comp, P, F, G, kick,
# drift, ns, kahan)`` (the arrays as the addresses of their data: seven of numba's array
# structures by value were 392 bytes copied a call) is ``compose_step``'s loop ``for j
# in range(ns + 1)``, the same operations in the same order: the results are bitwise
# compose_step's.


def composef_work(coef, m):
    return compose_work(coef, m)


def composef_step(fns, y, comp, clock, P, coef, work):
    """``compose_step`` with its stages in one call of the scene's ``compose_stages``."""
    grad_potential, compose_stages = fns
    kick, drift, kahan = coef
    F, G, valid = work
    tau = clock[CLOCK_T]
    evals = 0
    if valid[0] == 0.0:
        grad_potential(tau, y, P, F)
        evals += 1
        valid[0] = 1.0
    ns = drift.shape[0]
    compose_stages(
        tau, clock[CLOCK_H], y.ctypes.data, comp.ctypes.data, P.ctypes.data, F.ctypes.data,
        G.ctypes.data, kick.ctypes.data, drift.ctypes.data, ns, 1 if kahan else 0,
    )  # fmt: skip
    _tick_fixed(clock)
    return STATUS_RUNNING, evals + ns


def composef_sample_work(coef, m):
    return compose_work(coef, m)


def composef_sample(fns, prev, state, s, P, coef, work, swork, scratch, first):
    """As ``compose_sample``, with ``composef_step``."""
    _restart(prev, s, scratch)
    swork[-1][0] = 0.0
    return composef_step(fns, scratch[0], scratch[1], scratch[2], P, coef, swork)


# -- logarithmic-Hamiltonian compositions (Mikkola-Tanikawa, Preto-Tremaine) ---------------


def logh_work(coef, m):
    return compose_work(coef, m)


def logh_step(fns, y, comp, clock, P, coef, work):
    """One fictitious-time step ``ds = clock[CLOCK_H]`` of a log-H leapfrog composition.

    Time is a coordinate with momentum ``-energy``: drifts advance q and t by
    ``kick ds / (T - E)``, kicks p by ``drift ds / (-V)``, both positive only while V < 0
    (attractive singular potentials such as -k/r); otherwise ``STATUS_BAD_TRANSFORM``.
    For autonomous separable H = T(p) + V(q).
    """
    kinetic, potential, grad_kinetic, grad_potential = fns
    kick, drift, energy, kahan = coef
    F, G, _ = work
    n = y.shape[0] // 2
    ds = clock[CLOCK_H]
    evals = 0
    ns = drift.shape[0]
    for j in range(ns + 1):
        w = kinetic(y, P) - energy
        if not w > 0.0:
            return STATUS_BAD_TRANSFORM, evals
        h = kick[j] * ds / w
        grad_kinetic(y, P, G)
        for k in range(n):
            _add(y, comp, k, h * G[k], kahan)
        _tick(clock, h)
        if j < ns:
            u = -potential(clock[CLOCK_T], y, P)
            if not u > 0.0:
                return STATUS_BAD_TRANSFORM, evals
            h = drift[j] * ds / u
            grad_potential(clock[CLOCK_T], y, P, F)
            evals += 1
            for k in range(n):
                _add(y, comp, n + k, -h * F[k], kahan)
    return STATUS_RUNNING, evals


def logh_sample_work(coef, m):
    return (compose_work(coef, m), np.zeros(5))


def logh_sample(fns, prev, state, s, P, coef, work, swork, scratch, first):
    """The state at ``s``: the fictitious step from the start of the last step whose
    physical duration is ``s - t`` (``logh_fictitious``): each trial is one step of the
    method, so the sample has the method's accuracy, at a time within a few units of
    round-off of ``s``."""
    return logh_fictitious(fns, prev, state, s, P, coef, swork, scratch)


# -- Gauss-Legendre collocation, any rhs -----------------------------------------------------
#
# Round-off grows like sqrt(t) (Brouwer's law) only if nothing in a step is biased
# (Hairer, McLachlan & Razakarivony, BIT 48, 2008): the fixed-point iteration runs until it
# stops improving, not to a tolerance; the stages see the compensated state y - comp; the
# stage increments are Z_i = sum_j MU_ij (h b_j) F_j with MU_ij = a_ij / b_j, whose pairs
# MU_ij + MU_ji = 1 hold exactly in floating point (so the rounded method is still
# symplectic); and the products and sums of h b_j F_j are formed without rounding error.


def _two_prod(a, b):
    """(p, e) with p = fl(a b) and a b = p + e exactly (Dekker)."""
    p = a * b
    t = 134217729.0 * a
    ah = t - (t - a)
    al = a - ah
    t = 134217729.0 * b
    bh = t - (t - b)
    bl = b - bh
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


def _two_sum(a, b):
    """(s, e) with s = fl(a + b) and a + b = s + e exactly (Knuth)."""
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def _stage_rates(rhs, t, y, comp, P, stages, scaling):
    """f (and the Sundman factor g) at the stages y - comp + Z_i, into ``F`` (and ``G``)."""
    Z, Zlo, F, Yst, hb, T, G, _, _ = stages
    fscale, power = scaling
    for i in range(Z.shape[0]):
        for k in range(y.shape[0]):
            Yst[k] = y[k] + (Z[i, k] + (Zlo[i, k] - comp[k]))
        rhs(t + T[i, 0], Yst, P, F[i])
        if power > 0.0:
            G[i] = _rate(F[i], fscale, power)


def _collocate(rhs, t, y, comp, P, MU, stages, scaling, maxit):
    """Solve a collocation step for its stage increments by fixed-point iteration.

    ``stages = (Z, Zlo, F, Yst, hb, T, G, PH, PL)``: increments ``Z`` (s, m) with their
    low-order parts ``Zlo``, starting from the guess in them; f at the stages ``F``
    (s, m); scratch ``Yst`` (m,), ``PH`` and ``PL`` (s, m); ``hb`` (s,) the step times the
    weights; stage time offsets ``T`` (s, 1) and rhs scales ``G`` (s,).
    ``scaling = (fscale, power)``: power 0 leaves ``T`` and ``G`` as given (plain
    collocation, ``T = c h``, ``G = 1``); otherwise the stages follow the Sundman
    transformation g = (fscale / |f|)^power, with ``T`` solved too. Returns (iterations,
    converged); on success ``F`` and ``G`` belong to the final stages.
    """
    Z, Zlo, F, Yst, hb, T, G, PH, PL = stages
    fscale, power = scaling
    s = MU.shape[0]
    m = y.shape[0]
    prev = np.inf
    converged = False
    exact = False  # plain sums until near the fixed point, then error-free ones to the end
    it = 0
    diff = 0.0
    while it < maxit:
        it += 1
        _stage_rates(rhs, t, y, comp, P, stages, scaling)
        diff = 0.0
        if exact:
            for j in range(s):
                for k in range(m):  # h b_j g_j f_j, split exactly into high and low parts
                    PH[j, k], PL[j, k] = _two_prod(hb[j], F[j, k] * G[j])
        for i in range(s):
            if power > 0.0:
                acc = 0.0
                for j in range(s):
                    acc += MU[i, j] * hb[j] * G[j]
                T[i, 0] = acc
            for k in range(m):
                hi = 0.0
                lo = 0.0
                if exact:
                    for j in range(s):
                        mh, ml = _two_prod(MU[i, j], PH[j, k])
                        hi, e = _two_sum(hi, mh)
                        lo += ml + e + MU[i, j] * PL[j, k]
                else:
                    for j in range(s):
                        hi += MU[i, j] * (hb[j] * (F[j, k] * G[j]))
                z = hi + lo
                d = abs(z - Z[i, k]) / (1.0 + abs(y[k]))
                if d > diff:
                    diff = d
                Z[i, k] = z
                Zlo[i, k] = lo - (z - hi)
        if not diff == diff:
            break
        near = diff == 0.0 or (diff >= prev and diff < 1e-10)
        if not exact and (near or diff < 1e-12):
            exact = True
            prev = np.inf
            continue
        if near:
            converged = True  # round-off level: further iterations only wander
            break
        prev = diff
    if not converged and diff < 1e-10:
        converged = True
    if converged:
        _stage_rates(rhs, t, y, comp, P, stages, scaling)
        it += 1
    return it, converged


def _collocation_update(y, comp, hb, F, G, kahan):
    """y += sum_j hb_j G_j F_j, summed without rounding error into the compensated state."""
    for k in range(y.shape[0]):
        if not kahan:
            acc = 0.0
            for j in range(hb.shape[0]):
                acc += hb[j] * G[j] * F[j, k]
            y[k] += acc
            continue
        hi = 0.0
        lo = -comp[k]
        for j in range(hb.shape[0]):
            ph, pl = _two_prod(hb[j], F[j, k] * G[j])
            hi, e = _two_sum(hi, ph)
            lo += pl + e
        yn, e = _two_sum(y[k], hi)
        lo += e
        yh = yn + lo
        comp[k] = (yh - yn) - lo
        y[k] = yh


def _extrapolate(E, Z, Zlo, Zold):
    """The next step's starting guess: ``Z`` continued by ``E``, low parts cleared."""
    for j in range(Z.shape[0]):
        for k in range(Z.shape[1]):
            Zold[j, k] = Z[j, k]
            Zlo[j, k] = 0.0
    _combine(E, Zold, Z)


def _collocation_work(coef, m):
    s = coef[0].shape[0]
    # Z, Zlo, F, Yst, hb, T, G, PH, PL, Zold, Told, and the guess flag (the step it was
    # made for)
    return (
        np.zeros((s, m)),
        np.zeros((s, m)),
        np.empty((s, m)),
        np.empty(m),
        np.empty(s),
        np.zeros((s, 1)),
        np.ones(s),
        np.empty((s, m)),
        np.empty((s, m)),
        np.empty((s, m)),
        np.empty((s, 1)),
        np.zeros(1),
    )


def gauss_work(coef, m):
    return _collocation_work(coef, m)


def gauss_step(fns, y, comp, clock, P, coef, work):
    """Gauss-Legendre collocation with ``s`` stages (order 2s): ``MU`` (s, s) the tableau
    as a_ij / b_j, ``b``, ``c`` (s,), and ``E`` (s, s), which continues a step's
    collocation polynomial to the starting guess of the next step's stage increments."""
    rhs = fns[0]
    MU, b, c, E, maxit, kahan = coef
    Z, Zlo, F, Yst, hb, T, G, PH, PL, Zold, _, guess_h = work
    s = b.shape[0]
    t = clock[CLOCK_T]
    h = clock[CLOCK_H]
    evals = 0
    if guess_h[0] != h:
        rhs(t, y, P, F[0])
        evals += 1
        for j in range(s):
            hb[j] = h * b[j]
            T[j, 0] = c[j] * h
            for k in range(y.shape[0]):
                Z[j, k] = c[j] * h * F[0, k]
                Zlo[j, k] = 0.0
    stages = (Z, Zlo, F, Yst, hb, T, G, PH, PL)
    its, ok = _collocate(rhs, t, y, comp, P, MU, stages, (1.0, 0.0), maxit)
    evals += its * s
    if not ok:
        guess_h[0] = 0.0
        return STATUS_NOT_CONVERGED, evals
    _collocation_update(y, comp, hb, F, G, kahan)
    _extrapolate(E, Z, Zlo, Zold)
    guess_h[0] = h
    _tick_fixed(clock)
    return STATUS_RUNNING, evals


def gauss_sample_work(coef, m):
    return _collocation_work(coef, m)


def gauss_sample(fns, prev, state, s, P, coef, work, swork, scratch, first):
    """The state at ``s``: one collocation step of length ``s - t`` from the start of the
    last step (the method's own accuracy), its stages started from the last step's
    collocation polynomial (``Zold`` in ``work``, only read) at ``c_i (s - t)``. Unlike a
    step of the trajectory, nothing is carried on from it: the fixed-point iteration
    stops at round-off with plain sums (no error-free ones: the sample is not stepped
    from) and the update takes the stage rates of the last iterate."""
    rhs = fns[0]
    MU, b, c, E, maxit, kahan = coef
    Zold = work[9]
    Z, _, F, Yst, hb, _, _, _, _, _, _, _ = swork
    yprev, _, kprev = prev
    t0 = kprev[CLOCK_T]
    h = s - t0
    theta = h / kprev[CLOCK_H]
    ns = b.shape[0]
    m = yprev.shape[0]
    for i in range(ns):
        x = c[i] * theta
        for k in range(m):
            Z[i, k] = 0.0
        for j in range(ns):
            w = x / c[j]  # Lagrange basis on the nodes 0, c_1 .. c_s (the polynomial is 0 at 0)
            for l in range(ns):
                if l != j:
                    w *= (x - c[l]) / (c[j] - c[l])
            for k in range(m):
                Z[i, k] += w * Zold[j, k]
        hb[i] = h * b[i]
    evals = 0
    previous = np.inf
    converged = False
    for _ in range(maxit):
        for i in range(ns):
            for k in range(m):
                Yst[k] = yprev[k] + Z[i, k]
            rhs(t0 + c[i] * h, Yst, P, F[i])
        evals += ns
        diff = 0.0
        for i in range(ns):
            for k in range(m):
                acc = 0.0
                for j in range(ns):
                    acc += MU[i, j] * (hb[j] * F[j, k])
                d = abs(acc - Z[i, k]) / (1.0 + abs(yprev[k]))
                if d > diff:
                    diff = d
                Z[i, k] = acc
        if not diff == diff:
            break
        if diff <= 1e-15 or (diff >= previous and diff < 1e-10):
            converged = True
            break
        previous = diff
    if not converged:
        return STATUS_NOT_CONVERGED, evals
    ys = scratch[0]
    for k in range(m):
        acc = 0.0
        for j in range(ns):
            acc += hb[j] * F[j, k]
        ys[k] = yprev[k] + acc
    return STATUS_RUNNING, evals


# -- Gauss-Legendre on the Sundman-transformed system ----------------------------------------


def _rate(f, fscale, power):
    """Sundman time-transformation factor g = (|f0| / |f|)^power of a state with rhs f."""
    acc = 0.0
    for k in range(f.shape[0]):
        acc += f[k] * f[k]
    norm = math.sqrt(acc)
    if norm == 0.0:
        return 1e3
    return min((fscale / norm) ** power, 1e3)


def gauss_tt_work(coef, m):
    return _collocation_work(coef, m)


def gauss_tt_step(fns, y, comp, clock, P, coef, work):
    """Gauss-Legendre collocation in fictitious time s: dy/ds = g(y) f(t, y), dt/ds = g(y),
    with g = (fscale / |f(y)|)^power (g ~ r^1.5 near a 1/r singularity for power 3/4).

    A symmetric method on a reversible system: energy errors stay bounded on Kepler-like
    orbits though the map is not symplectic. ``ds = clock[CLOCK_H]``.
    """
    rhs = fns[0]
    MU, b, c, E, maxit, fscale, power = coef
    Z, Zlo, F, Yst, hb, T, G, PH, PL, Zold, Told, valid = work
    s = b.shape[0]
    t = clock[CLOCK_T]
    ds = clock[CLOCK_H]
    evals = 0
    if valid[0] == 0.0:
        rhs(t, y, P, F[0])
        evals += 1
        g0 = _rate(F[0], fscale, power)
        for j in range(s):
            hb[j] = ds * b[j]
            T[j, 0] = c[j] * ds * g0
            for k in range(y.shape[0]):
                Z[j, k] = c[j] * ds * g0 * F[0, k]
                Zlo[j, k] = 0.0
    stages = (Z, Zlo, F, Yst, hb, T, G, PH, PL)
    its, ok = _collocate(rhs, t, y, comp, P, MU, stages, (fscale, power), maxit)
    evals += its * s
    if not ok:
        valid[0] = 0.0
        return STATUS_NOT_CONVERGED, evals
    dt = 0.0
    for j in range(s):
        dt += hb[j] * G[j]
    _collocation_update(y, comp, hb, F, G, True)
    _tick(clock, dt)
    _extrapolate(E, Z, Zlo, Zold)
    for j in range(s):
        Told[j, 0] = T[j, 0]
    _combine(E, Told, T)
    valid[0] = 1.0
    return STATUS_RUNNING, evals


def gauss_tt_sample_work(coef, m):
    return (_collocation_work(coef, m), np.zeros(5))


def gauss_tt_sample(fns, prev, state, s, P, coef, work, swork, scratch, first):
    """The state at ``s``: the fictitious step from the start of the last step whose
    physical duration is ``s - t`` (``gauss_tt_fictitious``); every trial is a step of
    the method from a fresh guess, so the sample has the method's accuracy, at a time
    within a few units of round-off of ``s``."""
    return gauss_tt_fictitious(fns, prev, state, s, P, coef, swork, scratch)


# -- Dormand-Prince 8(5,3), adaptive ---------------------------------------------------------


def _dop853_norm(K, E5, E3, h, y, ynew, rtol, atol):
    m = y.shape[0]
    e5 = 0.0
    e3 = 0.0
    for k in range(m):
        sc = atol + rtol * max(abs(y[k]), abs(ynew[k]))
        a5 = 0.0
        a3 = 0.0
        for j in range(E5.shape[0]):  # K has a row more (dop853_work)
            a5 += K[j, k] * E5[j]
            a3 += K[j, k] * E3[j]
        a5 /= sc
        a3 /= sc
        e5 += a5 * a5
        e3 += a3 * a3
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * m)


def dop853_work(coef, m):
    S = coef[1].shape[0]
    # K (f at the start, the stages, f at the end; row S + 1: f at the start of the last
    # accepted step, for the dense output), ynew, ys, flags [K[0] valid, last rejected]
    return (np.empty((S + 2, m)), np.empty(m), np.empty(m), np.zeros(2))


def dop853_step(fns, y, comp, clock, P, coef, work):
    """A trial step of Dormand-Prince 8(5,3) with Hairer's error control.

    ``A`` (12, 12), ``B`` (12,), ``C`` (12,), ``E3``/``E5`` (13,) are the coefficients of
    ``scipy.integrate._ivp.dop853_coefficients``. Returns ``STATUS_REJECTED`` with a
    smaller ``clock[CLOCK_H]`` when the error is too large; never steps past the end time.
    The next step is at most ``hmax``: motion DOP853 integrates exactly (a free flight)
    would otherwise be crossed in one step, and a drawing of the states would skip it.
    """
    rhs = fns[0]
    A, B, C, E3, E5, _, _, _, rtol, atol, hmax = coef
    K, ynew, ys, flags = work
    t = clock[CLOCK_T]
    evals = 0
    if flags[0] == 0.0:  # K[0] is f at the start of the step (first same as last)
        rhs(t, y, P, K[0])
        evals += 1
        flags[0] = 1.0
    m = y.shape[0]
    S = B.shape[0]
    h = clock[CLOCK_H]
    t_end = clock[CLOCK_T_END]
    last = h >= t_end - t
    if last:
        h = t_end - t
    if h < 1e-14 * max(abs(t), 1.0) * 4.0:
        return STATUS_STEP_COLLAPSED, evals
    _rk_stages(rhs, t, y, P, h, (A, C), (K, ys), (1, S))
    for k in range(m):
        ynew[k] = y[k] + h * _rk_sum(K, B, k)
    rhs(t + h, ynew, P, K[S])
    evals += S
    err = _dop853_norm(K, E5, E3, h, y, ynew, rtol, atol)
    if not err == err or not _finite(ynew):
        clock[CLOCK_H] = h * 0.2
        flags[1] = 1.0
        return STATUS_REJECTED, evals
    if err >= 1.0:
        clock[CLOCK_H] = h * max(0.2, 0.9 * err ** (-1.0 / 8.0))
        flags[1] = 1.0
        return STATUS_REJECTED, evals
    factor = 10.0 if err == 0.0 else min(10.0, 0.9 * err ** (-1.0 / 8.0))
    if flags[1] != 0.0:
        factor = min(1.0, factor)
    for k in range(m):
        y[k] = ynew[k]
        K[S + 1, k] = K[0, k]
        K[0, k] = K[S, k]
    clock[CLOCK_T] = t_end if last else t + h
    clock[CLOCK_H] = min(h * factor, hmax)
    flags[1] = 0.0
    return STATUS_RUNNING, evals


def dop853_sample_work(coef, m):
    AX = coef[5]
    # the extended stages, the interpolant's coefficients (7, m), a stage's state
    return (np.empty((AX.shape[1], m)), np.empty((7, m)), np.empty(m))


def _dop853_dense(rhs, prev, state, P, coef, K, swork):
    """The dense output's coefficients ``F`` (7, m) of the last step from ``prev`` to
    ``state``: its three extra stages, then ``F`` (scipy's ``_dense_output_impl``)."""
    AX, CX, D = coef[5], coef[6], coef[7]
    Kx, F, ys = swork
    yprev, _, kprev = prev
    ynew = state[0]
    t0 = kprev[CLOCK_T]
    h = state[2][CLOCK_T] - t0
    m = yprev.shape[0]
    S = coef[1].shape[0]
    for k in range(m):
        Kx[0, k] = K[S + 1, k]
        for j in range(1, S + 1):
            Kx[j, k] = K[j, k]
    for e in range(AX.shape[0]):
        stage = S + 1 + e
        for k in range(m):
            acc = 0.0
            for j in range(stage):
                acc += AX[e, j] * Kx[j, k]
            ys[k] = yprev[k] + h * acc
        rhs(t0 + CX[e] * h, ys, P, Kx[stage])
    for k in range(m):
        delta = ynew[k] - yprev[k]
        F[0, k] = delta
        F[1, k] = h * Kx[0, k] - delta
        F[2, k] = 2.0 * delta - h * (Kx[S, k] + Kx[0, k])
        for r in range(D.shape[0]):
            acc = 0.0
            for j in range(Kx.shape[0]):
                acc += D[r, j] * Kx[j, k]
            F[3 + r, k] = h * acc
    return AX.shape[0]


def dop853_sample(fns, prev, state, s, P, coef, work, swork, scratch, first):
    """The state at ``s`` from DOP853's dense output of the last step (Hairer's 7th-order
    interpolant, scipy's ``Dop853DenseOutput``): once per step, three more stages and the
    coefficients ``F`` (``_dop853_dense``), then each sample a polynomial in (s - t) / h.
    Its error is of the order of the tolerance, one order below the steps' (see
    docs/internals.md)."""
    evals = 0
    if first:
        evals = _dop853_dense(fns[0], prev, state, P, coef, work[0], swork)
    F = swork[1]
    yprev = prev[0]
    t0 = prev[2][CLOCK_T]
    x = (s - t0) / (state[2][CLOCK_T] - t0)
    w = 1.0 - x
    out = scratch[0]
    for k in range(yprev.shape[0]):  # scipy's loop over F's rows, written out
        v = F[5, k] + x * F[6, k]
        v = F[3, k] + x * (F[4, k] + w * v)
        v = F[1, k] + x * (F[2, k] + w * v)
        out[k] = yprev[k] + x * (F[0, k] + w * v)
    return STATUS_RUNNING, evals


# -- Taylor series of adaptive order (Jorba & Zou), the coefficients from the derivation --------
# fns = (taylor_coefficients, taylor_double): the scene's coefficient function
# (systems.taylor.compiled) and its orders 1 and 2 in double-double (systems.taylor.double:
# built only when asked, else a function that is never called), coef = (width, kahan,
# order, hmax, factor, double): the columns of its out (m + nodes), compensated sums, the
# order p (from the tolerance: Jorba and Zou's ceil(-ln(tol)/2 + 1)), the longest step,
# exp(-0.7 / (p - 1)) / e^2 (heyoka's safety factor), and whether the state and orders 1
# and 2 are double-double (runners.TaylorRunner: a tolerance below machine epsilon).


def taylor_work(coef, m):
    width = coef[0]
    order = coef[2]
    # the coefficients of the last step (order + 1, width): its dense output; orders 1
    # and 2 in double-double (4, m: taylor_double's out); flags [coefficients valid]
    return (np.empty((order + 1, width)), np.zeros((4, m)), np.zeros(1))


def _taylor_horner(C, order, i, h):
    """sum_{k=1}^{order} C[k, i] h^k (the increment over C[0, i]; order >= 2), as
    (O(h^2) h + E(h^2)) h: Horner's rule in h^2 over the odd coefficients (E) and,
    independently, the even ones (O): two chains of half the length in flight instead of
    one, with the accuracy of Horner's rule."""
    h2 = h * h
    if order % 2 == 0:
        e = C[order - 1, i]
        o = C[order, i]
        top = order - 3
    else:
        e = C[order, i] * h2 + C[order - 2, i]
        o = C[order - 1, i]
        top = order - 4
    for k in range(top, 0, -2):
        e = e * h2 + C[k, i]
        o = o * h2 + C[k + 1, i]
    return (o * h + e) * h


def _taylor_horner4(C, order, i, h):
    """``_taylor_horner`` of the variables i..i+3 at once: eight independent chains of
    fused multiply-adds in flight, each variable's sums as ``_taylor_horner``'s. It calls
    nothing (``codegen.FUSED``)."""
    h2 = h * h
    if order % 2 == 0:
        e0 = C[order - 1, i]
        e1 = C[order - 1, i + 1]
        e2 = C[order - 1, i + 2]
        e3 = C[order - 1, i + 3]
        o0 = C[order, i]
        o1 = C[order, i + 1]
        o2 = C[order, i + 2]
        o3 = C[order, i + 3]
        top = order - 3
    else:
        e0 = C[order, i] * h2 + C[order - 2, i]
        e1 = C[order, i + 1] * h2 + C[order - 2, i + 1]
        e2 = C[order, i + 2] * h2 + C[order - 2, i + 2]
        e3 = C[order, i + 3] * h2 + C[order - 2, i + 3]
        o0 = C[order - 1, i]
        o1 = C[order - 1, i + 1]
        o2 = C[order - 1, i + 2]
        o3 = C[order - 1, i + 3]
        top = order - 4
    for k in range(top, 0, -2):
        e0 = e0 * h2 + C[k, i]
        e1 = e1 * h2 + C[k, i + 1]
        e2 = e2 * h2 + C[k, i + 2]
        e3 = e3 * h2 + C[k, i + 3]
        o0 = o0 * h2 + C[k + 1, i]
        o1 = o1 * h2 + C[k + 1, i + 1]
        o2 = o2 * h2 + C[k + 1, i + 2]
        o3 = o3 * h2 + C[k + 1, i + 3]
    return (o0 * h + e0) * h, (o1 * h + e1) * h, (o2 * h + e2) * h, (o3 * h + e3) * h


def _taylor_advance(C, order, h, y, comp, kahan):
    """y += sum_{k=1}^{order} C[k, :] h^k (with Kahan's compensation in ``comp`` when
    ``kahan``): Horner's rule four variables at a time (``_taylor_horner4``: the step of
    Hénon–Heiles 0.094 -> 0.073 us outside the coefficient function), each sum as
    ``_taylor_horner``'s."""
    m = y.shape[0]
    i = 0
    while i + 4 <= m:
        d0, d1, d2, d3 = _taylor_horner4(C, order, i, h)
        _add(y, comp, i, d0, kahan)
        _add(y, comp, i + 1, d1, kahan)
        _add(y, comp, i + 2, d2, kahan)
        _add(y, comp, i + 3, d3, kahan)
        i += 4
    while i < m:
        _add(y, comp, i, _taylor_horner(C, order, i, h), kahan)
        i += 1


def _dd_times(xh, xl, h):
    """(xh + xl) h in double-double (TwoProd by a fused multiply-add: ``fma``, the
    intrinsic ``systems.codegen`` imports into the drivers' module)."""
    p = xh * h
    e = fma(xh, h, -p)
    e += xl * h
    s = p + e
    return s, e - (s - p)


def _dd_plus(xh, xl, yh, yl):
    """(xh + xl) + (yh + yl) in double-double."""
    s = xh + yh
    back = s - xh
    e = (xh - (s - back)) + (yh - back)
    e += xl + yl
    t = s + e
    return t, e - (t - s)


def _taylor_first(D, i, u, h, y, comp):
    """y[i] - comp[i] += ((u + c_2) h + c_1) h in double-double: the state's orders 1 and
    2 ``c_k`` double-double in ``D`` (``taylor_double``'s out: rows c_1, its low part,
    c_2, its low part), ``u = sum_{k>=3} C[k, i] h^(k-2)`` in double. The state stays
    the double-double ``(y, -comp)``."""
    xh, xl = _dd_plus(u, 0.0, D[2, i], D[3, i])
    xh, xl = _dd_times(xh, xl, h)
    xh, xl = _dd_plus(xh, xl, D[0, i], D[1, i])
    xh, xl = _dd_times(xh, xl, h)
    sh, sl = _dd_plus(y[i], -comp[i], xh, xl)
    y[i] = sh
    comp[i] = -sl


def _taylor_tail(C, order, i, h):
    """sum_{k=3}^{order} C[k, i] h^(k-2) (``_taylor_horner``'s sums from order 3)."""
    if order >= 4:
        return _taylor_horner(C[2:], order - 2, i, h)
    return C[3, i] * h if order == 3 else 0.0


def _taylor_advance_double(C, D, order, h, y, comp):
    """``_taylor_advance`` with the state the double-double ``y - comp`` and orders 1 and
    2 double-double in ``D``: the sum from order 3 in double (``_taylor_horner4``'s
    chains on ``C[2:]``), the first two orders and the addition to the state in
    double-double (``_taylor_first``)."""
    m = y.shape[0]
    i = 0
    if order >= 4:
        tail = C[2:]
        while i + 4 <= m:
            d0, d1, d2, d3 = _taylor_horner4(tail, order - 2, i, h)
            _taylor_first(D, i, d0, h, y, comp)
            _taylor_first(D, i + 1, d1, h, y, comp)
            _taylor_first(D, i + 2, d2, h, y, comp)
            _taylor_first(D, i + 3, d3, h, y, comp)
            i += 4
    while i < m:
        _taylor_first(D, i, _taylor_tail(C, order, i, h), h, y, comp)
        i += 1


def taylor_step(fns, y, comp, clock, P, coef, work):
    """One Taylor step: the coefficients of the solution through ``(t, y)`` to order p
    (``fns[0]``), the step from the last two (Jorba and Zou with heyoka's safety factor:
    ``rho = min(|[y]_{p-1}|^(-1/(p-1)), |[y]_p|^(-1/p))``, the norms the largest entry
    relative to ``max(1, |y|)``; ``h = rho / e^2 exp(-0.7 / (p - 1))``, at most ``hmax``,
    never past the end time), and the series summed by Horner's rule, the increment
    added with Kahan's compensation; with ``coef[5]`` (a tolerance below machine
    epsilon) orders 1 and 2 again in double-double (``fns[1]``, ``taylor_double``) and
    the state carried as the double-double ``y - comp`` (``_taylor_advance_double``).
    Never rejected: non-finite coefficients give a
    non-finite state, which the driver undoes. The coefficients stay in ``work`` for the
    dense output (``taylor_sample``); ``clock[CLOCK_H]`` is the step taken."""
    kahan = coef[1]
    order = coef[2]
    double = coef[5]
    C, D, flags = work
    t = clock[CLOCK_T]
    fns[0](t, y, P, C)
    if double:
        fns[1](t, y, comp, P, D)
    flags[0] = 1.0
    t_end = clock[CLOCK_T_END]
    h, last = _taylor_h(C, y, coef, t, t_end)
    if not h > 4e-14 * max(abs(t), 1.0):
        if h == h:
            return STATUS_STEP_COLLAPSED, 1
        h = 1.0  # nan coefficients: a non-finite state, undone by the driver
    if double:
        _taylor_advance_double(C, D, order, h, y, comp)
    else:
        _taylor_advance(C, order, h, y, comp, kahan)
    if last:
        clock[CLOCK_T] = t_end
        clock[CLOCK_TC] = 0.0
    else:
        _tick(clock, h)
    clock[CLOCK_H] = h
    return STATUS_RUNNING, 1


def _taylor_h(C, y, coef, t, t_end):
    """(h, last): the step from the coefficients ``C`` (order + 1, width) of the state
    ``y`` (m,) at ``t`` (``taylor_step``'s rule), and whether it ends at ``t_end``."""
    order = coef[2]
    hmax = coef[3]
    factor = coef[4]
    m = y.shape[0]
    scale = 1.0
    below = 0.0
    top = 0.0
    for i in range(m):
        scale = max(scale, abs(y[i]))
        below = max(below, abs(C[order - 1, i]))
        top = max(top, abs(C[order, i]))
    # rho = min((below/scale)^(-1/(p-1)), (top/scale)^(-1/p)), by logarithms (two pows
    # cost 23 ns, two logs and an exp 15); one division, the others products with
    # reciprocals the loop hoists (Hénon–Heiles' step 4% faster)
    inv = 1.0 / scale
    exponent = -math.inf
    if below > 0.0:
        exponent = math.log(below * inv) * (1.0 / (order - 1))
    if top > 0.0:
        exponent = max(exponent, math.log(top * inv) * (1.0 / order))
    rho = math.exp(-exponent)
    if rho == math.inf:  # a polynomial solution: every coefficient zero
        h = t_end - t if t_end < 1e300 else 1.0
    else:
        h = rho * factor
    h = min(h, hmax)
    last = h >= t_end - t
    if last:
        h = t_end - t
    return h, last


def _taylor_lane_steps(C, y, yl, coef, T, t_end, H, ends, live, status, lo, n):
    """Each of the first ``n`` lanes still live: its next step from its coefficients
    (``_taylor_h``) into ``H`` (0 for none) and ``ends`` (1: it lands on ``t_end``). A lane
    whose step collapses or is not finite gets that status (row ``lo + lane``) and stops.
    Returns how many lanes stopped; ``yl`` is scratch of the state's size."""
    stopped = 0
    for lane in range(H.shape[0]):
        H[lane] = 0.0
        if lane >= n or live[lane] == 0:
            continue
        for i in range(yl.shape[0]):
            yl[i] = y[i, lane]
        t = T[lane]
        h, last = _taylor_h(C[:, :, lane], yl, coef, t, t_end)
        if not h > 4e-14 * max(abs(t), 1.0):
            status[lo + lane] = STATUS_STEP_COLLAPSED if h == h else STATUS_NON_FINITE
            live[lane] = 0
            stopped += 1
            continue
        H[lane] = h
        ends[lane] = 1 if last else 0
    return stopped


def _taylor_lanes(C, order, H, inc):
    """inc[i, lane] = sum_{k=1}^{order} C[k, i, lane] H[lane]^k for every lane at once
    (each as ``_taylor_horner``'s: the same fused multiply-adds in the same order),
    eight lanes' sixteen chains side by side where the batch's lanes come in eights.
    The single run's split halves a chain's latency; here the eight lanes' chains
    already fill the multiply-add units, so this costs 12% more than one Horner chain
    per lane (120 against 107 ns a call, eight lanes, m = 4, order 20): the price of
    rows bitwise the single runs'."""
    m = inc.shape[0]
    B = H.shape[0]
    odd = order % 2 == 1
    top = order - 4 if odd else order - 3
    if B % 8 == 0:
        for g in range(0, B, 8):
            h0, h1, h2, h3 = H[g], H[g + 1], H[g + 2], H[g + 3]
            h4, h5, h6, h7 = H[g + 4], H[g + 5], H[g + 6], H[g + 7]
            s0, s1, s2, s3 = h0 * h0, h1 * h1, h2 * h2, h3 * h3
            s4, s5, s6, s7 = h4 * h4, h5 * h5, h6 * h6, h7 * h7
            for i in range(m):
                if odd:
                    e0 = C[order, i, g] * s0 + C[order - 2, i, g]
                    e1 = C[order, i, g + 1] * s1 + C[order - 2, i, g + 1]
                    e2 = C[order, i, g + 2] * s2 + C[order - 2, i, g + 2]
                    e3 = C[order, i, g + 3] * s3 + C[order - 2, i, g + 3]
                    e4 = C[order, i, g + 4] * s4 + C[order - 2, i, g + 4]
                    e5 = C[order, i, g + 5] * s5 + C[order - 2, i, g + 5]
                    e6 = C[order, i, g + 6] * s6 + C[order - 2, i, g + 6]
                    e7 = C[order, i, g + 7] * s7 + C[order - 2, i, g + 7]
                    j = order - 1
                else:
                    e0 = C[order - 1, i, g]
                    e1 = C[order - 1, i, g + 1]
                    e2 = C[order - 1, i, g + 2]
                    e3 = C[order - 1, i, g + 3]
                    e4 = C[order - 1, i, g + 4]
                    e5 = C[order - 1, i, g + 5]
                    e6 = C[order - 1, i, g + 6]
                    e7 = C[order - 1, i, g + 7]
                    j = order
                o0 = C[j, i, g]
                o1 = C[j, i, g + 1]
                o2 = C[j, i, g + 2]
                o3 = C[j, i, g + 3]
                o4 = C[j, i, g + 4]
                o5 = C[j, i, g + 5]
                o6 = C[j, i, g + 6]
                o7 = C[j, i, g + 7]
                for k in range(top, 0, -2):
                    e0 = e0 * s0 + C[k, i, g]
                    e1 = e1 * s1 + C[k, i, g + 1]
                    e2 = e2 * s2 + C[k, i, g + 2]
                    e3 = e3 * s3 + C[k, i, g + 3]
                    e4 = e4 * s4 + C[k, i, g + 4]
                    e5 = e5 * s5 + C[k, i, g + 5]
                    e6 = e6 * s6 + C[k, i, g + 6]
                    e7 = e7 * s7 + C[k, i, g + 7]
                    o0 = o0 * s0 + C[k + 1, i, g]
                    o1 = o1 * s1 + C[k + 1, i, g + 1]
                    o2 = o2 * s2 + C[k + 1, i, g + 2]
                    o3 = o3 * s3 + C[k + 1, i, g + 3]
                    o4 = o4 * s4 + C[k + 1, i, g + 4]
                    o5 = o5 * s5 + C[k + 1, i, g + 5]
                    o6 = o6 * s6 + C[k + 1, i, g + 6]
                    o7 = o7 * s7 + C[k + 1, i, g + 7]
                inc[i, g] = (o0 * h0 + e0) * h0
                inc[i, g + 1] = (o1 * h1 + e1) * h1
                inc[i, g + 2] = (o2 * h2 + e2) * h2
                inc[i, g + 3] = (o3 * h3 + e3) * h3
                inc[i, g + 4] = (o4 * h4 + e4) * h4
                inc[i, g + 5] = (o5 * h5 + e5) * h5
                inc[i, g + 6] = (o6 * h6 + e6) * h6
                inc[i, g + 7] = (o7 * h7 + e7) * h7
        return
    for lane in range(B):
        h = H[lane]
        s = h * h
        for i in range(m):
            if odd:
                e = C[order, i, lane] * s + C[order - 2, i, lane]
                o = C[order - 1, i, lane]
            else:
                e = C[order - 1, i, lane]
                o = C[order, i, lane]
            for k in range(top, 0, -2):
                e = e * s + C[k, i, lane]
                o = o * s + C[k + 1, i, lane]
            inc[i, lane] = (o * h + e) * h


def _taylor_lane_sum(C, order, kahan, double, fd, t, P, inc, y, comp, lane, h, yl, cl, D):
    """Lane ``lane``'s state after its step ``h`` into ``yl`` and ``cl`` (m,) from its
    start in ``y``, ``comp`` (m, B): the batch's sums ``inc`` added with ``_add``, or with
    ``double`` (from order 3 then) the lane's double-double orders 1 and 2 from ``fd``
    (``taylor_double`` at ``t`` and the lane's parameters ``P``, as its single run's)
    and ``_taylor_first``'s sums."""
    m = yl.shape[0]
    for i in range(m):
        yl[i] = y[i, lane]
        cl[i] = comp[i, lane]
    if not double:
        for i in range(m):
            _add(yl, cl, i, inc[i, lane], kahan)
        return
    fd(t, yl, cl, P, D)
    for i in range(m):
        u = inc[i, lane] if order >= 4 else _taylor_tail(C[:, :, lane], order, i, h)
        _taylor_first(D, i, u, h, yl, cl)


def _taylor_lane_samples(C, order, y, comp, lane, t, tc, t_next, times, j, out):
    """The states at ``times[j:]`` before ``t_next`` (the end of lane ``lane``'s step from
    ``t``, its clock's compensation ``tc``) from the step's series at its start ``y``,
    ``comp`` (m, B) into ``out`` (k, m) (``taylor_sample``'s sums). Returns the index
    of the first time left."""
    m = y.shape[0]
    while j < times.shape[0] and times[j] < t_next:
        s = times[j]
        ds = (s - t) + tc
        for i in range(m):
            if s <= t:
                out[j, i] = y[i, lane]
            else:
                d = _taylor_horner(C[:, :, lane], order, i, ds)
                out[j, i] = y[i, lane] + (d - comp[i, lane])
        j += 1
    return j


def taylor_batch_parallel(fb, fd, Y, clock0, P, coef, times, lanes, out, status, counts):
    """Many initial states ``Y`` (N, m) in batches of ``lanes``: the coefficients of a
    batch's trajectories from one call of the batch function ``fb`` (``taylor_batch``:
    T (B,), y (m, B), out (order + 1, width, B), SIMD lanes), each trajectory its own
    step (``_taylor_h``), sum (``_taylor_advance``, or with ``coef[5]`` the double-double
    orders of ``fd``, ``taylor_double``, called lane by lane, and
    ``_taylor_advance_double``'s sums) and clock from there, until every
    trajectory of the batch has ended; the batches spread over cores. ``clock0`` gives
    the start time and ``CLOCK_T_END``; ``out`` (N, k, m) gets the states at ``times``
    (k,) from the series, ``status`` (N,) ``STATUS_END`` or the problem that stopped a
    row (its later samples left as they were; a non-finite step is undone), ``counts``
    the steps. The trajectories are those of ``taylor_step``: the same coefficients,
    the same steps, the same sums."""
    kahan = coef[1]
    order = coef[2]
    width = coef[0]
    double = coef[5]
    N = Y.shape[0]
    m = Y.shape[1]
    B = lanes
    t0 = clock0[CLOCK_T]
    t_end = clock0[CLOCK_T_END]
    for batch in prange((N + B - 1) // B):
        lo = batch * B
        n = min(B, N - lo)
        y = np.empty((m, B))
        comp = np.zeros((m, B))
        T = np.full(B, t0)
        TC = np.zeros(B)
        C = np.empty((order + 1, width, B))
        H = np.zeros(B)
        ends = np.zeros(B, dtype=np.int64)
        inc = np.empty((m, B))
        yl = np.empty(m)
        cl = np.empty(m)
        D = np.zeros((4, m))
        live = np.zeros(B, dtype=np.int64)
        j = np.zeros(B, dtype=np.int64)
        for lane in range(B):
            row = lo + lane if lane < n else lo  # spare lanes copy a row, unused
            for i in range(m):
                y[i, lane] = Y[row, i]
            if lane < n:
                live[lane] = 1
                status[row] = STATUS_RUNNING
                counts[row] = 0
        running = n
        while running > 0:
            fb(T, y, P, C)
            # each lane's step (H 0: none)
            running -= _taylor_lane_steps(C, y, yl, coef, T, t_end, H, ends, live, status, lo, n)
            # every lane's sums at once (from order 3 where the first two orders and the
            # state are double-double, as _taylor_advance_double's)
            if not double:
                _taylor_lanes(C, order, H, inc)
            elif order >= 4:
                _taylor_lanes(C[2:], order - 2, H, inc)
            for lane in range(n):
                h = H[lane]
                if h == 0.0:
                    continue
                row = lo + lane
                _taylor_lane_sum(
                    C, order, kahan, double, fd, T[lane], P, inc, y, comp, lane, h, yl, cl, D
                )
                if not _finite(yl):  # the state stays the step's start
                    status[row] = STATUS_NON_FINITE
                    live[lane] = 0
                    running -= 1
                    continue
                counts[row] += 1
                t = T[lane]
                last = ends[lane] == 1
                t_next = t_end if last else t + h
                j[lane] = _taylor_lane_samples(
                    C, order, y, comp, lane, t, TC[lane], t_next, times, j[lane], out[row]
                )
                for i in range(m):
                    y[i, lane] = yl[i]
                    comp[i, lane] = cl[i]
                if last:
                    T[lane] = t_end
                    TC[lane] = 0.0
                    while j[lane] < times.shape[0]:
                        for i in range(m):
                            out[row, j[lane], i] = yl[i]
                        j[lane] += 1
                    status[row] = STATUS_END
                    live[lane] = 0
                    running -= 1
                else:
                    dd = h - TC[lane]
                    s = T[lane] + dd
                    TC[lane] = (s - T[lane]) - dd
                    T[lane] = s
        for lane in range(n):
            for i in range(m):
                Y[lo + lane, i] = y[i, lane]


# -- orbit diagrams: each orbit its own parameters and sample times (the taylor family) ---------


def taylor_batch_strobe_parallel(fb, fd, Y, clock0, P, coef, times, lanes, out, status, counts):
    """``taylor_batch_parallel``'s orbits with each row its own parameters ``P`` (N, k)
    and its own times ``times`` (N, K), increasing: an orbit diagram's rows
    (``systems.chaos.bifurcation``), row r's states at t0 + j T_r. ``fb`` is the batch
    function with parameters per lane (``TaylorKernels.sweep``: P (k, B) flattened),
    ``fd`` called with the lane's own row of ``P``. No end time: every step is the one
    a run without one takes (``Run(strobe=...)``), and a row ends once its last time
    is sampled (``STATUS_END``) or at the problem that stopped it (its later samples
    left as they were). ``clock0`` gives the start time; ``out`` (N, K, m) gets the
    states from the series (``_taylor_lane_samples``), ``counts`` (N,) the steps."""
    kahan = coef[1]
    order = coef[2]
    width = coef[0]
    double = coef[5]
    N = Y.shape[0]
    m = Y.shape[1]
    k = P.shape[1]
    K = times.shape[1]
    B = lanes
    t0 = clock0[CLOCK_T]
    t_end = math.inf
    for batch in prange((N + B - 1) // B):
        lo = batch * B
        n = min(B, N - lo)
        y = np.empty((m, B))
        comp = np.zeros((m, B))
        T = np.full(B, t0)
        TC = np.zeros(B)
        C = np.empty((order + 1, width, B))
        H = np.zeros(B)
        ends = np.zeros(B, dtype=np.int64)
        inc = np.empty((m, B))
        yl = np.empty(m)
        cl = np.empty(m)
        D = np.zeros((4, m))
        Pb = np.empty(k * B)
        live = np.zeros(B, dtype=np.int64)
        j = np.zeros(B, dtype=np.int64)
        for lane in range(B):
            row = lo + lane if lane < n else lo  # spare lanes copy a row, unused
            for i in range(m):
                y[i, lane] = Y[row, i]
            for q in range(k):
                Pb[q * B + lane] = P[row, q]
            if lane < n:
                live[lane] = 1
                status[row] = STATUS_RUNNING
                counts[row] = 0
        running = n
        while running > 0:
            fb(T, y, Pb, C)
            running -= _taylor_lane_steps(C, y, yl, coef, T, t_end, H, ends, live, status, lo, n)
            if not double:
                _taylor_lanes(C, order, H, inc)
            elif order >= 4:
                _taylor_lanes(C[2:], order - 2, H, inc)
            for lane in range(n):
                h = H[lane]
                if h == 0.0:
                    continue
                row = lo + lane
                t = T[lane]
                _taylor_lane_sum(
                    C, order, kahan, double, fd, t, P[row], inc, y, comp, lane, h, yl, cl, D
                )
                if not _finite(yl):  # the state stays the step's start
                    status[row] = STATUS_NON_FINITE
                    live[lane] = 0
                    running -= 1
                    continue
                counts[row] += 1
                j[lane] = _taylor_lane_samples(
                    C, order, y, comp, lane, t, TC[lane], t + h, times[row], j[lane], out[row]
                )
                for i in range(m):
                    y[i, lane] = yl[i]
                    comp[i, lane] = cl[i]
                dd = h - TC[lane]
                s = T[lane] + dd
                TC[lane] = (s - T[lane]) - dd
                T[lane] = s
                if j[lane] == K:
                    status[row] = STATUS_END
                    live[lane] = 0
                    running -= 1
        for lane in range(n):
            for i in range(m):
                Y[lo + lane, i] = y[i, lane]


# -- Poincaré sections of many orbits in SIMD batches (the taylor family) -----------------------


def _taylor_lane_value(C, lane, order, i, x, y0, c0):
    """Component ``i`` of lane ``lane``'s step polynomial at ``x`` from its start ``y0``
    with compensation ``c0`` (``taylor_sample``'s sum)."""
    d = C[order, i, lane]
    for k in range(order - 1, 0, -1):
        d = d * x + C[k, i, lane]
    return y0 + (d * x - c0)


def _taylor_lane_root(C, lane, order, i, level, h, y0, c0, g1):
    """The fraction s of the step ``h`` where lane ``lane``'s polynomial of component
    ``i`` reaches ``level``: ``events._root``'s regula falsi (Illinois) on [0, 1], from
    g(0) = y0 - level and g(1) = ``g1`` (the state after the step less the level)."""
    g0 = y0 - level
    lo = 0.0
    hi = 1.0
    g_lo = g0
    g_hi = g1
    if g_lo == 0.0:
        return 0.0
    if g_hi == 0.0:
        return 1.0
    s = 0.5
    for _ in range(100):
        s = lo - g_lo * (hi - lo) / (g_hi - g_lo)
        if not (lo < s and s < hi):
            s = 0.5 * (lo + hi)
        gs = _taylor_lane_value(C, lane, order, i, s * h, y0, c0) - level
        if abs(gs) <= 1e-16 * (abs(g0) + abs(g1)) or hi - lo < 1e-15:
            return s
        if (gs < 0.0) == (g_lo < 0.0):
            lo = s
            g_lo = gs
            g_hi *= 0.5
        else:
            hi = s
            g_hi = gs
            g_lo *= 0.5
    return s


def taylor_batch_section_parallel(
    fb, Y, clock0, P, coef, section, lanes, ev_t, ev_y, events, status, counts, reached
):
    """``taylor_batch_parallel``'s orbits (the same steps: ``fb``, ``_taylor_h``,
    ``_taylor_lanes``, ``_add``) recording where each crosses the surface ``y[index] =
    value`` (``section = (index, value, direction, period)``, float64: direction +1
    upward, -1 downward, 0 both; period > 0 crosses every ``value + period j``, an
    angle's cut), each crossing located on the lane's own series of the step that
    crosses (``_taylor_lane_root``: ``events.locate_crossings``' root on the step's
    polynomial). ``ev_t`` (N, E) and ``ev_y`` (N, E, m) get the crossings, ``events``
    (N,) their number; a row stops at ``clock0[CLOCK_T_END]`` (``STATUS_END``), when its
    E crossings are found (``STATUS_RUNNING``) or on a problem (its status, the step
    undone); ``counts`` (N,) the steps, ``reached`` (N,) the time it stopped at, ``Y``
    (N, m) its state there."""
    kahan = coef[1]
    order = coef[2]
    width = coef[0]
    N = Y.shape[0]
    m = Y.shape[1]
    B = lanes
    E = ev_t.shape[1]
    index = int(section[0])
    value = section[1]
    direction = section[2]
    period = section[3]
    t0 = clock0[CLOCK_T]
    t_end = clock0[CLOCK_T_END]
    for batch in prange((N + B - 1) // B):
        lo = batch * B
        n = min(B, N - lo)
        y = np.empty((m, B))
        comp = np.zeros((m, B))
        T = np.full(B, t0)
        TC = np.zeros(B)
        C = np.empty((order + 1, width, B))
        H = np.zeros(B)
        ends = np.zeros(B, dtype=np.int64)
        inc = np.empty((m, B))
        yl = np.empty(m)
        cl = np.empty(m)
        live = np.zeros(B, dtype=np.int64)
        for lane in range(B):
            row = lo + lane if lane < n else lo  # spare lanes copy a row, unused
            for i in range(m):
                y[i, lane] = Y[row, i]
            if lane < n:
                live[lane] = 1
                status[row] = STATUS_RUNNING
                counts[row] = 0
                events[row] = 0
        running = n
        while running > 0:
            fb(T, y, P, C)
            # each lane's step (H 0: none)
            running -= _taylor_lane_steps(C, y, yl, coef, T, t_end, H, ends, live, status, lo, n)
            _taylor_lanes(C, order, H, inc)
            for lane in range(n):
                h = H[lane]
                if h == 0.0:
                    continue
                row = lo + lane
                for i in range(m):
                    yl[i] = y[i, lane]
                    cl[i] = comp[i, lane]
                    _add(yl, cl, i, inc[i, lane], kahan)
                if not _finite(yl):  # the state stays the step's start
                    status[row] = STATUS_NON_FINITE
                    live[lane] = 0
                    running -= 1
                    continue
                counts[row] += 1
                last = ends[lane] == 1
                before = y[index, lane] - value
                after = yl[index] - value
                first = 0
                top = 0
                step = 1
                if period > 0.0:
                    kb = math.floor(before / period)
                    ka = math.floor(after / period)
                    cb = math.ceil(before / period)
                    ca = math.ceil(after / period)
                    if direction >= 0 and ka > kb:
                        first = int(kb) + 1
                        top = int(ka) + 1
                    elif direction <= 0 and ca < cb:
                        first = int(cb) - 1
                        top = int(ca) - 1
                        step = -1
                elif _crossed(before, after, direction):
                    top = 1
                j = first
                while j != top and events[row] < E:
                    level = value + period * j
                    s = _taylor_lane_root(
                        C, lane, order, index, level, h, y[index, lane], comp[index, lane],
                        yl[index] - level,
                    )  # fmt: skip
                    x = s * h
                    e = events[row]
                    ev_t[row, e] = T[lane] + (x - TC[lane])
                    for i in range(m):
                        ev_y[row, e, i] = _taylor_lane_value(
                            C, lane, order, i, x, y[i, lane], comp[i, lane]
                        )
                    events[row] = e + 1
                    j += step
                for i in range(m):
                    y[i, lane] = yl[i]
                    comp[i, lane] = cl[i]
                if last:
                    T[lane] = t_end
                    TC[lane] = 0.0
                else:
                    dd = h - TC[lane]
                    s = T[lane] + dd
                    TC[lane] = (s - T[lane]) - dd
                    T[lane] = s
                if last or events[row] >= E:
                    status[row] = STATUS_END if last else STATUS_RUNNING
                    live[lane] = 0
                    running -= 1
        for lane in range(n):
            reached[lo + lane] = T[lane] - TC[lane]
            for i in range(m):
                Y[lo + lane, i] = y[i, lane]


# -- chaos maps in SIMD batches (the taylor family): MEGNO on the variational system -----------
# Gauss-Legendre's 8 nodes and weights on [0, 1]: MEGNO's mean over a step from the series
_GL8_X = (
    0.019855071751231912, 0.10166676129318664, 0.2372337950418355, 0.4082826787521751,
    0.5917173212478248, 0.7627662049581645, 0.8983332387068134, 0.9801449282487681,
)  # fmt: skip
_GL8_W = (
    0.05061426814518853, 0.11119051722668721, 0.15685332293894344, 0.18134189168918083,
    0.18134189168918083, 0.15685332293894344, 0.11119051722668721, 0.05061426814518853,
)  # fmt: skip
TANGENT_RESCALE = 1e3
"""The tangent vector is brought back to unit length when it grows past this (or shrinks
below its inverse): the step's rule measures every variable against max(1, |y|)."""


def _tangent_length(y, lane, n):
    """|delta| of lane ``lane``'s tangent vector, rows 2n..4n of ``y`` (m, B)."""
    norm = 0.0
    for i in range(2 * n, 4 * n):
        norm += y[i, lane] * y[i, lane]
    return math.sqrt(norm)


def taylor_batch_megno_parallel(fb, Y, clock0, P, coef, lanes, out, status, counts):
    """MEGNO and the maximal exponent of many orbits with adaptive Taylor steps, in
    batches of ``lanes`` (``taylor_batch_parallel``'s loop on the extended system of
    ``systems.chaos.taylor_map``): ``Y`` (N, 4n + 1) rows ``(q, p, dq, dp, W)`` with W'
    = (t - t0) P[-2] (delta . delta') / |delta|^2, so that MEGNO's Y(t) = 2 W / (P[-2]
    (t - t0)) (``P[-2]`` = 1 / (t_end - t0) keeps W of order one). Each step adds
    ``int Y ds`` over the step by Gauss-Legendre on the lane's series of W (8 nodes: the
    series is the solution over the whole step), so <Y> = that sum / (t - t0); the
    tangent vector is rescaled to unit length past ``TANGENT_RESCALE`` (its logarithm
    summed). ``out`` (N, 3): <Y>, ln(|delta(t)| / |delta(0)|) / (t - t0) and Y(t) at
    ``clock0[CLOCK_T_END]`` (or where a problem stopped the row: ``status`` (N,)
    ``STATUS_END`` or the problem), ``counts`` (N,) the steps; ``Y`` gets the end."""
    kahan = coef[1]
    order = coef[2]
    width = coef[0]
    N = Y.shape[0]
    m = Y.shape[1]
    n = (m - 1) // 4
    iw = m - 1
    B = lanes
    scale = P[P.shape[0] - 2]
    t0 = clock0[CLOCK_T]
    t_end = clock0[CLOCK_T_END]
    for batch in prange((N + B - 1) // B):
        lo = batch * B
        n_rows = min(B, N - lo)
        y = np.empty((m, B))
        comp = np.zeros((m, B))
        T = np.full(B, t0)
        TC = np.zeros(B)
        C = np.empty((order + 1, width, B))
        H = np.zeros(B)
        ends = np.zeros(B, dtype=np.int64)
        inc = np.empty((m, B))
        yl = np.empty(m)
        cl = np.empty(m)
        live = np.zeros(B, dtype=np.int64)
        logs = np.zeros(B)
        mean = np.zeros(B)
        for lane in range(B):
            row = lo + lane if lane < n_rows else lo  # spare lanes copy a row, unused
            for i in range(m):
                y[i, lane] = Y[row, i]
            logs[lane] = -math.log(_tangent_length(y, lane, n))
            if lane < n_rows:
                live[lane] = 1
                status[row] = STATUS_RUNNING
                counts[row] = 0
        running = n_rows
        while running > 0:
            fb(T, y, P, C)
            # each lane's step (H 0: none)
            running -= _taylor_lane_steps(
                C, y, yl, coef, T, t_end, H, ends, live, status, lo, n_rows
            )
            _taylor_lanes(C, order, H, inc)
            for lane in range(n_rows):
                h = H[lane]
                if h == 0.0:
                    continue
                row = lo + lane
                for i in range(m):
                    yl[i] = y[i, lane]
                    cl[i] = comp[i, lane]
                    _add(yl, cl, i, inc[i, lane], kahan)
                if not _finite(yl):  # the state stays the step's start
                    status[row] = STATUS_NON_FINITE
                    live[lane] = 0
                    running -= 1
                    continue
                counts[row] += 1
                tau = (T[lane] - TC[lane]) - t0
                acc = 0.0
                for k in range(8):
                    x = _GL8_X[k] * h
                    w = _taylor_lane_value(C, lane, order, iw, x, y[iw, lane], comp[iw, lane])
                    acc += _GL8_W[k] * w / (tau + x)
                mean[lane] += 2.0 * h * acc / scale
                for i in range(m):
                    y[i, lane] = yl[i]
                    comp[i, lane] = cl[i]
                length = _tangent_length(y, lane, n)
                if length > TANGENT_RESCALE or length < 1.0 / TANGENT_RESCALE:
                    for i in range(2 * n, 4 * n):
                        y[i, lane] /= length
                        comp[i, lane] = 0.0
                    logs[lane] += math.log(length)
                if ends[lane] == 1:
                    T[lane] = t_end
                    TC[lane] = 0.0
                    status[row] = STATUS_END
                    live[lane] = 0
                    running -= 1
                else:
                    dd = h - TC[lane]
                    s = T[lane] + dd
                    TC[lane] = (s - T[lane]) - dd
                    T[lane] = s
        for lane in range(n_rows):
            row = lo + lane
            for i in range(m):
                Y[row, i] = y[i, lane]
            s = (T[lane] - TC[lane]) - t0
            if s > 0.0:
                out[row, 0] = mean[lane] / s
                out[row, 1] = (logs[lane] + math.log(_tangent_length(y, lane, n))) / s
                out[row, 2] = 2.0 * y[iw, lane] / (scale * s)
            else:
                out[row, 0] = math.nan
                out[row, 1] = math.nan
                out[row, 2] = math.nan


def taylor_sample_work(coef, m):
    width = coef[0]
    order = coef[2]
    return (np.empty((order + 1, width)),)


def taylor_sample(fns, prev, state, s, P, coef, work, swork, scratch, first):
    """The state at ``s`` from the polynomial of the last step: its coefficients (kept in
    ``work``; computed again into ``swork`` from the step's start if the driver undid a
    step since), summed at ``s - t`` with the start's compensation."""
    order = coef[2]
    yprev, cprev, kprev = prev
    C = work[0]
    evals = 0
    if work[-1][0] == 0.0:
        C = swork[0]
        if first:
            fns[0](kprev[CLOCK_T], yprev, P, C)
            evals = 1
    ds = (s - kprev[CLOCK_T]) + kprev[CLOCK_TC]
    out = scratch[0]
    m = yprev.shape[0]
    i = 0
    while i + 4 <= m:  # four chains in flight, as a step's sums (_taylor_advance)
        d0, d1, d2, d3 = _taylor_horner4(C, order, i, ds)
        out[i] = yprev[i] + (d0 - cprev[i])
        out[i + 1] = yprev[i + 1] + (d1 - cprev[i + 1])
        out[i + 2] = yprev[i + 2] + (d2 - cprev[i + 2])
        out[i + 3] = yprev[i + 3] + (d3 - cprev[i + 3])
        i += 4
    while i < m:
        out[i] = yprev[i] + (_taylor_horner(C, order, i, ds) - cprev[i])
        i += 1
    return STATUS_RUNNING, evals


def _taylor_horner4x2(C, order, i, a, b):
    """``_taylor_horner4`` at two steps ``a`` and ``b`` at once: sixteen chains in flight,
    each sum as ``_taylor_horner``'s (run's rows two at a time: 21 -> 14 ns a row of
    four variables at order 20). It calls nothing (``codegen.FUSED``)."""
    p = a * a
    q = b * b
    if order % 2 == 0:
        e0 = C[order - 1, i]
        e1 = C[order - 1, i + 1]
        e2 = C[order - 1, i + 2]
        e3 = C[order - 1, i + 3]
        o0 = C[order, i]
        o1 = C[order, i + 1]
        o2 = C[order, i + 2]
        o3 = C[order, i + 3]
        f0, f1, f2, f3 = e0, e1, e2, e3
        g0, g1, g2, g3 = o0, o1, o2, o3
        top = order - 3
    else:
        e0 = C[order, i] * p + C[order - 2, i]
        e1 = C[order, i + 1] * p + C[order - 2, i + 1]
        e2 = C[order, i + 2] * p + C[order - 2, i + 2]
        e3 = C[order, i + 3] * p + C[order - 2, i + 3]
        f0 = C[order, i] * q + C[order - 2, i]
        f1 = C[order, i + 1] * q + C[order - 2, i + 1]
        f2 = C[order, i + 2] * q + C[order - 2, i + 2]
        f3 = C[order, i + 3] * q + C[order - 2, i + 3]
        o0 = C[order - 1, i]
        o1 = C[order - 1, i + 1]
        o2 = C[order - 1, i + 2]
        o3 = C[order - 1, i + 3]
        g0, g1, g2, g3 = o0, o1, o2, o3
        top = order - 4
    for k in range(top, 0, -2):
        c0 = C[k, i]
        c1 = C[k, i + 1]
        c2 = C[k, i + 2]
        c3 = C[k, i + 3]
        d0 = C[k + 1, i]
        d1 = C[k + 1, i + 1]
        d2 = C[k + 1, i + 2]
        d3 = C[k + 1, i + 3]
        e0 = e0 * p + c0
        e1 = e1 * p + c1
        e2 = e2 * p + c2
        e3 = e3 * p + c3
        o0 = o0 * p + d0
        o1 = o1 * p + d1
        o2 = o2 * p + d2
        o3 = o3 * p + d3
        f0 = f0 * q + c0
        f1 = f1 * q + c1
        f2 = f2 * q + c2
        f3 = f3 * q + c3
        g0 = g0 * q + d0
        g1 = g1 * q + d1
        g2 = g2 * q + d2
        g3 = g3 * q + d3
    return (
        (o0 * a + e0) * a, (o1 * a + e1) * a, (o2 * a + e2) * a, (o3 * a + e3) * a,
        (g0 * b + f0) * b, (g1 * b + f1) * b, (g2 * b + f2) * b, (g3 * b + f3) * b,
    )  # fmt: skip


def taylor_sample_rows(fns, prev, state, times, lo, hi, P, coef, work, swork, states, out_y, row):
    """``DRIVER_sample_rows`` of the taylor family: each row ``taylor_sample``'s sums,
    two rows at a time where the state has four variables or more
    (``_taylor_horner4x2``), written straight into ``out_y``."""
    order = coef[2]
    yprev, cprev, kprev = prev
    C = work[0]
    evals = 0
    if work[-1][0] == 0.0:  # a step undone since: its coefficients again
        C = swork[0]
        fns[0](kprev[CLOCK_T], yprev, P, C)
        evals = 1
    t0 = kprev[CLOCK_T]
    tc = kprev[CLOCK_TC]
    m = yprev.shape[0]
    j = 0
    if m >= 4:
        while lo + j + 2 <= hi:
            a = (times[lo + j] - t0) + tc
            b = (times[lo + j + 1] - t0) + tc
            r = row + j
            i = 0
            while i + 4 <= m:
                d0, d1, d2, d3, x0, x1, x2, x3 = _taylor_horner4x2(C, order, i, a, b)
                out_y[r, i] = yprev[i] + (d0 - cprev[i])
                out_y[r, i + 1] = yprev[i + 1] + (d1 - cprev[i + 1])
                out_y[r, i + 2] = yprev[i + 2] + (d2 - cprev[i + 2])
                out_y[r, i + 3] = yprev[i + 3] + (d3 - cprev[i + 3])
                out_y[r + 1, i] = yprev[i] + (x0 - cprev[i])
                out_y[r + 1, i + 1] = yprev[i + 1] + (x1 - cprev[i + 1])
                out_y[r + 1, i + 2] = yprev[i + 2] + (x2 - cprev[i + 2])
                out_y[r + 1, i + 3] = yprev[i + 3] + (x3 - cprev[i + 3])
                i += 4
            while i < m:
                out_y[r, i] = yprev[i] + (_taylor_horner(C, order, i, a) - cprev[i])
                out_y[r + 1, i] = yprev[i] + (_taylor_horner(C, order, i, b) - cprev[i])
                i += 1
            if not (_finite(out_y[r]) and _finite(out_y[r + 1])):
                return STATUS_NON_FINITE, evals, j + (1 if _finite(out_y[r]) else 0)
            j += 2
    while lo + j < hi:  # the last row of an odd count, or a state of fewer than four
        code, used = taylor_sample(
            fns, prev, state, times[lo + j], P, coef, work, swork, states, False
        )
        if not _finite(states[0]):
            return STATUS_NON_FINITE, evals, j
        for k in range(m):
            out_y[row + j, k] = states[0][k]
        j += 1
    return STATUS_RUNNING, evals, hi - lo


# -- constrained systems: the multipliers, the projection, contacts and impacts ------------------
# ``cs`` is the scene's tuple of constraint functions (``Family.functions`` of the
# constrained families, in this order: ``c_free_rhs``, ``c_positions``, ``c_rows``,
# ``c_mass``, ``c_velocities``, ``c_momenta``, ``c_saddle``, ``c_gamma``, see
# ``systems.constraints.kernel_source``) followed by ``sizes`` (int64: the number of
# constraints k, of holonomic ones, of bilateral ones (holonomic and nonholonomic), and
# the index of the parameter ``restitution`` in P, -1 without one). The state y = (q, p)
# has n = len(y) // 2 coordinates; the saddle-point systems are m = n + k square.
# ``sc`` is their scratch (``c_scratch``), held in the constrained families' work: the
# helpers the stepping loops call allocate nothing, so they and the loops are compiled
# without reference counting (``codegen.jit_wrappers``), and each evaluation of ``c_rhs``
# no longer allocates its saddle-point system.


def c_scratch(k, n):
    """The scratch of the constrained helpers: (W (m, m + 1), R (k, n + 1), four
    n-vectors, seven k-vectors), m = n + k. Which helper uses which row is written at
    its start; a helper never holds a row across a call that uses it."""
    return (np.empty((n + k, n + k + 1)), np.empty((k, n + 1)), np.empty((4, n)), np.empty((7, k)))


def c_solve(W, m, r):
    """Solve A X = B in place for W = [A | B] (m, m + r), A square and invertible.

    Gaussian elimination with partial pivoting (the saddle-point matrix is symmetric but
    indefinite, so no Cholesky); on return columns m .. m + r - 1 hold X. A singular A
    gives inf or nan, which the driver rejects like any non-finite step.
    """
    for j in range(m):
        pivot = j
        for i in range(j + 1, m):
            if abs(W[i, j]) > abs(W[pivot, j]):
                pivot = i
        if pivot != j:
            for c in range(j, m + r):
                W[j, c], W[pivot, c] = W[pivot, c], W[j, c]
        for i in range(j + 1, m):
            f = W[i, j] / W[j, j]
            for c in range(j, m + r):
                W[i, c] -= f * W[j, c]
    for c in range(m, m + r):
        for i in range(m - 1, -1, -1):
            s = W[i, c]
            for l in range(i + 1, m):
                s -= W[i, l] * W[l, c]
            W[i, c] = s / W[i, i]


def _settled(size, previous, scale):
    """Newton's correction is at round-off: tiny, or small and no longer shrinking
    (quadratic convergence halves the digits left at least; noise does not)."""
    if size <= 1e-14 * scale:
        return True
    return size <= 1e-10 * scale and size > 0.5 * previous


def c_bilateral(cs, act):
    """act = 1 for the bilateral rows, 0 for the unilateral ones (no contact)."""
    k = cs[8][0]
    for i in range(k):
        act[i] = 1.0 if i < cs[8][2] else 0.0


def c_lambda(cs, t, y, P, act, W):
    """Fill and solve the saddle-point system of the rows with act > 0 (a row that does
    not act gets an identity row and lambda = 0): W[n:m, m] is lambda, W[:n, m]
    qddot."""
    n = y.shape[0] // 2
    k = cs[8][0]
    m = n + k
    for i in range(k):
        for j in range(k):
            W[n + i, n + j] = 0.0
    cs[6](t, y, P, W)
    for i in range(k):
        if act[i] > 0.0:
            for j in range(n):
                W[j, n + i] = W[n + i, j]
        else:
            for j in range(n):
                W[j, n + i] = 0.0
                W[n + i, j] = 0.0
            W[n + i, n + i] = 1.0
            W[n + i, m] = 0.0
    # the small sizes with m a constant (``c_solve`` is inlined): LLVM unrolls them, 168
    # -> 134 ns a solve of m = 6, a dozen solves a DOP853 step (the kernels inlined per
    # scene had m constant); the same operations, bitwise
    if m == 2:
        c_solve(W, 2, 1)
    elif m == 3:
        c_solve(W, 3, 1)
    elif m == 4:
        c_solve(W, 4, 1)
    elif m == 5:
        c_solve(W, 5, 1)
    elif m == 6:
        c_solve(W, 6, 1)
    else:
        c_solve(W, m, 1)


def c_rhs(cs, t, y, P, act, out, sc):
    n = y.shape[0] // 2
    k = cs[8][0]
    m = n + k
    W, R = sc[0], sc[1]
    c_lambda(cs, t, y, P, act, W)
    cs[2](t, y, P, R)
    cs[0](t, y, P, out)
    for i in range(n):
        acc = 0.0
        for j in range(k):
            acc += R[j, i] * W[n + j, m]
        out[n + i] -= acc


def c_bilateral_rhs(cs, t, y, P, out):
    sc = c_scratch(cs[8][0], y.shape[0] // 2)
    act = sc[3][6]
    c_bilateral(cs, act)
    c_rhs(cs, t, y, P, act, out, sc)


def c_normal_speeds(cs, t, y, P, qd, R, out):
    """out[i] = R[i, :n] . qd + R[i, n]: each row's velocity (a . qdot + b, G qdot + g_t)."""
    n = y.shape[0] // 2
    k = cs[8][0]
    n + k
    for i in range(k):
        acc = R[i, n]
        for j in range(n):
            acc += R[i, j] * qd[j]
        out[i] = acc


def c_contacts(cs, t, y, P, act, sc):
    """act for the state y: the bilateral rows, and the unilateral rows it touches (g and
    the normal velocity at zero) where the contact pushes (lambda <= 0). Uses W, R, n-row
    0 and k-rows 0-1 of ``sc``."""
    n = y.shape[0] // 2
    k = cs[8][0]
    m = n + k
    c_bilateral(cs, act)
    if cs[8][2] == k:
        return
    W, R, qd, g, v = sc[0], sc[1], sc[2][0], sc[3][0], sc[3][1]
    cs[1](t, y, P, g)
    cs[4](t, y, P, qd)
    cs[2](t, y, P, R)
    c_normal_speeds(cs, t, y, P, qd, R, v)
    qscale = 1.0
    vscale = 1.0
    for j in range(n):
        qscale = max(qscale, abs(y[j]))
        vscale = max(vscale, abs(qd[j]))
    touching = 0
    for i in range(cs[8][2], k):
        if abs(g[i]) <= CONTACT_GAP * qscale and abs(v[i]) <= CONTACT_SPEED * vscale:
            act[i] = 1.0
            touching += 1
    while touching > 0:
        c_lambda(cs, t, y, P, act, W)
        pulling = False
        for i in range(cs[8][2], k):
            if act[i] > 0.0 and W[n + i, m] > 0.0:
                act[i] = 0.0
                touching -= 1
                pulling = True
                break
        if not pulling:
            break


def c_multipliers(cs, t, y, P, out):
    n = y.shape[0] // 2
    k = cs[8][0]
    m = n + k
    sc = c_scratch(k, n)
    act, W = sc[3][6], sc[0]
    c_contacts(cs, t, y, P, act, sc)
    c_lambda(cs, t, y, P, act, W)
    for j in range(k):
        out[j] = W[n + j, m]


def c_constraint_values(cs, t, y, P, out):
    n = y.shape[0] // 2
    k = cs[8][0]
    n + k
    cs[1](t, y, P, out)
    if cs[8][2] > cs[8][1]:
        qd = np.empty(n)
        cs[4](t, y, P, qd)
        R = np.empty((k, n + 1))
        cs[2](t, y, P, R)
        v = np.empty(k)
        c_normal_speeds(cs, t, y, P, qd, R, v)
        for i in range(cs[8][1], cs[8][2]):
            out[i] = v[i]


def c_metric(cs, t, y, P, R, use, top, r, out, W):
    """out = x of [[M, R_u^T], [R_u, 0]] [x; mu] = [M top; r_u] over the rows with
    use > 0: x = top - M^-1 R_u^T (R_u M^-1 R_u^T)^-1 (R_u top - r_u), the point of
    R_u x = r_u nearest to ``top`` in the kinetic metric (W: its saddle-point system)."""
    n = y.shape[0] // 2
    k = cs[8][0]
    m = n + k
    cs[3](t, y, P, W)
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += W[i, j] * top[j]
        W[i, m] = acc
    for a in range(k):
        for b in range(k):
            W[n + a, n + b] = 0.0
        if use[a] > 0.0:
            for j in range(n):
                W[n + a, j] = R[a, j]
                W[j, n + a] = R[a, j]
            W[n + a, m] = r[a]
        else:
            for j in range(n):
                W[n + a, j] = 0.0
                W[j, n + a] = 0.0
            W[n + a, n + a] = 1.0
            W[n + a, m] = 0.0
    c_solve(W, m, 1)
    for i in range(n):
        out[i] = W[i, m]


def c_project(cs, t, y, P, act, sc):
    """Move y = (q, p) onto the position rows (holonomic, and the acting contacts) and
    every acting velocity row, in place; False if Newton's iteration did not converge.
    Uses W, R, n-rows 0-3 and k-rows 0-1 of ``sc``."""
    n = y.shape[0] // 2
    k = cs[8][0]
    n + k
    W, R, pos, use = sc[0], sc[1], sc[3][0], sc[3][1]
    qd, dq, zero, p = sc[2][0], sc[2][1], sc[2][2], sc[2][3]
    cs[4](t, y, P, qd)
    npos = 0
    for i in range(n):
        zero[i] = 0.0
    for i in range(k):
        use[i] = 0.0
        if act[i] > 0.0 and (i < cs[8][1] or i >= cs[8][2]):
            use[i] = 1.0
            npos += 1
    converged = True
    if npos > 0:
        converged = False
        previous = math.inf
        for _ in range(PROJECTION_ITERATIONS):
            cs[1](t, y, P, pos)
            cs[2](t, y, P, R)
            c_metric(cs, t, y, P, R, use, zero, pos, dq, W)
            size = 0.0
            scale = 1.0
            for i in range(n):
                y[i] -= dq[i]
                size = max(size, abs(dq[i]))
                scale = max(scale, abs(y[i]))
            if not size == size:
                return False
            if _settled(size, previous, scale):
                converged = True
                break
            previous = size
    cs[2](t, y, P, R)
    for i in range(k):
        pos[i] = -R[i, n]
    c_metric(cs, t, y, P, R, act, qd, pos, dq, W)
    cs[5](t, y, dq, P, p)
    for i in range(n):
        y[n + i] = p[i]
    return converged


def c_project_bilateral(cs, t, y, P, sc):
    """Move y = (q, p) onto Phi(q, t) = 0 and the bilateral velocity rows, in place."""
    act = sc[3][6]
    c_bilateral(cs, act)
    return c_project(cs, t, y, P, act, sc)


def c_restitution(cs, P):
    cs[8][0]
    if cs[8][3] < 0:
        return 1.0
    return max(P[cs[8][3]], 0.0)


def c_event_values(cs, t, y, P, act, out, sc):
    """out[i] for the unilateral rows: g (a free row) or -lambda (an acting contact);
    inf for the bilateral rows. A negative value means the state went through a wall or
    a contact pulls. Uses W and k-row 0 of ``sc``."""
    n = y.shape[0] // 2
    k = cs[8][0]
    m = n + k
    for i in range(k):
        out[i] = math.inf
    if cs[8][2] == k:
        return
    W, g = sc[0], sc[3][0]
    cs[1](t, y, P, g)
    contact = False
    for i in range(cs[8][2], k):
        if act[i] > 0.0:
            contact = True
        else:
            out[i] = g[i]
    if contact:
        c_lambda(cs, t, y, P, act, W)
        for i in range(cs[8][2], k):
            if act[i] > 0.0:
                out[i] = -W[n + i, m]


def c_switch(cs, t, y, P, act, which, sc):
    """At the located event of row ``which``: release it if it is an acting contact (its
    multiplier reached zero); otherwise Newton's restitution law on it (and on every other
    free row as close, g <= its g, that approaches), jointly and keeping every acting row:
    G qdot+ + g_t = -e (G qdot- + g_t), then p = p(q, qdot+). A rebound that would rise
    less than the contact gap (v+**2 <= 2 |a_n| CONTACT_GAP max(1, |q|), with a_n the
    normal acceleration of the free motion after the impact: e = 0, or the end of a Zeno
    sequence of ever lower bounces) makes the contact a resting one instead (normal
    velocity 0, act = 1). Contacts that would pull are then released, one at a time.
    Returns False if nothing changed. Uses W, R, n-rows 0, 1, 3 and k-rows 0-5 of
    ``sc``."""
    n = y.shape[0] // 2
    k = cs[8][0]
    m = n + k
    if act[which] > 0.0:
        act[which] = 0.0
        return True
    e = c_restitution(cs, P)
    W, R, qd, new, p = sc[0], sc[1], sc[2][0], sc[2][1], sc[2][3]
    g, v, use, target, hit, gamma = sc[3][0], sc[3][1], sc[3][2], sc[3][3], sc[3][4], sc[3][5]
    cs[4](t, y, P, qd)
    cs[1](t, y, P, g)
    cs[2](t, y, P, R)
    c_normal_speeds(cs, t, y, P, qd, R, v)
    qscale = 1.0
    for j in range(n):
        qscale = max(qscale, abs(y[j]))
    level = max(g[which], 0.0)
    changed = False
    for i in range(k):
        use[i] = act[i]
        target[i] = -R[i, n]
        hit[i] = 0.0
        if i >= cs[8][2] and act[i] == 0.0 and (i == which or g[i] <= level):
            if v[i] > 0.0:
                continue  # leaving already
            use[i] = 1.0
            hit[i] = 1.0
            target[i] = -R[i, n] - e * v[i]
            changed = True
    if not changed:
        return False
    c_metric(cs, t, y, P, R, use, qd, target, new, W)
    cs[5](t, y, new, P, p)
    for i in range(n):
        y[n + i] = p[i]
    # how high each rebound would rise: v+**2 / (2 |a_n|) with the free motion's a_n
    c_lambda(cs, t, y, P, act, W)
    cs[7](t, y, P, gamma)
    resting = False
    for i in range(cs[8][2], k):
        if hit[i] > 0.0:
            a_n = -gamma[i]
            for j in range(n):
                a_n += R[i, j] * W[j, m]
            rebound = -e * v[i]
            if rebound * rebound <= 2.0 * max(-a_n, 0.0) * 1e-10 * qscale:
                act[i] = 1.0
                target[i] = -R[i, n]
                resting = True
    if resting:
        c_metric(cs, t, y, P, R, use, qd, target, new, W)
        cs[5](t, y, new, P, p)
        for i in range(n):
            y[n + i] = p[i]
    for _ in range(k):
        c_lambda(cs, t, y, P, act, W)
        pulling = False
        for i in range(cs[8][2], k):
            if act[i] > 0.0 and W[n + i, m] > 0.0:
                act[i] = 0.0
                pulling = True
                break
        if not pulling:
            break
    return changed


# -- constrained systems: a step, then the projection onto the constraints ------------------
#
# The contacts of unilateral constraints are part of the step's work: ``act`` (one entry
# per constraint, 1.0 where the row acts) and ``act0``, its value at the start of the last
# step. The driver zeroes the work's flag when it undoes a step; the next step then takes
# ``act0`` back (or, at the very start, finds the contacts of the state: ``c_contacts``).
# A step that ends beyond a wall or with a pulling contact is redone shorter, to the
# event (regula falsi, Illinois variant, on the step size: every trial is a DOP853 step
# from the same state, projected), and ends there with the impact or release applied: the
# driver never sees the penetrated state.


def _c_stages(fns, t, y, P, act, h, tableau, buffers, stages, sc):
    """``_rk_stages`` on the constrained ``c_rhs`` with the rows ``act``."""
    A, c = tableau
    K, Yst = buffers
    first, last = stages
    for i in range(first, last):
        for k in range(y.shape[0]):
            acc = 0.0
            for j in range(i):
                acc += A[i, j] * K[j, k]
            Yst[k] = y[k] + h * acc
        c_rhs(fns, t + c[i] * h, Yst, P, act, K[i], sc)


def cdop853_work(coef, m):
    S = coef[1].shape[0]
    k = coef[5][0]
    # K, ynew, ys, y at the left end of an event's bracket, act, act0, mask (the rows
    # watched for an event: value >= 0 at the start of the step), event values, the
    # helpers' scratch, flags [step kept (the driver zeroes it when it undoes one), last
    # rejected, K[0] valid, contacts known, 1 + the row of an event to apply next]
    return (
        np.empty((S + 1, m)),
        np.empty(m),
        np.empty(m),
        np.empty(m),
        np.empty(k),
        np.empty(k),
        np.empty(k),
        np.empty(k),
        c_scratch(k, m // 2),
        np.zeros(5),
    )


def _c_trial(fns, t, y, P, act, h, coef, work):
    """ynew = the DOP853 step of size h from y (K[0] = f(t, y) already), not projected;
    returns the error norm."""
    A, B, C, E3, E5, _sizes, rtol, atol, _hmax = coef
    K, ynew, ys, sc = work[0], work[1], work[2], work[8]
    S = B.shape[0]
    _c_stages(fns, t, y, P, act, h, (A, C), (K, ys), (1, S), sc)
    for k in range(y.shape[0]):
        ynew[k] = y[k] + h * _rk_sum(K, B, k)
    c_rhs(fns, t + h, ynew, P, act, K[S], sc)
    return _dop853_norm(K, E5, E3, h, y, ynew, rtol, atol)


def _c_first(values, mask):
    """(the smallest of ``values`` over the rows with mask > 0, its row)."""
    worst = math.inf
    which = -1
    for i in range(values.shape[0]):
        if mask[i] > 0.0 and values[i] < worst:
            worst = values[i]
            which = i
    return worst, which


def _c_locate(fns, t, y, P, h, coef, work):
    """The event inside a step of size h whose end ``ynew`` has a negative event value:
    the largest step size a found with value >= 0 (regula falsi, Illinois), its state in
    ``ynew``. Returns (a, the event's row, evaluations). ``mask`` (in ``work[6]``) holds the
    rows whose value was >= 0 at the start of the step."""
    K, ynew, ys, ya, act, act0, mask, values, sc, flags = work
    S = coef[1].shape[0]
    evals = 0
    c_event_values(fns, t, y, P, act, values, sc)
    fa, _ = _c_first(values, mask)
    fa = max(fa, 0.0)
    for k in range(y.shape[0]):
        ya[k] = y[k]
    a = 0.0
    b = h
    c_event_values(fns, t + h, ynew, P, act, values, sc)
    fb, which = _c_first(values, mask)
    tol = 1e-15 * max(fa, -fb)
    side = 0
    ga = fa  # the true value at a (fa and fb are weighted down by the Illinois rule)
    for _ in range(120):
        if b - a <= 4e-16 * (abs(t) + b) or (ga <= tol and a > 0.0):
            break
        s = b - fb * (b - a) / (fb - fa)
        if ga <= tol or not (a < s and s < b):
            # a row at zero at the start that leaves and comes back within the step (a
            # low bounce): halve until the bracket's left end is clearly inside
            s = 0.5 * (a + b)
        _c_trial(fns, t, y, P, act, s, coef, work)
        evals += S
        if not c_project(fns, t + s, ynew, P, act, sc) or not _finite(ynew):
            b = s  # no good state there: look before it
            side = 0
            continue
        c_event_values(fns, t + s, ynew, P, act, values, sc)
        fs, row = _c_first(values, mask)
        if fs < 0.0:
            b = s
            fb = fs
            which = row
            if side == -1:
                fa *= 0.5
            side = -1
        else:
            a = s
            fa = fs
            ga = fs
            for k in range(y.shape[0]):
                ya[k] = ynew[k]
            if side == 1:
                fb *= 0.5
            side = 1
    for k in range(y.shape[0]):
        ynew[k] = ya[k]
    return a, which, evals


def cdop853_step(fns, y, comp, clock, P, coef, work):
    """A DOP853 step on the constrained ``c_rhs``; an accepted step is projected onto the
    constraints (positions, then velocities), so they hold to round-off after every step.

    With unilateral constraints, a step that ends beyond a wall (g < 0 on a free row) or
    with a contact that pulls (lambda > 0 on an acting one) is shortened to the event and
    ends there, before it; the next call applies the impact or the release
    (``c_switch``) without moving in time, so the state arriving at a wall and the state
    leaving it are both kept (a drawing shows the jump of the velocities at the wall, not
    a chord across it). Steps are at most ``hmax``, as in ``dop853_step``.
    """
    A, B, C, E3, E5, sizes, rtol, atol, hmax = coef
    K, ynew, ys, ya, act, act0, mask, values, sc, flags = work
    t = clock[CLOCK_T]
    evals = 0
    if flags[0] == 0.0:  # the start, or the driver undid the last step
        if flags[3] == 0.0:
            c_contacts(fns, t, y, P, act, sc)
            flags[3] = 1.0
        else:
            for i in range(act.shape[0]):
                act[i] = act0[i]
        flags[2] = 0.0
        flags[0] = 1.0
        flags[4] = 0.0  # an event found by an undone step is found again
    for i in range(act.shape[0]):
        act0[i] = act[i]
    if flags[4] != 0.0:  # the event the last step ended at: applied here, at the same t
        which = int(flags[4]) - 1
        flags[4] = 0.0
        c_switch(fns, t, y, P, act, which, sc)
        for k in range(y.shape[0]):
            comp[k] = 0.0
        flags[2] = 0.0
        return STATUS_RUNNING, evals
    if flags[2] == 0.0:  # K[0] is f at the start of the step
        c_rhs(fns, t, y, P, act, K[0], sc)
        evals += 1
        flags[2] = 1.0
    S = B.shape[0]
    h = clock[CLOCK_H]
    t_end = clock[CLOCK_T_END]
    last = h >= t_end - t
    if last:
        h = t_end - t
    if h < 1e-14 * max(abs(t), 1.0) * 4.0:
        return STATUS_STEP_COLLAPSED, evals
    err = _c_trial(fns, t, y, P, act, h, coef, work)
    evals += S
    if not err == err or not _finite(ynew):
        clock[CLOCK_H] = h * 0.2
        flags[1] = 1.0
        return STATUS_REJECTED, evals
    if err >= 1.0:
        clock[CLOCK_H] = h * max(0.2, 0.9 * err ** (-1.0 / 8.0))
        flags[1] = 1.0
        return STATUS_REJECTED, evals
    factor = 10.0 if err == 0.0 else min(10.0, 0.9 * err ** (-1.0 / 8.0))
    if flags[1] != 0.0:
        factor = min(1.0, factor)
    if not c_project(fns, t + h, ynew, P, act, sc):
        return STATUS_NOT_CONVERGED, evals
    following = min(h * factor, hmax)
    if sizes[1] < sizes[0]:  # unilateral rows
        c_event_values(fns, t + h, ynew, P, act, values, sc)
        event = False
        for i in range(act.shape[0]):
            if values[i] < 0.0:
                event = True
        if event:
            c_event_values(fns, t, y, P, act, mask, sc)
            for i in range(act.shape[0]):
                mask[i] = 1.0 if mask[i] >= 0.0 and mask[i] < math.inf else 0.0
            _, first = _c_first(values, mask)
            if first >= 0:
                following = h
                h, which, used = _c_locate(fns, t, y, P, h, coef, work)
                evals += used
                last = False
                if h > 0.0:
                    flags[4] = which + 1.0  # the next call applies it
                elif not c_switch(fns, t, ynew, P, act, which, sc):
                    return STATUS_NOT_CONVERGED, evals  # an event at once that changes nothing
    for k in range(y.shape[0]):
        y[k] = ynew[k]
        comp[k] = 0.0
    clock[CLOCK_T] = t_end if last else t + h
    clock[CLOCK_H] = following
    flags[1] = 0.0
    flags[2] = 0.0  # the carried-over f (first same as last) is of the unprojected y
    return STATUS_RUNNING, evals


def cdop853_sample_work(coef, m):
    return cdop853_work(coef, m)


def cdop853_sample(fns, prev, state, s, P, coef, work, swork, scratch, first):
    """The state at ``s``: a DOP853 trial of length ``s - t`` from the start of the last
    step with the rows that acted in it (``act0`` in ``work``), projected onto the
    constraints as every step is. The step's own error control passed a longer trial, so
    the sample is as accurate; an event ends a step, so no sample crosses one."""
    yprev, _, kprev = prev
    ys = scratch[0]
    K, ynew, act, sc = swork[0], swork[1], swork[4], swork[8]
    t0 = kprev[CLOCK_T]
    evals = 0
    if first:
        act0 = work[5]
        for i in range(act.shape[0]):
            act[i] = act0[i]
        c_rhs(fns, t0, yprev, P, act, K[0], sc)
        evals += 1
    _c_trial(fns, t0, yprev, P, act, s - t0, coef, swork)
    evals += coef[1].shape[0]
    for k in range(ys.shape[0]):
        ys[k] = ynew[k]
    if not c_project(fns, s, ys, P, act, sc):
        return STATUS_NOT_CONVERGED, evals
    return STATUS_RUNNING, evals


def cerk_work(coef, m):
    s = coef[0].shape[0]
    k = coef[4][0]
    return (np.empty((s, m)), np.empty(m), np.empty(k), c_scratch(k, m // 2), np.zeros(1))


def cerk_step(fns, y, comp, clock, P, coef, work):
    """A fixed explicit Runge-Kutta step on the equations with the multipliers of the
    bilateral constraints (the registry refuses unilateral ones), then the projection."""
    A, b, c, kahan, _sizes = coef
    K, Yst, act, sc, _ = work
    s = b.shape[0]
    m = y.shape[0]
    t = clock[CLOCK_T]
    h = clock[CLOCK_H]
    c_bilateral(fns, act)
    _c_stages(fns, t, y, P, act, h, (A, c), (K, Yst), (0, s), sc)
    for k in range(m):
        _add(y, comp, k, h * _rk_sum(K, b, k), kahan)
    _tick_fixed(clock)
    if not c_project_bilateral(fns, clock[CLOCK_T], y, P, sc):
        return STATUS_NOT_CONVERGED, s
    for k in range(m):
        comp[k] = 0.0
    return STATUS_RUNNING, s


def cerk_sample_work(coef, m):
    return cerk_work(coef, m)


def cerk_sample(fns, prev, state, s, P, coef, work, swork, scratch, first):
    """The state at ``s``: one step of the method (projected) of length ``s - t`` from
    the start of the last step."""
    _restart(prev, s, scratch)
    return cerk_step(fns, scratch[0], scratch[1], scratch[2], P, coef, swork)


# -- many states at once: a scene's function over the rows of an array ------------------------


def batch_scalar(f, ts, Y, P, out):
    """out[i] = f(ts[i], Y[i], P): H or L at many states."""
    for i in range(Y.shape[0]):
        out[i] = f(ts[i], Y[i], P)


def batch_vector(f, ts, Y, P, out):
    """f(ts[i], Y[i], P, out[i]): the velocities or the drawing's points at many states."""
    for i in range(Y.shape[0]):
        f(ts[i], Y[i], P, out[i])


def batch_pairs(f, ts, Q, Qdot, P, out):
    """f(ts[i], Q[i], Qdot[i], P, out[i]): the momenta from (q, qdot) at many states."""
    for i in range(Q.shape[0]):
        f(ts[i], Q[i], Qdot[i], P, out[i])


# -- a system function called from Python (systems.llvm_kernels) ----------------------------


def call2(f, a, b):
    return f(a, b)


def call3(f, a, b, c):
    return f(a, b, c)


def call4(f, a, b, c, d):
    return f(a, b, c, d)


def call5(f, a, b, c, d, e):
    return f(a, b, c, d, e)


# -- the drivers -------------------------------------------------------------------------------


def DRIVER_run(fns, state, P, coef, work, spare, limits, section, samples, out, info):
    """Up to ``limits = (nsteps, stride)`` accepted steps of the family's ``STEP`` from
    ``state = (y, comp, clock)``.

    ``spare = ((y, comp, clock), swork, (y, comp, clock))``, allocated by the caller: the
    start of each step (to undo it), the family's sample work (``X_sample_work``) and a
    sample's state. The loop allocates nothing, so numba compiles it, and every step and
    sample it calls, without reference counting (``codegen.jit_wrappers``).

    With ``samples = (times, y, comp, clock)`` (times ascending, and the start of the last
    step a former call took, its clock's time nan if none; None: numba compiles the loop
    without them) the output is one row per time instead of every ``stride``-th state:
    the state at
    exactly that time, from the family's ``SAMPLE`` inside the step that contains it (a
    shortened step of the method, or a dense output), never changing the trajectory;
    a time at the end of a step is answered by the next step that moves in time (the
    state after an impact applied there), or by the last state at the end time. Times
    before the current one, inside the last step of a former call (which returned after
    the last time it had, and could not know the next), are answered first from the
    start of that step, kept in ``samples`` (the work still holds that step's). The
    call returns after the last of them (``info[INFO_SAMPLED]``: how many were answered,
    each one row). A sample that fails (a shortened implicit step that does not
    converge) undoes the step and ends the call with its status.

    ``out = (out_t (k,), out_y (k, m), ev_t (e, 2), ev_y (e, 2, m))`` receives every
    ``stride``-th state, both states of a jump (a step that applies an event without
    moving in time) where ``out_t`` has room beyond the strided states, and the states
    on both sides of each crossing of
    ``y[index] = value`` for ``section = (index, value, direction)`` (None: numba compiles
    the loop without event code). Returns through ``info`` (``INFO_*`` slots). A step that
    fails or leaves a non-finite state is undone, so ``y``, ``comp`` and ``clock`` always
    hold the last good state; so is a step past ``clock[CLOCK_T_END]``
    (``STATUS_OVERSHOT``). The call also returns after the first step that reaches
    ``clock[CLOCK_T_PAUSE]``, which changes nothing in the solution.
    """
    y, comp, clock = state
    nsteps, stride = limits
    out_t, out_y, ev_t, ev_y = out
    m = y.shape[0]
    prev, swork, scratch = spare
    yprev, cprev, kprev = prev
    ev_index = -1
    ev_value = 0.0
    ev_dir = 0.0
    if section is not None:  # None: numba compiles the loop without event code
        ev_index = int(section[0])
        ev_value = section[1]
        ev_dir = section[2]
    t_end = clock[CLOCK_T_END]
    slack = 1e-12 * max(abs(t_end), abs(clock[CLOCK_H]))
    status = STATUS_RUNNING
    steps = 0
    evals = 0
    outputs = 0
    events = 0
    count = 0
    sampled = 0
    if samples is not None:
        times, last_y, last_c, last_k = samples
        if last_k[CLOCK_T] == last_k[CLOCK_T]:  # the start of a former call's last step
            code, used, sampled, outputs = DRIVER_answer(
                fns, (last_y, last_c, last_k), (y, comp, clock), P, coef, work,
                (swork, scratch), times, (sampled, outputs), (out_t, out_y),
            )  # fmt: skip
            evals += used
            if code != STATUS_RUNNING:
                status = code
                nsteps = 0  # nothing more: the call ends here with the problem
        if sampled > 0 and sampled >= times.shape[0]:
            nsteps = 0  # all answered: a step now would lose the start of the last one
    wrote = True  # the state before the first step: the caller has it
    while steps < nsteps:
        for k in range(m):
            yprev[k] = y[k]
            cprev[k] = comp[k]
        for k in range(clock.shape[0]):
            kprev[k] = clock[k]
        code, used = STEP(fns, y, comp, clock, P, coef, work)
        evals += used
        if code == STATUS_REJECTED:
            continue
        if code == STATUS_RUNNING and not _finite(y):
            code = STATUS_NON_FINITE
        if code == STATUS_RUNNING and clock[CLOCK_T] > t_end + slack:
            code = STATUS_OVERSHOT
        answered = outputs
        if samples is not None and code == STATUS_RUNNING:
            if clock[CLOCK_T] > kprev[CLOCK_T]:  # a jump (an impact) answers none
                code, used, sampled, outputs = DRIVER_answer(
                    fns, (yprev, cprev, kprev), (y, comp, clock), P, coef, work,
                    (swork, scratch), samples[0], (sampled, outputs), (out_t, out_y),
                )  # fmt: skip
                evals += used
            if code != STATUS_RUNNING:  # the step is undone: so are its samples
                sampled -= outputs - answered
                outputs = answered
            else:  # the start of the step, for the times after the call's last
                for k in range(m):
                    samples[1][k] = yprev[k]
                    samples[2][k] = cprev[k]
                for k in range(clock.shape[0]):
                    samples[3][k] = kprev[k]
        if code != STATUS_RUNNING:
            for k in range(m):
                y[k] = yprev[k]
                comp[k] = cprev[k]
            for k in range(clock.shape[0]):
                clock[k] = kprev[k]
            work[-1][0] = 0.0  # what the step carried over belongs to the undone state
            status = code
            break
        steps += 1
        t = clock[CLOCK_T]
        if section is not None:
            if (
                ev_index >= 0
                and events < ev_t.shape[0]
                and t > kprev[CLOCK_T]  # not an impact's jump: the flow crosses sections
                and _crossed(yprev[ev_index] - ev_value, y[ev_index] - ev_value, ev_dir)
            ):
                ev_t[events, 0] = kprev[CLOCK_T]
                ev_t[events, 1] = t
                for k in range(m):
                    ev_y[events, 0, k] = yprev[k]
                    ev_y[events, 1, k] = y[k]
                events += 1
        if samples is not None:
            if t >= t_end - slack:  # the times at the end: its state
                while (
                    sampled < samples[0].shape[0]
                    and samples[0][sampled] <= t_end + slack
                    and outputs < out_t.shape[0]
                ):
                    out_t[outputs] = samples[0][sampled]
                    for k in range(m):
                        out_y[outputs, k] = y[k]
                    outputs += 1
                    sampled += 1
                status = STATUS_END
                break
            if t >= clock[CLOCK_T_PAUSE] or sampled >= samples[0].shape[0]:
                break
            continue
        count += 1
        # a step that does not move in time applied an event (an impact): the states on
        # both sides of the jump are kept whatever the stride, while the rows left for
        # the strided output still fit
        jump = t == kprev[CLOCK_T] and outputs + (nsteps - steps) // stride + 3 <= out_t.shape[0]
        if jump and not wrote:
            out_t[outputs] = kprev[CLOCK_T]
            for k in range(m):
                out_y[outputs, k] = yprev[k]
            outputs += 1
        wrote = False
        if count == stride or jump:
            count = 0
            if outputs < out_t.shape[0]:
                out_t[outputs] = t
                for k in range(m):
                    out_y[outputs, k] = y[k]
                outputs += 1
                wrote = True
        if t >= t_end - slack:
            status = STATUS_END
            break
        if t >= clock[CLOCK_T_PAUSE]:
            break
    info[INFO_STEPS] = steps
    info[INFO_OUTPUTS] = outputs
    info[INFO_STATUS] = status
    info[INFO_EVENTS] = events
    info[INFO_EVALUATIONS] = evals
    info[INFO_SAMPLED] = sampled


def DRIVER_answer(fns, prev, state, P, coef, work, scratch, times, counts, out):
    """The rows for the times ``times[sampled:]`` before the time of ``state`` (the end of
    the step from ``prev``; ``counts = (sampled, outputs)``): a time at the step's start
    gets its state (after any jump applied there), the others ``SAMPLE_ROWS``'s, into
    ``out = (out_t, out_y)`` from row ``outputs``. ``scratch = (swork, (y, comp,
    clock))``. Returns (status, evaluations, sampled, outputs); a sample that fails ends
    it with the problem's status."""
    yprev, _, kprev = prev
    swork, states = scratch
    out_t, out_y = out
    sampled, outputs = counts
    t = state[2][CLOCK_T]
    room = out_t.shape[0]
    while sampled < times.shape[0] and times[sampled] <= kprev[CLOCK_T] and outputs < room:
        out_t[outputs] = times[sampled]
        for k in range(yprev.shape[0]):
            out_y[outputs, k] = yprev[k]
        outputs += 1
        sampled += 1
    end = sampled  # the times inside the step, as many as there is room for
    while end < times.shape[0] and times[end] < t and outputs + (end - sampled) < room:
        end += 1
    if end == sampled:
        return STATUS_RUNNING, 0, sampled, outputs
    code, evals, done = SAMPLE_ROWS(
        fns, prev, state, times, sampled, end, P, coef, work, swork, states, out_y, outputs
    )
    for j in range(done):
        out_t[outputs + j] = times[sampled + j]
    return code, evals, sampled + done, outputs + done


def DRIVER_sample_rows(fns, prev, state, times, lo, hi, P, coef, work, swork, states, out_y, row):
    """``out_y[row + j]`` the state at ``times[lo + j]`` (inside the step from ``prev`` to
    ``state``) for j < ``hi - lo``, one ``SAMPLE`` each, until one fails or is not
    finite. Returns (status, evaluations, rows written). A family may define its own
    ``X_sample_rows`` (the taylor family's takes two rows at a time)."""
    evals = 0
    for j in range(hi - lo):
        code, used = SAMPLE(fns, prev, state, times[lo + j], P, coef, work, swork, states, j == 0)
        evals += used
        if code == STATUS_RUNNING and not _finite(states[0]):
            code = STATUS_NON_FINITE
        if code != STATUS_RUNNING:
            return code, evals, j
        for k in range(states[0].shape[0]):
            out_y[row + j, k] = states[0][k]
    return STATUS_RUNNING, evals, hi - lo


def DRIVER_fictitious(fns, prev, state, s, P, coef, swork, scratch):
    """The state at ``s`` inside the last step of a family that steps in fictitious time
    (``STEP`` advances the clock by the physical time of a fictitious step
    ``clock[CLOCK_H]``): the fictitious step from the last step's start (``prev``) whose
    physical duration is ``s - t``, by regula falsi (Illinois) between 0 and the last
    step's, each trial one ``STEP`` on ``scratch`` with its own work (``swork = (work,
    bracket)``; the work's flag cleared: nothing carried over). Ends when the duration
    is within a few units of round-off of ``s``."""
    scr, bracket = swork
    ys, cs, ks = scratch
    kprev = prev[2]
    goal = s - kprev[CLOCK_T]
    full = _elapsed(kprev, state[2])
    bracket[0] = 0.0
    bracket[1] = -goal
    bracket[2] = kprev[CLOCK_H]
    bracket[3] = full - goal
    bracket[4] = 0.0
    sigma = kprev[CLOCK_H] * goal / full
    tol = 4e-16 * max(abs(s), abs(kprev[CLOCK_T]))
    evals = 0
    f = math.inf
    for _ in range(TT_ITERATIONS):
        _restart(prev, s, scratch)
        ks[CLOCK_H] = sigma
        scr[-1][0] = 0.0
        code, used = STEP(fns, ys, cs, ks, P, coef, scr)
        evals += used
        if code != STATUS_RUNNING:
            return code, evals
        f = _elapsed(kprev, ks) - goal
        if abs(f) <= tol:
            return STATUS_RUNNING, evals
        sigma = _illinois(bracket, sigma, f)
    if abs(f) <= 1e-13 * max(abs(s), full):
        return STATUS_RUNNING, evals
    return STATUS_NOT_CONVERGED, evals


def DRIVER_ensemble_parallel(fns, Y, clock0, P, coef, limits, out, status):
    """Many initial states ``Y`` (N, m) at once, advanced in place, rows spread over cores.

    Every ``stride``-th state of ``limits = (nsteps, stride)`` goes to ``out`` (N, k, m);
    ``status`` (N,) gets ``STATUS_RUNNING`` or the problem that stopped a row.
    """
    nsteps, stride = limits
    N = Y.shape[0]
    m = Y.shape[1]
    for r in prange(N):
        y = Y[r]
        comp = np.zeros(m)
        clock = clock0.copy()
        work = WORK(coef, m)
        status[r] = STATUS_RUNNING
        count = 0
        j = 0
        steps = 0
        while steps < nsteps:
            code, used = STEP(fns, y, comp, clock, P, coef, work)
            if code == STATUS_REJECTED:
                continue
            if code == STATUS_RUNNING and not _finite(y):
                code = STATUS_NON_FINITE
            if code != STATUS_RUNNING:
                status[r] = code
                break
            steps += 1
            count += 1
            if count == stride:
                count = 0
                if j < out.shape[1]:
                    for k in range(m):
                        out[r, j, k] = y[k]
                    j += 1


def DRIVER_ensemble_adaptive_parallel(fns, Y, clock0, P, coef, times, limits, out, status, counts):
    """Many initial states ``Y`` (N, m) at once, each with its own adaptive steps, rows
    spread over cores: the adaptive families' ensemble (the taylor family's).

    Each row starts from ``clock0`` (its ``CLOCK_T_END`` the end time, never passed) and
    takes at most ``limits[0]`` steps; ``out`` (N, k, m) gets its states at ``times``
    (k,), ascending, after the start and at most the end time, each from the family's
    ``SAMPLE`` inside the step that contains it (a dense output: the trajectory is the
    one a single run takes), a time at the end the end's state. ``status`` (N,) gets
    ``STATUS_END`` or the problem that stopped a row (its later rows of ``out`` are left
    as they were), ``counts`` (N,) the steps taken. The rows share nothing: a row's work
    and scratch are its own.
    """
    nsteps = limits[0]
    N = Y.shape[0]
    m = Y.shape[1]
    c = clock0.shape[0]
    for r in prange(N):
        y = Y[r]
        comp = np.zeros(m)
        clock = clock0.copy()
        work = WORK(coef, m)
        swork = SAMPLE_WORK(coef, m)
        prev = (np.empty(m), np.empty(m), np.empty(c))
        scratch = (np.empty(m), np.empty(m), np.empty(c))
        yprev, cprev, kprev = prev
        t_end = clock[CLOCK_T_END]
        slack = 1e-12 * max(abs(t_end), abs(clock[CLOCK_H]))
        code = STATUS_RUNNING
        steps = 0
        j = 0
        while code == STATUS_RUNNING and steps < nsteps:
            for k in range(m):
                yprev[k] = y[k]
                cprev[k] = comp[k]
            for k in range(c):
                kprev[k] = clock[k]
            code, used = STEP(fns, y, comp, clock, P, coef, work)
            if code == STATUS_REJECTED:
                code = STATUS_RUNNING
                continue
            if code == STATUS_RUNNING and not _finite(y):
                code = STATUS_NON_FINITE
            if code == STATUS_RUNNING and clock[CLOCK_T] > t_end + slack:
                code = STATUS_OVERSHOT
            if code != STATUS_RUNNING:
                for k in range(m):
                    y[k] = yprev[k]
                break
            steps += 1
            t = clock[CLOCK_T]
            first = True
            while j < times.shape[0] and times[j] < t:
                if times[j] <= kprev[CLOCK_T]:
                    for k in range(m):
                        out[r, j, k] = yprev[k]
                else:
                    code, used = SAMPLE(
                        fns, prev, (y, comp, clock), times[j], P, coef, work, swork, scratch,
                        first,
                    )  # fmt: skip
                    first = False
                    if code != STATUS_RUNNING:
                        break
                    for k in range(m):
                        out[r, j, k] = scratch[0][k]
                j += 1
            if code == STATUS_RUNNING and t >= t_end - slack:
                while j < times.shape[0]:
                    for k in range(m):
                        out[r, j, k] = y[k]
                    j += 1
                code = STATUS_END
        status[r] = code
        counts[r] = steps
