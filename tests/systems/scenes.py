"""Small scenes written out in the tests, independent of the catalogue files."""

from systems.scene import Scene, parse_scene

OSCILLATOR = """
title = "Oscillator"
[system]
coordinates = ["x"]
parameters = { m = 2.0, k = 3.0 }
kinetic = "m*x_dot**2/2"
potential = "k*x**2/2"
[initial]
x = 1.0
"""

INVERTED_OSCILLATOR = """
title = "Inverted oscillator"
[system]
coordinates = ["q"]
hamiltonian = "(p_q**2 - q**2)/2"
[initial]
q = 0.0
p_q = 0.0
"""
"""H = (p^2 - q^2)/2 at its saddle: Lyapunov exponents +1 and -1 exactly."""

DAMPED_OSCILLATOR = """
title = "damped oscillator"
[system]
coordinates = ["x"]
parameters = { m = 1.0, k = 1.0, c = 0.2 }
kinetic = "m*x_dot**2/2"
potential = "k*x**2/2"
[effects]
forces = { x = "-c*x_dot" }
[initial]
x = 1.0
"""

PENDULUM = """
title = "Pendulum"
[system]
coordinates = ["theta"]
parameters = { m = 1.5, g = 9.81, l = 0.7 }
kinetic = "m*l**2*theta_dot**2/2"
potential = "-m*g*l*cos(theta)"
[initial]
theta = 1.0
[drawing]
points = { bob = ["l*sin(theta)", "-l*cos(theta)"] }
links = [["origin", "bob"]]
"""

PLANETARY = """
title = "Planetary motion"
[system]
coordinates = ["r", "theta"]
parameters = { m = 1.3, k = 0.8 }
kinetic = "m*(r_dot**2 + r**2*theta_dot**2)/2"
potential = "-k/r"
[initial]
r = 1.0
theta_dot = 1.1
"""

VARIABLE_LENGTH = """
title = "Pendulum of variable length"
[system]
coordinates = ["theta"]
parameters = { m = 1.0, g = 9.81, l0 = 1.0, a = 0.2, w = 1.5 }
kinetic = "m*((a*w*cos(w*t))**2 + (l0 + a*sin(w*t))**2*theta_dot**2)/2"
potential = "-m*g*(l0 + a*sin(w*t))*cos(theta)"
"""

DRIVEN_DAMPED = """
title = "Driven damped pendulum"
[system]
coordinates = ["theta"]
parameters = { m = 1.0, g = 1.0, l = 1.0, b = 0.5, A = 1.2, w = 0.6667 }
kinetic = "m*l**2*theta_dot**2/2"
potential = "-m*g*l*cos(theta)"
[effects]
dissipation = "b*theta_dot**2/2"
forces = { theta = "A*cos(w*t)" }
"""

HENON_HEILES = """
title = "Henon-Heiles"
[system]
coordinates = ["x", "y"]
hamiltonian = "(p_x**2 + p_y**2)/2 + (x**2 + y**2)/2 + x**2*y - y**3/3"
[initial]
x = 0.1
p_y = 0.5
"""


def scene(text: str) -> Scene:
    return parse_scene(text, source="test.toml")
