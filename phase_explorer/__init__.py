"""Phase Explorer's Python API, for notebooks and scripts (``docs/api.md``)::

    import phase_explorer as pe

    pendulum = pe.load("simple_pendulum")
    pendulum.derive()                  # the equations, as sympy objects
    orbit = pendulum.run(t_end=20)     # t (k,), y (k, 2n), named columns
    orbit.plot()                       # a figure Jupyter shows as a PNG

A small layer over ``systems``: the same derivation, integrators and chaos indicators as
the window and ``python main.py``, and the same checks of what is asked (``UsageError``,
a ``ValueError``, with the command line's messages). Never imports Qt.
"""

from __future__ import annotations

from phase_explorer.figures import Figure
from phase_explorer.results import (
    ChaosMap,
    Derivation,
    Lyapunov,
    OrbitDiagram,
    Section,
    Trajectory,
)
from phase_explorer.system import System, catalogue, load
from systems.mechanics import DerivationError
from systems.scene import SceneError
from systems.usage import UsageError

__all__ = [
    "ChaosMap", "Derivation", "DerivationError", "Figure", "Lyapunov", "OrbitDiagram",
    "SceneError", "Section", "System", "Trajectory", "UsageError", "catalogue", "load",
]  # fmt: skip
