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
