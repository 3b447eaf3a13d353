# ruff: noqa: F821
# The stepper templates below call the system functions ``rhs``, ``kinetic``,
# ``potential``, ``grad_kinetic``, ``grad_potential`` and the constant ``N_DOF`` by global
# name. They are not defined here: ``systems.codegen.build_module`` copies everything after
# the marker line into each scene's generated module, next to the system functions printed
# from sympy, and wraps every top-level function in ``numba.njit(nogil=True, cache=True)``.
"""Stepper templates: compiled stepping loops shared by every scene's kernel module.

This module is imported only for its source text (``systems.codegen.template_source``);
the functions are never called from here. Conventions shared by all ``*_run`` loops:

- ``y`` (shape ``(2n,)``) is the state ``(q, p)``, advanced in place.
- ``comp`` (shape ``(2n + 1,)``) holds the Kahan compensation terms of ``y`` (and of ``t``
  for time-transformed loops); it persists between calls.
- ``out_t`` (shape ``(m,)``) and ``out_y`` (shape ``(m, 2n)``) receive every
  ``stride``-th state.
- ``ev_spec = (index, value, direction)`` asks for crossings of ``y[index] = value``
  (None: none, and numba then compiles the loop without the event code); the states
  on both sides of each crossing are written to ``ev_t`` (shape ``(e, 2)``) and
  ``ev_y`` (shape ``(e, 2, 2n)``), for interpolation.
- ``info`` (int64, shape ``(8,)``) returns ``[steps, outputs, status, events,
  rhs_evaluations, iterations_max, 0, 0]``. Status 0 is fine, 1 a non-finite state,
  2 an implicit solve that did not converge, 3 an invalid time transformation, 4 a step
  size that collapsed, 5 the end time was reached. On a problem, ``y`` is left at the
  last good state and ``steps`` counts the good steps.
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


def _crossed(before, after, direction):
    if direction >= 0 and before < 0.0 and after >= 0.0:
        return True
    if direction <= 0 and before > 0.0 and after <= 0.0:
        return True
    return False


def _record_event(ev_t, ev_y, info, t_before, y_before, t_after, y_after):
    e = info[3]
    if e < ev_t.shape[0]:
        ev_t[e, 0] = t_before
        ev_t[e, 1] = t_after
        for k in range(y_after.shape[0]):
            ev_y[e, 0, k] = y_before[k]
            ev_y[e, 1, k] = y_after[k]
        info[3] = e + 1


def compose_run(
    t0,
    y,
    comp,
    P,
    dt,
    nsteps,
    stride,
    kick,
    drift,
    kahan,
    ev_spec,
    out_t,
    out_y,
    ev_t,
    ev_y,
    info,
):
    """Composition of kick-drift-kick leapfrogs for H = T(p) + V(t, q).

    ``kick`` (shape ``(s + 1,)``) and ``drift`` (shape ``(s,)``) are the merged stage
    coefficients; one gradient of V per stage (first same as last).
    """
    n = N_DOF
    F = np.empty(n)
    G = np.empty(n)
    yprev = np.empty(2 * n)
    q = y[:n]
    p = y[n:]
    ns = drift.shape[0]
    ev_index = -1
    ev_value = 0.0
    ev_dir = 0.0
    if ev_spec is not None:  # None: numba compiles the loop without event code
        ev_index = int(ev_spec[0])
        ev_value = ev_spec[1]
        ev_dir = ev_spec[2]
    grad_potential(t0, q, P, F)
    evals = 1
    info[0] = 0
    info[1] = 0
    info[2] = 0
    info[3] = 0
    count = 0
    for i in range(nsteps):
        t = t0 + i * dt
        for k in range(2 * n):
            yprev[k] = y[k]
        tau = t
        for j in range(ns + 1):
            h = kick[j] * dt
            for k in range(n):
                d = -h * F[k]
                if kahan:
                    dd = d - comp[n + k]
                    s = p[k] + dd
                    comp[n + k] = (s - p[k]) - dd
                    p[k] = s
                else:
                    p[k] += d
            if j < ns:
                h = drift[j] * dt
                grad_kinetic(p, P, G)
                for k in range(n):
                    d = h * G[k]
                    if kahan:
                        dd = d - comp[k]
                        s = q[k] + dd
                        comp[k] = (s - q[k]) - dd
                        q[k] = s
                    else:
                        q[k] += d
                tau += h
                grad_potential(tau, q, P, F)
                evals += 1
        if not _finite(y):
            # report the last finite state: undo the failed step
            for k in range(2 * n):
                y[k] = yprev[k]
            info[0] = i
            info[2] = 1
            info[4] = evals
            return
        if ev_spec is not None:
            if ev_index >= 0 and _crossed(
                yprev[ev_index] - ev_value, y[ev_index] - ev_value, ev_dir
            ):
                _record_event(ev_t, ev_y, info, t, yprev, t + dt, y)
        count += 1
        if count == stride:
            count = 0
            m = info[1]
            if m < out_t.shape[0]:
                out_t[m] = t + dt
                for k in range(2 * n):
                    out_y[m, k] = y[k]
                info[1] = m + 1
    info[0] = nsteps
    info[4] = evals


def compose_ensemble_parallel(t0, Y, P, dt, nsteps, stride, kick, drift, out, status):
    """Many initial states at once: ``Y`` (N, 2n) advanced in place by ``nsteps`` steps.

    Every ``stride``-th state goes to ``out`` (N, m, 2n); ``status`` (N,) gets 0 or 1
    (non-finite). One compiled loop over the rows, spread over the cores.
    """
    N = Y.shape[0]
    n = N_DOF
    for r in prange(N):
        F = np.empty(n)
        G = np.empty(n)
        y = Y[r]
        q = y[:n]
        p = y[n:]
        ns = drift.shape[0]
        grad_potential(t0, q, P, F)
        count = 0
        m = 0
        status[r] = 0
        for i in range(nsteps):
            tau = t0 + i * dt
            for j in range(ns + 1):
                h = kick[j] * dt
                for k in range(n):
                    p[k] -= h * F[k]
                if j < ns:
                    h = drift[j] * dt
                    grad_kinetic(p, P, G)
                    for k in range(n):
                        q[k] += h * G[k]
                    tau += h
                    grad_potential(tau, q, P, F)
            if not _finite(y):
                status[r] = 1
                break
            count += 1
            if count == stride:
                count = 0
                if m < out.shape[1]:
                    for k in range(2 * n):
                        out[r, m, k] = y[k]
                    m += 1


def _gauss_step(t, y, P, dt, A, b, c, Z, F, Yst, tol, maxit):
    """One collocation step: solve for the stage increments ``Z`` (s, 2n) by fixed-point
    iteration from the guess already in ``Z``; returns (iterations, converged)."""
    s = b.shape[0]
    m = y.shape[0]
    prev = np.inf
    converged = False
    it = 0
    while it < maxit:
        it += 1
        for i in range(s):
            for k in range(m):
                Yst[k] = y[k] + Z[i, k]
            rhs(t + c[i] * dt, Yst, P, F[i])
        diff = 0.0
        for i in range(s):
            for k in range(m):
                z = 0.0
                for j in range(s):
                    z += A[i, j] * F[j, k]
                z *= dt
                d = abs(z - Z[i, k]) / (1.0 + abs(y[k]))
                if d > diff:
                    diff = d
                Z[i, k] = z
        if not diff == diff:
            break
        if diff <= tol:
            converged = True
            break
        if diff >= prev and diff < 1e-10:
            # round-off level reached (Hairer's criterion): further iterations only wander
            converged = True
            break
        prev = diff
    if not converged and diff < 1e-10:
        converged = True
    if converged:
        # the increment uses F(y + Z) of the converged stages
        for i in range(s):
            for k in range(m):
                Yst[k] = y[k] + Z[i, k]
            rhs(t + c[i] * dt, Yst, P, F[i])
        it += 1
    return it, converged


def gauss_run(
    t0,
    y,
    comp,
    P,
    dt,
    nsteps,
    stride,
    A,
    b,
    c,
    E,
    Z,
    zvalid,
    tol,
    maxit,
    kahan,
    ev_spec,
    out_t,
    out_y,
    ev_t,
    ev_y,
    info,
):
    """Gauss-Legendre collocation with ``s`` stages (order 2s) for any H (and any rhs).

    ``A`` (s, s), ``b`` (s,), ``c`` (s,) the tableau; ``E`` (s, s) extrapolates the stage
    increments ``Z`` (s, 2n) of one step to the starting guess of the next (the
    collocation polynomial continued). ``zvalid`` (shape (1,)) says whether ``Z`` holds
    the last step's stages; it and ``Z`` persist between calls.
    """
    n = N_DOF
    m = 2 * n
    s = b.shape[0]
    F = np.empty((s, m))
    Yst = np.empty(m)
    Zold = np.empty((s, m))
    yprev = np.empty(m)
    ev_index = -1
    ev_value = 0.0
    ev_dir = 0.0
    if ev_spec is not None:  # None: numba compiles the loop without event code
        ev_index = int(ev_spec[0])
        ev_value = ev_spec[1]
        ev_dir = ev_spec[2]
    evals = 0
    itmax = 0
    info[0] = 0
    info[1] = 0
    info[2] = 0
    info[3] = 0
    count = 0
    for i in range(nsteps):
        t = t0 + i * dt
        if zvalid[0] == 0:
            rhs(t, y, P, F[0])
            evals += 1
            for j in range(s):
                for k in range(m):
                    Z[j, k] = c[j] * dt * F[0, k]
        for k in range(m):
            yprev[k] = y[k]
        its, ok = _gauss_step(t, y, P, dt, A, b, c, Z, F, Yst, tol, maxit)
        evals += its * s
        if its > itmax:
            itmax = its
        if not ok:
            info[0] = i
            info[2] = 2
            info[4] = evals
            info[5] = itmax
            zvalid[0] = 0
            return
        for k in range(m):
            d = 0.0
            for j in range(s):
                d += b[j] * F[j, k]
            d *= dt
            if kahan:
                dd = d - comp[k]
                sm = y[k] + dd
                comp[k] = (sm - y[k]) - dd
                y[k] = sm
            else:
                y[k] += d
        if not _finite(y):
            for k in range(m):
                y[k] = yprev[k]
            info[0] = i
            info[2] = 1
            info[4] = evals
            info[5] = itmax
            zvalid[0] = 0
            return
        for j in range(s):
            for k in range(m):
                Zold[j, k] = Z[j, k]
        for j in range(s):
            for k in range(m):
                z = 0.0
                for l in range(s):
                    z += E[j, l] * Zold[l, k]
                Z[j, k] = z
        zvalid[0] = 1
        if ev_spec is not None:
            if ev_index >= 0 and _crossed(
                yprev[ev_index] - ev_value, y[ev_index] - ev_value, ev_dir
            ):
                _record_event(ev_t, ev_y, info, t, yprev, t + dt, y)
        count += 1
        if count == stride:
            count = 0
            mo = info[1]
            if mo < out_t.shape[0]:
                out_t[mo] = t + dt
                for k in range(m):
                    out_y[mo, k] = y[k]
                info[1] = mo + 1
    info[0] = nsteps
    info[4] = evals
    info[5] = itmax


def gauss_ensemble_parallel(t0, Y, P, dt, nsteps, stride, A, b, c, E, tol, maxit, out, status):
    """Gauss-Legendre for many initial states ``Y`` (N, 2n), advanced in place.

    ``out`` (N, m, 2n) receives every ``stride``-th state; ``status`` (N,) 0, 1
    (non-finite) or 2 (no convergence).
    """
    N = Y.shape[0]
    n = N_DOF
    mm = 2 * n
    for r in prange(N):
        s = b.shape[0]
        F = np.empty((s, mm))
        Yst = np.empty(mm)
        Z = np.empty((s, mm))
        Zold = np.empty((s, mm))
        y = Y[r]
        rhs(t0, y, P, F[0])
        for j in range(s):
            for k in range(mm):
                Z[j, k] = c[j] * dt * F[0, k]
        status[r] = 0
        count = 0
        m = 0
        for i in range(nsteps):
            t = t0 + i * dt
            its, ok = _gauss_step(t, y, P, dt, A, b, c, Z, F, Yst, tol, maxit)
            if not ok:
                status[r] = 2
                break
            for k in range(mm):
                d = 0.0
                for j in range(s):
                    d += b[j] * F[j, k]
                y[k] += d * dt
            if not _finite(y):
                status[r] = 1
                break
            for j in range(s):
                for k in range(mm):
                    Zold[j, k] = Z[j, k]
            for j in range(s):
                for k in range(mm):
                    z = 0.0
                    for l in range(s):
                        z += E[j, l] * Zold[l, k]
                    Z[j, k] = z
            count += 1
            if count == stride:
                count = 0
                if m < out.shape[1]:
                    for k in range(mm):
                        out[r, m, k] = y[k]
                    m += 1


def _rate(f, fscale, power):
    """Sundman time-transformation factor g = (|f0| / |f|)^power of a state with rhs f."""
    acc = 0.0
    for k in range(f.shape[0]):
        acc += f[k] * f[k]
    norm = math.sqrt(acc)
    if norm == 0.0:
        return 1e3
    return min((fscale / norm) ** power, 1e3)


def gauss_tt_run(
    tq,
    y,
    comp,
    P,
    ds,
    nsteps,
    stride,
    A,
    b,
    c,
    E,
    Z,
    T,
    zvalid,
    fscale,
    power,
    t_end,
    tol,
    maxit,
    ev_spec,
    out_t,
    out_y,
    ev_t,
    ev_y,
    info,
):
    """Gauss-Legendre collocation on the Sundman-transformed system, for any rhs.

    In fictitious time s: dy/ds = g(y) f(t, y), dt/ds = g(y), with
    g = (fscale / |f(y)|)^power (so g = 1 where |f| = fscale, and g ~ r^1.5 near a 1/r
    singularity for power 3/4). A symmetric method on a reversible system: energy errors
    stay bounded on Kepler-like orbits though the map is not symplectic. ``tq`` (1,)
    holds t; ``Z`` (s, 2n) and ``T`` (s,) the stage increments of y and t, extrapolated
    by ``E`` to the next step's guess. A step that would pass ``t_end`` is undone
    (status 5), as in ``logh_run``.
    """
    n = N_DOF
    m = 2 * n
    s = b.shape[0]
    F = np.empty((s, m))
    G = np.empty(s)
    Yst = np.empty(m)
    Zold = np.empty((s, m))
    Told = np.empty(s)
    yprev = np.empty(m)
    ev_index = -1
    ev_value = 0.0
    ev_dir = 0.0
    if ev_spec is not None:  # None: numba compiles the loop without event code
        ev_index = int(ev_spec[0])
        ev_value = ev_spec[1]
        ev_dir = ev_spec[2]
    evals = 0
    info[0] = 0
    info[1] = 0
    info[2] = 0
    info[3] = 0
    count = 0
    for i in range(nsteps):
        t = tq[0]
        if zvalid[0] == 0:
            rhs(t, y, P, F[0])
            evals += 1
            g0 = _rate(F[0], fscale, power)
            for j in range(s):
                T[j] = c[j] * ds * g0
                for k in range(m):
                    Z[j, k] = c[j] * ds * g0 * F[0, k]
        for k in range(m):
            yprev[k] = y[k]
        prev = np.inf
        converged = False
        it = 0
        diff = 0.0
        while it < maxit:
            it += 1
            for j in range(s):
                for k in range(m):
                    Yst[k] = y[k] + Z[j, k]
                rhs(t + T[j], Yst, P, F[j])
                G[j] = _rate(F[j], fscale, power)
            diff = 0.0
            for j in range(s):
                tz = 0.0
                for l in range(s):
                    tz += A[j, l] * G[l]
                T[j] = tz * ds
                for k in range(m):
                    z = 0.0
                    for l in range(s):
                        z += A[j, l] * G[l] * F[l, k]
                    z *= ds
                    d = abs(z - Z[j, k]) / (1.0 + abs(y[k]))
                    if d > diff:
                        diff = d
                    Z[j, k] = z
            if not diff == diff:
                break
            if diff <= tol or (diff >= prev and diff < 1e-10):
                converged = True
                break
            prev = diff
        evals += it * s
        if not converged and diff < 1e-10:
            converged = True
        if not converged:
            info[0] = i
            info[2] = 2
            info[4] = evals
            zvalid[0] = 0
            return
        for j in range(s):
            for k in range(m):
                Yst[k] = y[k] + Z[j, k]
            rhs(t + T[j], Yst, P, F[j])
            G[j] = _rate(F[j], fscale, power)
        evals += s
        dt = 0.0
        for j in range(s):
            dt += b[j] * G[j]
        dt *= ds
        if t + dt > t_end:
            zvalid[0] = 0
            info[0] = i
            info[2] = 5
            info[4] = evals
            return
        for k in range(m):
            d = 0.0
            for j in range(s):
                d += b[j] * G[j] * F[j, k]
            d *= ds
            dd = d - comp[k]
            sm = y[k] + dd
            comp[k] = (sm - y[k]) - dd
            y[k] = sm
        dd = dt - comp[m]
        sm = tq[0] + dd
        comp[m] = (sm - tq[0]) - dd
        tq[0] = sm
        if not _finite(y):
            for k in range(m):
                y[k] = yprev[k]
            tq[0] = t
            info[0] = i
            info[2] = 1
            info[4] = evals
            zvalid[0] = 0
            return
        for j in range(s):
            Told[j] = T[j]
            for k in range(m):
                Zold[j, k] = Z[j, k]
        for j in range(s):
            tz = 0.0
            for l in range(s):
                tz += E[j, l] * Told[l]
            T[j] = tz
            for k in range(m):
                z = 0.0
                for l in range(s):
                    z += E[j, l] * Zold[l, k]
                Z[j, k] = z
        zvalid[0] = 1
        if ev_spec is not None:
            if ev_index >= 0 and _crossed(
                yprev[ev_index] - ev_value, y[ev_index] - ev_value, ev_dir
            ):
                _record_event(ev_t, ev_y, info, t, yprev, tq[0], y)
        count += 1
        if count == stride:
            count = 0
            mo = info[1]
            if mo < out_t.shape[0]:
                out_t[mo] = tq[0]
                for k in range(m):
                    out_y[mo, k] = y[k]
                info[1] = mo + 1
    info[0] = nsteps
    info[4] = evals


def logh_run(
    tq,
    y,
    comp,
    P,
    ds,
    nsteps,
    stride,
    kick,
    drift,
    energy,
    t_end,
    kahan,
    ev_spec,
    out_t,
    out_y,
    ev_t,
    ev_y,
    info,
):
    """Logarithmic-Hamiltonian (Mikkola-Tanikawa, Preto-Tremaine) leapfrog compositions.

    Time is a coordinate (``tq``, shape (1,), advanced in place) with momentum
    ``-energy``; the fictitious time step is ``ds``. Drifts advance ``dt = a ds / (T - E)``,
    kicks ``dt = b ds / (-V)``, both positive only while V < 0 (attractive, singular
    potentials such as -k/r): otherwise status 3. A step that would pass ``t_end`` is
    undone and the loop returns status 5, leaving the remainder to the caller.
    For autonomous separable H = T(p) + V(q); ``kick``/``drift`` as in ``compose_run``
    (the drift here plays the role of the half steps).
    """
    n = N_DOF
    m = 2 * n
    F = np.empty(n)
    G = np.empty(n)
    yprev = np.empty(m)
    cprev = np.empty(m + 1)
    q = y[:n]
    p = y[n:]
    ns = drift.shape[0]
    ev_index = -1
    ev_value = 0.0
    ev_dir = 0.0
    if ev_spec is not None:  # None: numba compiles the loop without event code
        ev_index = int(ev_spec[0])
        ev_value = ev_spec[1]
        ev_dir = ev_spec[2]
    info[0] = 0
    info[1] = 0
    info[2] = 0
    info[3] = 0
    evals = 0
    count = 0
    for i in range(nsteps):
        t_before = tq[0]
        for k in range(m):
            yprev[k] = y[k]
            cprev[k] = comp[k]
        cprev[m] = comp[m]
        bad = False
        for j in range(ns + 1):
            # drift (the first split part here): q and t advance
            w = kinetic(p, P) - energy
            if not w > 0.0:
                bad = True
                break
            h = kick[j] * ds / w
            grad_kinetic(p, P, G)
            for k in range(n):
                d = h * G[k]
                if kahan:
                    dd = d - comp[k]
                    sm = q[k] + dd
                    comp[k] = (sm - q[k]) - dd
                    q[k] = sm
                else:
                    q[k] += d
            if kahan:
                dd = h - comp[m]
                sm = tq[0] + dd
                comp[m] = (sm - tq[0]) - dd
                tq[0] = sm
            else:
                tq[0] += h
            if j < ns:
                u = -potential(tq[0], q, P)
                if not u > 0.0:
                    bad = True
                    break
                h = drift[j] * ds / u
                grad_potential(tq[0], q, P, F)
                evals += 1
                for k in range(n):
                    d = -h * F[k]
                    if kahan:
                        dd = d - comp[n + k]
                        sm = p[k] + dd
                        comp[n + k] = (sm - p[k]) - dd
                        p[k] = sm
                    else:
                        p[k] += d
        if bad or not _finite(y) or not tq[0] == tq[0]:
            for k in range(m):
                y[k] = yprev[k]
                comp[k] = cprev[k]
            comp[m] = cprev[m]
            tq[0] = t_before
            info[0] = i
            info[2] = 3 if bad else 1
            info[4] = evals
            return
        if tq[0] > t_end:
            for k in range(m):
                y[k] = yprev[k]
                comp[k] = cprev[k]
            comp[m] = cprev[m]
            tq[0] = t_before
            info[0] = i
            info[2] = 5
            info[4] = evals
            return
        if ev_spec is not None:
            if ev_index >= 0 and _crossed(
                yprev[ev_index] - ev_value, y[ev_index] - ev_value, ev_dir
            ):
                _record_event(ev_t, ev_y, info, t_before, yprev, tq[0], y)
        count += 1
        if count == stride:
            count = 0
            mo = info[1]
            if mo < out_t.shape[0]:
                out_t[mo] = tq[0]
                for k in range(m):
                    out_y[mo, k] = y[k]
                info[1] = mo + 1
    info[0] = nsteps
    info[4] = evals


def _dop853_norm(K, E5, E3, h, y, ynew, rtol, atol):
    m = y.shape[0]
    e5 = 0.0
    e3 = 0.0
    for k in range(m):
        sc = atol + rtol * max(abs(y[k]), abs(ynew[k]))
        a5 = 0.0
        a3 = 0.0
        for j in range(K.shape[0]):
            a5 += K[j, k] * E5[j]
            a3 += K[j, k] * E3[j]
        a5 /= sc
        a3 /= sc
        e5 += a5 * a5
        e3 += a3 * a3
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * m)


def dop853_run(
    state,
    y,
    P,
    t_end,
    rtol,
    atol,
    max_steps,
    A,
    B,
    C,
    E3,
    E5,
    ev_spec,
    out_t,
    out_y,
    ev_t,
    ev_y,
    info,
):
    """Dormand-Prince 8(5,3) with Hairer's error control, accepted steps recorded.

    ``state`` (shape (3,)) holds ``[t, h, unused]`` and persists between calls, so a
    run continues with the step size it had; each call evaluates f once at its start.
    ``A`` (12, 12), ``B`` (12,), ``C`` (12,), ``E3``/``E5`` (13,) are the coefficients of
    ``scipy.integrate._ivp.dop853_coefficients``. Stops after ``max_steps`` accepted
    steps, at ``t_end`` (status 5), or when the step size collapses (status 4).
    """
    m = y.shape[0]
    S = B.shape[0]
    K = np.empty((S + 1, m))
    ynew = np.empty(m)
    ys = np.empty(m)
    t = state[0]
    h = state[1]
    rhs(t, y, P, K[0])
    evals = 1
    ev_index = -1
    ev_value = 0.0
    ev_dir = 0.0
    if ev_spec is not None:  # None: numba compiles the loop without event code
        ev_index = int(ev_spec[0])
        ev_value = ev_spec[1]
        ev_dir = ev_spec[2]
    info[0] = 0
    info[1] = 0
    info[2] = 0
    info[3] = 0
    rejected = False
    steps = 0
    while steps < max_steps:
        if t >= t_end:
            info[2] = 5
            break
        if h > t_end - t:
            h = t_end - t
        if h < 1e-14 * max(abs(t), 1.0) * 4.0:
            info[2] = 4
            break
        for s in range(1, S):
            for k in range(m):
                acc = 0.0
                for j in range(s):
                    acc += A[s, j] * K[j, k]
                ys[k] = y[k] + h * acc
            rhs(t + C[s] * h, ys, P, K[s])
        for k in range(m):
            acc = 0.0
            for j in range(S):
                acc += B[j] * K[j, k]
            ynew[k] = y[k] + h * acc
        rhs(t + h, ynew, P, K[S])
        evals += S
        err = _dop853_norm(K, E5, E3, h, y, ynew, rtol, atol)
        if not err == err or not _finite(ynew):
            h *= 0.2
            rejected = True
            continue
        if err < 1.0:
            if err == 0.0:
                factor = 10.0
            else:
                factor = min(10.0, 0.9 * err ** (-1.0 / 8.0))
            if rejected:
                factor = min(1.0, factor)
            t_old = t
            t = t + h
            if ev_spec is not None:
                if ev_index >= 0 and _crossed(
                    y[ev_index] - ev_value, ynew[ev_index] - ev_value, ev_dir
                ):
                    _record_event(ev_t, ev_y, info, t_old, y, t, ynew)
            for k in range(m):
                y[k] = ynew[k]
                K[0, k] = K[S, k]
            h *= factor
            rejected = False
            steps += 1
            mo = info[1]
            if mo < out_t.shape[0]:
                out_t[mo] = t
                for k in range(m):
                    out_y[mo, k] = y[k]
                info[1] = mo + 1
        else:
            h *= max(0.2, 0.9 * err ** (-1.0 / 8.0))
            rejected = True
    state[0] = t
    state[1] = h
    info[0] = steps
    info[4] = evals
