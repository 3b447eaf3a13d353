"""The Energy tab's words for the kind of system (``explorer.textbook.energy_view``)."""

from __future__ import annotations

import numpy as np

from explorer.textbook.energy_view import explanation
from systems.textbook import jobs
from systems.textbook.conservation import EnergyBalance


def _result(*, explicit_time: bool, effects: bool, rheonomic: bool) -> jobs.EnergyResult:
    t = np.linspace(0.0, 1.0, 11)
    rate = np.cos(t)
    balance = EnergyBalance(t, np.sin(t), rate, rate, np.zeros_like(t), None)
    run = jobs.Run(t, np.zeros((len(t), 2)), np.zeros((len(t), 1)), True, "")
    return jobs.EnergyResult(balance, run, rheonomic, explicit_time, effects, True)


def test_rheonomic_energy_theorem_in_words():
    words = explanation(_result(explicit_time=True, effects=False, rheonomic=True))
    assert "only</i> through the explicit time dependence" in words


def test_moving_constraint_without_explicit_time_conserves_h():
    words = explanation(_result(explicit_time=False, effects=False, rheonomic=True))
    assert "H is conserved" in words and "rheonomic" in words
