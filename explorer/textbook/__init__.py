"""The Textbook dock: the theorems of analytical mechanics on the system being explored.

``install(window)`` adds it to a ``MainWindow``. All coupling to the window is in
``WindowLink`` (explorer/textbook/link.py); the tabs only see compiled systems.

Tabs (each a ``TextbookTabView`` that computes when shown after a change):

- ``EquilibriaView``: ``search_equilibria`` in a table (kind, U, ω and mode shapes, sympy's
  closed forms); ``EquilibriumMarkers`` puts dots (stable) and crosses (unstable) into
  the phase view, with the frequencies as tooltips. Computed even while hidden.
- ``PrincipleView``: S(ε) along sine variations of a stretch of the run, the tangent at
  ε = 0, minimum or only stationary from the second variation; the two-point problem by
  the stationary discrete action and by shooting.
- ``ReductionView``: V_eff with the conserved momenta on sliders, turning points, and the
  reduced phase portrait (exact level sets of the reduced H).
- ``ActionAngleView``: J(E) and T(E) up past the separatrix; the exact elliptic period
  for U = u0 − c cos q.
- ``EnergyTheoremView``: dH/dt against −∂L/∂t + Σ q̇ Q, and H against T + V.

Computations run in ``TaskRunner`` (each in a worker process, newest job per tab wins, an
older one's process ended; all ended when the window closes); the computations
themselves are Qt-free, in ``systems.textbook.jobs``.
"""

from __future__ import annotations

from explorer.textbook.link import WindowLink, install
from explorer.textbook.panel import TextbookPanel

__all__ = ["TextbookPanel", "WindowLink", "install"]
