"""An independent reference integrator for the textbook tests: Hamilton's equations of the
full system, lambdified and integrated with solve_ivp at tight tolerances."""

import numpy as np
import scipy.integrate
import sympy


def full_run(mech, y0, t):
    values = {mech.params[name]: v for name, v in mech.scene.parameter_values.items()}
    exprs = [e.xreplace(values) for e in mech.hamilton_equations]
    f = sympy.lambdify([mech.t, *mech.q, *mech.p], exprs)
    result = scipy.integrate.solve_ivp(
        lambda time, y: np.array(f(time, *y), dtype=float),
        (t[0], t[-1]),
        np.asarray(y0, dtype=float),
        t_eval=t,
        method="DOP853",
        rtol=1e-12,
        atol=1e-13,
    )
    assert result.status == 0
    return result.y.T
