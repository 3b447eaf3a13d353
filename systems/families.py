"""Scene text for families of systems of any size: pendulum chains, FPU lattices, rings.

Written out the way a user would type them (T and V, or H, in generalized coordinates),
so the same text serves the catalogue, the benchmarks and the tests.
"""

from __future__ import annotations

import math


def _names(prefix: str, n: int) -> list[str]:
    return [f"{prefix}{i}" for i in range(1, n + 1)]


def _toml_list(names: list[str]) -> str:
    return "[" + ", ".join(f'"{x}"' for x in names) + "]"


def pendulum_chain(n: int, *, start: float = 0.4, drawing: bool = True) -> str:
    """An ``n``-link planar pendulum chain: unit masses on massless rods of length l.

    Coordinates ``q1..qn`` are the angles of the rods from the downward vertical. The
    velocity of mass k is the sum of the rods' velocities above it, so T couples every
    pair of coordinates through cos(q_i - q_j): M(q) is full.

    Parameters
    ----------
    n : int
        Number of links (>= 1).
    start : float
        Initial angle of the first rod; rod k starts at ``start * (1 + k/n)``.
    drawing : bool
        Add a ``[drawing]`` with the joints and links.
    """
    q = _names("q", n)
    kinetic = []
    for k in range(1, n + 1):
        vx = " + ".join(f"{x}_dot*cos({x})" for x in q[:k])
        vy = " + ".join(f"{x}_dot*sin({x})" for x in q[:k])
        kinetic.append(f"(({vx})**2 + ({vy})**2)")
    potential = " + ".join(f"{n - i}*cos({x})" for i, x in enumerate(q))
    lines = [
        f'title = "Pendulum chain of {n} links"',
        f'description = "{n} unit masses on massless rods of length l, hanging from a pivot."',
        "[system]",
        f"coordinates = {_toml_list(q)}",
        "parameters = { m = 1.0, l = 1.0, g = 9.81 }",
        f'kinetic = "m*l**2*({" + ".join(kinetic)})/2"',
        f'potential = "-m*g*l*({potential})"',
        "[initial]",
        *(f"{x} = {start * (1 + i / n):.6g}" for i, x in enumerate(q)),
        "[view]",
        "t_end = 20",
        'phase = ["q1", "p_q1"]',
    ]
    if drawing:
        points, x, y = [], "0", "0"
        for i, qi in enumerate(q):
            x = f"{x} + l*sin({qi})" if i else f"l*sin({qi})"
            y = f"{y} - l*cos({qi})" if i else f"-l*cos({qi})"
            points.append(f'j{i + 1} = ["{x}", "{y}"]')
        chain = ", ".join(f'["{a}", "{b}"]' for a, b in _pairs(["origin", *_names("j", n)]))
        lines += [
            "[drawing]",
            f"points = {{ {', '.join(points)} }}",
            f"links = [{chain}]",
            f'trace = ["j{n}"]',
        ]
    return "\n".join(lines) + "\n"


def _pairs(names: list[str]) -> list[tuple[str, str]]:
    return list(zip(names, names[1:], strict=False))


def fpu_chain(
    n: int,
    *,
    form: str = "tv",
    mode: int = 1,
    amplitude: float = 1.0,
    drawing: bool = True,
) -> str:
    """The Fermi-Pasta-Ulam-Tsingou alpha chain of ``n`` unit masses with fixed ends.

    V = sum over the n + 1 bonds of d**2/2 + alpha*d**3/3 with d = q_{i+1} - q_i.

    Parameters
    ----------
    n : int
        Number of moving particles.
    form : {"tv", "h"}
        Written as T and V, or as a Hamiltonian.
    mode : int
        The linear normal mode that carries all the energy at the start, as in FPU's
        experiment: q_i = amplitude * sin(pi * mode * i / (n + 1)).
    drawing : bool
        Add a ``[drawing]``: particle i at x = i + q_i (less (n + 1)/2, to centre the
        chain) on a line between the two fixed walls, joined by the springs.
    """
    q = _names("q", n)

    def bond(i: int) -> str:
        right = q[i] if i < n else "0"
        left = q[i - 1] if i >= 1 else "0"
        if right == "0":
            return f"(-{left})"
        return f"({right} - {left})" if left != "0" else f"({right})"

    springs = " + ".join(f"{bond(i)}**2/2 + alpha*{bond(i)}**3/3" for i in range(n + 1))
    if form == "tv":
        body = [f'kinetic = "({" + ".join(f"{x}_dot**2" for x in q)})/2"']
        body.append(f'potential = "{springs}"')
    elif form == "h":
        body = [f'hamiltonian = "({" + ".join(f"p_{x}**2" for x in q)})/2 + {springs}"']
    else:
        raise ValueError(f"form must be 'tv' or 'h', not {form!r}")
    start = [
        f"{x} = {amplitude * math.sin(math.pi * mode * (i + 1) / (n + 1)):.12g}"
        for i, x in enumerate(q)
    ]
    return (
        "\n".join(
            [
                f'title = "FPU-alpha chain of {n} particles"',
                f'description = "{n} unit masses joined by anharmonic springs, ends fixed; '
                f'all the energy starts in linear mode {mode}."',
                "[system]",
                f"coordinates = {_toml_list(q)}",
                "parameters = { alpha = 0.25 }",
                *body,
                "[initial]",
                *start,
                "[view]",
                "t_end = 2000",
                'phase = ["q1", "p_q1"]',
                *(_fpu_drawing(q) if drawing else []),
            ]
        )
        + "\n"
    )


def _fpu_drawing(q: list[str]) -> list[str]:
    """The ``[view]`` area of the drawing and the ``[drawing]``: particle i at x = i + q_i,
    shifted to centre the chain on the origin, on a line between two fixed walls, with
    the springs between neighbours."""
    centre = (len(q) + 1) / 2
    points = [f'p{i} = ["{i - centre:g} + {x}", "0"]' for i, x in enumerate(q, start=1)]
    points = [f'left = ["{-centre:g}", "0"]', *points, f'right = ["{centre:g}", "0"]']
    names = ["left", *(f"p{i}" for i in range(1, len(q) + 1)), "right"]
    links = ", ".join(f'["{a}", "{b}"]' for a, b in _pairs(names))
    # the area of the drawing ([view] x and y): the chain across the whole width
    area = f"ranges = {{ x = [{-centre - 1:g}, {centre + 1:g}], y = [-1, 1] }}"
    return [area, "[drawing]", f"points = {{ {', '.join(points)} }}", f"links = [{links}]"]


def pendulum_ring(n: int, *, start: float = 0.8) -> str:
    """A ring of ``n`` identical pendulums, each coupled to its two neighbours by a
    torsion spring: V = sum m g l (1 - cos q_i) + k/2 sum (q_{i+1} - q_i)**2, periodic.

    A discrete sine-Gordon (Frenkel-Kontorova) lattice; one pendulum starts displaced.
    """
    q = _names("q", n)
    gravity = " + ".join(f"(1 - cos({x}))" for x in q)
    springs = " + ".join(f"({q[(i + 1) % n]} - {x})**2" for i, x in enumerate(q))
    return (
        "\n".join(
            [
                f'title = "Ring of {n} coupled pendulums"',
                f'description = "{n} pendulums on a circle, each joined to its neighbours by a '
                "torsion spring; one starts displaced and its swing spreads around the ring. "
                'Drawn in a row: the last is coupled to the first."',
                "[system]",
                f"coordinates = {_toml_list(q)}",
                "parameters = { m = 1.0, l = 1.0, g = 9.81, k = 2.0 }",
                f'kinetic = "m*l**2*({" + ".join(f"{x}_dot**2" for x in q)})/2"',
                f'potential = "m*g*l*({gravity}) + k*({springs})/2"',
                "[initial]",
                f"{q[0]} = {start}",
                "[view]",
                f"angles = {_toml_list(q)}",
                "t_end = 200",
                'phase = ["q1", "p_q1"]',
                "[drawing]",
                "points = { "
                + ", ".join(
                    f'a{i + 1} = ["{2.5 * i:g}*l", "0"], '
                    f'b{i + 1} = ["{2.5 * i:g}*l + l*sin({x})", "-l*cos({x})"]'
                    for i, x in enumerate(q)
                )
                + " }",
                "links = ["
                + ", ".join(
                    [f'["a{i + 1}", "a{i + 2}"]' for i in range(n - 1)]
                    + [f'["a{i + 1}", "b{i + 1}"]' for i in range(n)]
                )
                + "]",
            ]
        )
        + "\n"
    )
