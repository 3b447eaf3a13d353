"""A hypothesis strategy for whole scenes: every table of the scene format, valid or nearly.

``scenes()`` draws the text of a scene file: one of a few charts (a line, the plane, space,
polar coordinates, the sphere's polar angles), its dynamics given in each of the four ways
(T and V, ``[particles]`` with or without gravity, a Lagrangian with a total time
derivative, a Hamiltonian), and around it constraints (holonomic ones with singular points:
``sqrt(x**2 + y**2) - l`` at the origin, a cusp ``y**2 - x**3`` and a cross ``x*y`` whose
gradients vanish on them, a moving support; nonholonomic and unilateral ones), effects
(Rayleigh dissipation, a workless gyroscopic force ``{ x = "G*y_dot", y = "-G*x_dot" }``,
a drive, a circulatory force, effects switched off), symmetries, initial states at chart
singularities, view ranges (the search box) and angles, a drawing, and parameters that
make a mass zero, negative or tiny. Most scenes derive; some must be refused (a zero mass,
constraints as many as the coordinates): what a test may not see is a traceback or a hang.
"""

from __future__ import annotations

from hypothesis import strategies as st

CHARTS = {
    "line": ("x",),
    "plane": ("x", "y"),
    "space": ("x", "y", "z"),
    "polar": ("r", "theta"),
    "sphere": ("theta", "phi"),
}
KINETIC = {
    "line": [
        "m*x_dot**2/2",
        "m*(1 + x**2)*x_dot**2/2",
        "m*x_dot**2/2 + a*x*x_dot",
        "m*x_dot**2/(2*x)",
        "m*x**2*x_dot**2/2",
    ],
    "plane": [
        "m*(x_dot**2 + y_dot**2)/2",
        "m*(x_dot**2 + (1 + x**2)*y_dot**2)/2",
        "m*(x_dot**2 + y_dot**2)/2 + m*w*(x*y_dot - y*x_dot)",
        "m*(x_dot**2 + x**2*y_dot**2)/2",  # M singular along x = 0
    ],
    "space": ["m*(x_dot**2 + y_dot**2 + z_dot**2)/2", "m*(x_dot**2 + y_dot**2)/2 + M*z_dot**2/2"],
    "polar": ["m*(r_dot**2 + r**2*theta_dot**2)/2"],
    "sphere": ["m*l**2*(theta_dot**2 + sin(theta)**2*phi_dot**2)/2"],
}
POTENTIAL = {
    "line": ["k*x**2/2", "k*(x**2 - 1)**2/4", "-k*cos(x)", "0", "k*x**4", "m*g*x",
             "k*x**2/2 + a*x*cos(w*t)", "k*Abs(x)", "k*sqrt(x**2 + l**2)", "k*sqrt(x)",
             "k/x", "k*log(x**2)", "k*tan(x)", "k*x*log(Abs(x))"],
    "plane": ["k*(x**2 + y**2)/2", "m*g*y", "-k/sqrt(x**2 + y**2)", "k*x*y", "0",
              "k*(x**2 + y**2 - 1)**2", "k*x**2/2", "-k*cos(x) - k*cos(y)",
              "k*(x**2 + y**2)/2 + a*x*cos(w*t)", "k*atan2(y, x)", "k*sqrt(x*y)",
              "k*log(x**2 + y**2)", "k*(x**2 + y**2)**(1/3)"],
    "space": ["m*g*z", "k*(x**2 + y**2 + z**2)/2", "-k/sqrt(x**2 + y**2 + z**2)", "0",
              "k*z**2/2 + m*g*y"],
    "polar": ["-k/r", "k*(r - l)**2/2", "k*r**2*cos(theta)**2", "0", "m*g*r*sin(theta)"],
    "sphere": ["-m*g*l*cos(theta)", "k*theta**2/2", "k*cos(phi)**2", "0",
               "-m*g*l*cos(theta)*(1 + a*cos(w*t))"],
}  # fmt: skip
PARTICLES = {
    "line": [['"x"', '"0"'], ['"x"', '"a*cos(w*t)"'], ['"l*sin(x)"', '"-l*cos(x)"']],
    "plane": [['"x"', '"y"'], ['"x + a*cos(w*t)"', '"y"'], ['"x"', '"y"', '"0"'],
              ['"x*y"', '"y"']],
    "space": [['"x"', '"y"', '"z"'], ['"x*cos(w*t) - y*sin(w*t)"', '"x*sin(w*t) + y*cos(w*t)"',
              '"z"']],
    "polar": [['"r*cos(theta)"', '"r*sin(theta)"'], ['"r*cos(theta)"', '"r*sin(theta)"', '"0"']],
    "sphere": [['"l*sin(theta)*cos(phi)"', '"l*sin(theta)*sin(phi)"', '"-l*cos(theta)"'],
               ['"l*sin(theta)*cos(phi)"', '"-l*cos(theta)"', '"l*sin(theta)*sin(phi)"']],
}  # fmt: skip
HOLONOMIC = {
    "line": ["x - l", "x**2"],  # as many as the coordinates: refused
    "plane": ["x**2 + y**2 - l**2", "sqrt(x**2 + y**2) - l", "y**2 - x**3", "x*y", "x - y",
              "y - a*sin(w*t)", "x**2 + y**2", "x*y - a", "y - x**2", "atan2(y, x) - a",
              "Abs(x) + Abs(y) - l", "sqrt(x) - y", "log(x) - y", "(x**2 + y**2 - l**2)**2"],
    "space": ["x**2 + y**2 + z**2 - l**2", "sqrt(x**2 + z**2) - l", "z - x*y", "z**2 - x**3",
              "x*y", "z - a*cos(w*t)", "z - x**2 - y**2"],
    "polar": ["r - l", "r*cos(theta) - l", "r*sin(theta)", "r - l - a*sin(w*t)"],
    "sphere": ["phi - w*t", "theta - a", "sin(theta)*cos(phi)"],
}  # fmt: skip
NONHOLONOMIC = {
    "line": ["x_dot - a"],
    "plane": ["x_dot - a*y_dot", "x_dot - y*y_dot", "x_dot + a", "cos(y)*x_dot - y_dot"],
    "space": ["x_dot - y*z_dot", "z_dot - x*y_dot + y*x_dot", "cos(z)*x_dot + sin(z)*y_dot"],
    "polar": ["r_dot - r*theta_dot", "r_dot - a"],
    "sphere": ["theta_dot - sin(theta)*phi_dot"],
}
UNILATERAL = {
    "line": ["x", "l - x", "l**2 - x**2", "x - a*cos(w*t)"],
    "plane": [
        "y",
        "l**2 - x**2 - y**2",
        "x*y",
        "y - a*cos(w*t)",
        "y + l",
        "y - Abs(x)",
        "sqrt(x**2 + y**2) - l",
    ],
    "space": ["z", "l**2 - x**2 - y**2 - z**2", "z - x**2"],
    "polar": ["l - r", "r*sin(theta)"],
    "sphere": ["theta", "pi/2 - theta"],
}
DISSIPATION = {
    "line": ["b*x_dot**2/2", "b*x_dot**4/4", "b*(1 + x**2)*x_dot**2/2"],
    "plane": ["b*(x_dot**2 + y_dot**2)/2", "b*y_dot**2/2"],
    "space": ["b*(x_dot**2 + y_dot**2 + z_dot**2)/2", "b*z_dot**2/2"],
    "polar": ["b*r_dot**2/2", "b*(r_dot**2 + r**2*theta_dot**2)/2"],
    "sphere": ["b*theta_dot**2/2", "b*(theta_dot**2 + phi_dot**2)/2"],
}
FORCES = {
    "line": ['{ x = "a*cos(w*t)" }', '{ x = "-b*x_dot*Abs(x_dot)" }', '{ x = "G" }'],
    "plane": ['{ x = "G*y_dot", y = "-G*x_dot" }', '{ x = "a*cos(w*t)" }', '{ x = "-k*y" }',
              '{ y = "G*x" }', '{ x = "G*y_dot*x", y = "-G*x_dot*x" }'],
    "space": ['{ x = "G*y_dot", y = "-G*x_dot" }', '{ z = "a*cos(w*t)" }',
              '{ x = "G*z_dot", z = "-G*x_dot" }'],
    "polar": ['{ theta = "a*cos(w*t)" }', '{ r = "G*r*theta_dot", theta = "-G*r*r_dot" }'],
    "sphere": ['{ phi = "a" }', '{ theta = "G*phi_dot", phi = "-G*theta_dot" }'],
}  # fmt: skip
SYMMETRIES = {
    "line": ['s = { x = "1" }'],
    "plane": ['rot = { x = "-y", y = "x" }', 'slide = { x = "1" }', 'both = { x = "1", y = "1" }'],
    "space": ['rot = { x = "-y", y = "x" }', 'up = { z = "1" }', 'screw = { z = "1", x = "a" }'],
    "polar": ['turn = { theta = "1" }', 'out = { r = "r" }'],
    "sphere": ['spin = { phi = "1" }', 'tilt = { theta = "1" }'],
}
MASSES = ["1.0", "2.5", "0.0", "-1.0", "1e-9", "1e12"]
VALUES = ["0.0", "1.0", "-1.0", "0.5", "3.141592653589793", "1e-8"]


@st.composite
def scenes(draw) -> str:
    """The text of a scene file (see the module's docstring)."""
    chart = draw(st.sampled_from(sorted(CHARTS)))
    coordinates = CHARTS[chart]
    mass = draw(st.sampled_from(MASSES))
    parameters = {
        "m": mass, "M": draw(st.sampled_from(MASSES)),
        "k": draw(st.sampled_from(["2.0", "0.0", "-1.0"])), "g": "9.81",
        "l": draw(st.sampled_from(["1.0", "0.0"])), "w": "0.7", "a": "0.4", "b": "0.2",
        "G": "0.5",
    }  # fmt: skip
    way = draw(st.sampled_from(["energies", "particles", "lagrangian", "hamiltonian"]))
    potential = draw(st.sampled_from(POTENTIAL[chart]))
    system = [f"coordinates = {list(coordinates)!r}".replace("'", '"')]
    particles: list[str] = []
    if way == "energies":
        system += [
            f'kinetic = "{draw(st.sampled_from(KINETIC[chart]))}"',
            f'potential = "{potential}"',
        ]
    elif way == "particles":
        for i in range(draw(st.integers(1, 2))):
            position = draw(st.sampled_from(PARTICLES[chart]))
            particle_mass = draw(st.sampled_from(["m", "M", "1", "0", "-m"]))
            particles.append(
                f'p{i} = {{ mass = "{particle_mass}", position = [{", ".join(position)}] }}'
            )
        gravity = draw(st.sampled_from(["", '"g"', '["0", "-g"]', '["0", "0", "-g"]']))
        if gravity:
            system.append(f"gravity = {gravity}")
        if draw(st.booleans()):
            system.append(f'potential = "{potential}"')
    elif way == "lagrangian":
        kinetic = draw(st.sampled_from(KINETIC[chart]))
        q = coordinates[0]  # a total time derivative d(a t q)/dt, or one that is not
        gauge = draw(st.sampled_from(["", f" + a*({q} + t*{q}_dot)", f" + a*t*{q}*{q}_dot"]))
        system.append(f'lagrangian = "{kinetic} - ({potential}){gauge}"')
    else:
        kinetic = " + ".join(f"p_{q}**2/(2*m)" for q in coordinates)
        if chart == "polar":
            kinetic = "p_r**2/(2*m) + p_theta**2/(2*m*r**2)"
        elif chart == "sphere":
            kinetic = "p_theta**2/(2*m*l**2) + p_phi**2/(2*m*l**2*sin(theta)**2)"
        system.append(f'hamiltonian = "{kinetic} + {potential}"')
    sections = []
    constraints = []
    for kind, table in (("holonomic", HOLONOMIC), ("nonholonomic", NONHOLONOMIC),
                        ("unilateral", UNILATERAL)):  # fmt: skip
        most = max(len(coordinates) - 1, 1)  # more holonomic ones are refused
        chosen = draw(st.lists(st.sampled_from(table[chart]), max_size=most, unique=True))
        if chosen and draw(st.integers(0, 2)) == 0:  # each kind in a third of the scenes
            constraints.append(f"{kind} = {chosen!r}".replace("'", '"'))
    if any(c.startswith("unilateral") for c in constraints) and draw(st.booleans()):
        parameters["restitution"] = draw(st.sampled_from(["0.0", "0.8", "1.0"]))
    if constraints:
        sections.append("[constraints]\n" + "\n".join(constraints))
    effects = []
    if draw(st.booleans()):
        effects.append(f'dissipation = "{draw(st.sampled_from(DISSIPATION[chart]))}"')
    if draw(st.booleans()):
        effects.append(f"forces = {draw(st.sampled_from(FORCES[chart]))}")
    if effects and draw(st.integers(0, 3)) == 0:
        on = [f"forces.{q}" for q in coordinates if f"{q} = " in effects[-1]]
        on += ["dissipation"] if "dissipation" in effects[0] else []
        if on:
            off = draw(st.lists(st.sampled_from(on), min_size=1, unique=True))
            effects.append(f"disabled = {off!r}".replace("'", '"'))
    if effects:
        sections.append("[effects]\n" + "\n".join(e for e in effects if e))
    if draw(st.integers(0, 2)) == 0:
        sections.append("[symmetries]\n" + draw(st.sampled_from(SYMMETRIES[chart])))
    if particles:
        sections.append("[particles]\n" + "\n".join(particles))
    initial = [
        f"{name} = {draw(st.sampled_from(VALUES))}"
        for q in coordinates
        for name in (q, f"{q}_dot" if way != "hamiltonian" else f"p_{q}")
        if draw(st.booleans())
    ]
    if initial:
        sections.append("[initial]\n" + "\n".join(initial))
    view = []
    if draw(st.booleans()):  # the search box follows the ranges
        q = draw(st.sampled_from(coordinates))
        low, high = draw(st.sampled_from([(-1.0, 1.0), (0.0, 1e-6), (-1e6, 1e6), (2.0, 3.0)]))
        view.append(f"ranges = {{ {q} = [{low}, {high}] }}")
    if draw(st.booleans()):  # the periodic coordinates, as the scene says
        angles = draw(st.lists(st.sampled_from(coordinates), unique=True))
        view.append(f"angles = {angles!r}".replace("'", '"'))
    if view:
        sections.append("[view]\n" + "\n".join(view))
    if draw(st.booleans()):
        point = ", ".join(f'"{q}"' for q in (coordinates * 2)[:2])
        sections.append(f'[drawing]\npoints = {{ bob = [{point}] }}\nlinks = [["origin", "bob"]]')
    values = ", ".join(f"{k} = {v}" for k, v in parameters.items())
    return (
        f'title = "generated {chart} {way}"\n[system]\n'
        + "\n".join(system)
        + f"\nparameters = {{ {values} }}\n\n"
        + "\n\n".join(sections)
        + "\n"
    )
