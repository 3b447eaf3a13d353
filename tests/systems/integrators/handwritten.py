"""Hand-written kernel sources with exact solutions, independent of the derivation chain.

P holds the parameters; each source defines the system functions of the generated module
(``rhs``, ``hamiltonian`` and, for separable H, ``kinetic``/``potential`` and gradients,
which read the whole state y = (q, p)).
"""

import numpy as np

from systems.codegen import build_module, system_function

# H = p^2/(2m) + k q^2/2, P = (m, k)
OSCILLATOR = """
def rhs(t, y, P, out):
    out[0] = y[1] / P[0]
    out[1] = -P[1] * y[0]

def hamiltonian(t, y, P):
    return y[1] * y[1] / (2.0 * P[0]) + P[1] * y[0] * y[0] / 2.0

def kinetic(y, P):
    return y[1] * y[1] / (2.0 * P[0])

def potential(t, y, P):
    return P[1] * y[0] * y[0] / 2.0

def grad_kinetic(y, P, out):
    out[0] = y[1] / P[0]

def grad_potential(t, y, P, out):
    out[0] = P[1] * y[0]
"""

# H = p^2/(2 m l^2) - m g l cos(theta), P = (m, g, l)
PENDULUM = """
def rhs(t, y, P, out):
    out[0] = y[1] / (P[0] * P[2] * P[2])
    out[1] = -P[0] * P[1] * P[2] * math.sin(y[0])

def hamiltonian(t, y, P):
    return y[1] * y[1] / (2.0 * P[0] * P[2] * P[2]) - P[0] * P[1] * P[2] * math.cos(y[0])

def kinetic(y, P):
    return y[1] * y[1] / (2.0 * P[0] * P[2] * P[2])

def potential(t, y, P):
    return -P[0] * P[1] * P[2] * math.cos(y[0])

def grad_kinetic(y, P, out):
    out[0] = y[1] / (P[0] * P[2] * P[2])

def grad_potential(t, y, P, out):
    out[0] = P[0] * P[1] * P[2] * math.sin(y[0])
"""

# Kepler in the plane, Cartesian: H = |p|^2/(2m) - k/|q|, P = (m, k)
KEPLER_CARTESIAN = """
def rhs(t, y, P, out):
    r = math.sqrt(y[0] * y[0] + y[1] * y[1])
    f = P[1] / (r * r * r)
    out[0] = y[2] / P[0]
    out[1] = y[3] / P[0]
    out[2] = -f * y[0]
    out[3] = -f * y[1]

def hamiltonian(t, y, P):
    r = math.sqrt(y[0] * y[0] + y[1] * y[1])
    return (y[2] * y[2] + y[3] * y[3]) / (2.0 * P[0]) - P[1] / r

def kinetic(y, P):
    return (y[2] * y[2] + y[3] * y[3]) / (2.0 * P[0])

def potential(t, y, P):
    return -P[1] / math.sqrt(y[0] * y[0] + y[1] * y[1])

def grad_kinetic(y, P, out):
    out[0] = y[2] / P[0]
    out[1] = y[3] / P[0]

def grad_potential(t, y, P, out):
    r = math.sqrt(y[0] * y[0] + y[1] * y[1])
    f = P[1] / (r * r * r)
    out[0] = f * y[0]
    out[1] = f * y[1]
"""

# Kepler in polar coordinates (r, theta), non-separable:
# H = p_r^2/(2m) + p_theta^2/(2 m r^2) - k/r, P = (m, k)
KEPLER_POLAR = """
def rhs(t, y, P, out):
    r = y[0]
    out[0] = y[2] / P[0]
    out[1] = y[3] / (P[0] * r * r)
    out[2] = y[3] * y[3] / (P[0] * r * r * r) - P[1] / (r * r)
    out[3] = 0.0

def hamiltonian(t, y, P):
    r = y[0]
    return y[2] * y[2] / (2.0 * P[0]) + y[3] * y[3] / (2.0 * P[0] * r * r) - P[1] / r
"""

# Double pendulum (unit masses and lengths, g = P[0]), non-separable
DOUBLE_PENDULUM = """
def rhs(t, y, P, out):
    g = P[0]
    a, b, pa, pb = y[0], y[1], y[2], y[3]
    c = math.cos(a - b)
    s = math.sin(a - b)
    d = 1.0 + s * s
    out[0] = (pa - c * pb) / d
    out[1] = (2.0 * pb - c * pa) / d
    h1 = pa * pb * s / d
    h2 = (pa * pa + 2.0 * pb * pb - 2.0 * pa * pb * c) / (2.0 * d * d)
    out[2] = -2.0 * g * math.sin(a) - h1 + h2 * 2.0 * s * c
    out[3] = -g * math.sin(b) + h1 - h2 * 2.0 * s * c

def hamiltonian(t, y, P):
    g = P[0]
    a, b, pa, pb = y[0], y[1], y[2], y[3]
    c = math.cos(a - b)
    s = math.sin(a - b)
    d = 1.0 + s * s
    T = (pa * pa + 2.0 * pb * pb - 2.0 * pa * pb * c) / (2.0 * d)
    return T - 2.0 * g * math.cos(a) - g * math.cos(b)
"""


def module(source: str):
    """The generated kernel module of ``source`` (its functions compiled for the drivers'
    signatures)."""
    return build_module(source)


class Handwritten:
    """A kernel module and parameter values, in the shape runners expect of a compiled
    system (``kernels``, ``parameters``, ``rhs``, ``functions``)."""

    def __init__(self, kernels, P):
        self.kernels = kernels
        self.parameters = np.asarray(P, dtype=float)

    def functions(self, names):
        return tuple(system_function(getattr(self.kernels, name)) for name in names)

    def rhs(self, t, y):
        out = np.empty(len(y))
        self.kernels.rhs(float(t), np.ascontiguousarray(y, dtype=float), self.parameters, out)
        return out


def run_to(mod, name, P, y0, t_end, value, compensated=True):
    """(final state, total steps, final status) of method ``name`` from 0 to ``t_end``."""
    from systems.integrators.registry import STEPPERS, make_runner

    system = Handwritten(mod, P)
    runner = make_runner(system, STEPPERS[name], np.array(y0, float), 0.0, t_end, value, None,
                         compensated)  # fmt: skip
    steps = 0
    while True:
        outcome = runner.advance(10**7, 2)
        steps += outcome.steps
        if outcome.code != 0:
            return runner.y.copy(), steps, outcome.code, runner.t
