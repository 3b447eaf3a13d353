"""Scenes used only by the textbook tests (the shared ones are in tests/systems/scenes.py)."""

COUPLED = """
title = "Two masses between three equal springs"
[system]
coordinates = ["x1", "x2"]
parameters = { m = 1.7, k = 2.3 }
kinetic = "m*(x1_dot**2 + x2_dot**2)/2"
potential = "k*(x1**2 + (x2 - x1)**2 + x2**2)/2"
"""

HOOP = """
title = "Bead on a spinning hoop"
[system]
coordinates = ["theta"]
parameters = { m = 0.5, R = 0.8, g = 9.81, w = 6.0 }
kinetic = "m*(R**2*theta_dot**2 + w**2*R**2*sin(theta)**2)/2"
potential = "-m*g*R*cos(theta)"
[drawing]
points = { bead = ["R*sin(theta)*cos(w*t)", "-R*cos(theta)"] }
links = [["origin", "bead"]]
"""

TRANSCENDENTAL = """
title = "A well sympy cannot solve"
[system]
coordinates = ["x"]
parameters = { a = 0.2 }
kinetic = "x_dot**2/2"
potential = "cos(x) + a*x**2"
"""

CARTESIAN_HOOP = """
title = "Bead on a spinning hoop, in the hoop's x and y"
[system]
coordinates = ["x", "y"]
parameters = { m = 0.5, R = 0.8, g = 9.81, w = 6.0 }
kinetic = "m*(x_dot**2 + y_dot**2 + w**2*x**2)/2"
potential = "m*g*y"
[constraints]
holonomic = ["x**2 + y**2 - R**2"]
"""

RING_WELL = """
title = "Bead on a ring centred in a harmonic well"
[system]
coordinates = ["x", "y"]
parameters = { m = 1.0, k = 2.0 }
kinetic = "m*(x_dot**2 + y_dot**2)/2"
potential = "k*(x**2 + y**2)/2"
[constraints]
holonomic = ["x**2 + y**2 - 1"]
"""

RING_QUARTIC = """
title = "Bead on a ring with U = x**4/4"
[system]
coordinates = ["x", "y"]
parameters = { c = 1.0 }
kinetic = "(x_dot**2 + y_dot**2)/2"
potential = "c*x**4/4"
[constraints]
holonomic = ["x**2 + y**2 - 1"]
"""

SPRING_OVER_FLOOR = """
title = "A mass on a spring whose rest height is h, above a floor"
[system]
coordinates = ["y"]
parameters = { m = 1.0, k = 2.0, h = 1.0 }
kinetic = "m*y_dot**2/2"
potential = "k*(y - h)**2/2"
[constraints]
unilateral = ["y"]
"""

MOVING_RING = """
title = "Bead on a ring whose radius breathes"
[system]
coordinates = ["x", "y"]
parameters = { g = 9.81, a = 0.1, w = 2.0 }
kinetic = "(x_dot**2 + y_dot**2)/2"
potential = "g*y"
[constraints]
holonomic = ["x**2 + y**2 - (1 + a*sin(w*t))**2"]
"""

SKATE_ON_SLOPE = """
title = "A skate on an inclined plane"
[system]
coordinates = ["x", "y", "phi"]
parameters = { m = 1.0, g = 9.81, s = 0.3 }
kinetic = "m*(x_dot**2 + y_dot**2)/2 + m*phi_dot**2/20"
potential = "m*g*s*y"
[constraints]
nonholonomic = ["y_dot*cos(phi) - x_dot*sin(phi)"]
"""
