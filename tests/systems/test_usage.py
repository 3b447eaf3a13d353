"""systems.usage: each check refuses with one sentence naming the option as its caller
spells it, and returns what the run needs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from systems import usage
from systems.usage import UsageError


def test_the_option_is_named_as_the_caller_spells_it():
    assert usage.cli_name("t_end") == "--t-end"
    for spell, name in ((usage.cli_name, "--samples"), (str, "samples")):
        with pytest.raises(UsageError, match=f"^{name} must be between 1 and 10000000, not 0$"):
            usage.sample_times(10.0, samples=0, spell=spell)
    with pytest.raises(UsageError, match="^t_end must be a positive finite time, not inf$"):
        usage.check_t_end(math.inf, "t_end")
    with pytest.raises(UsageError, match="a shorter time cannot be divided into steps"):
        usage.check_t_end(1e-320)
    assert issubclass(UsageError, ValueError)


def test_sample_times():
    np.testing.assert_array_equal(usage.sample_times(1.0, samples=4), [0, 0.25, 0.5, 0.75, 1])
    np.testing.assert_array_equal(usage.sample_times(1.0, every=0.4), [0, 0.4, 0.8, 1.0])
    endless = usage.sample_times(math.inf, every=0.5)
    assert [next(endless) for _ in range(3)] == [0.5, 1.0, 1.5]
    with pytest.raises(UsageError, match="^--every 1e-09 asks for 1e\\+09 rows; at most 1e7$"):
        usage.sample_times(1.0, every=1e-9)
    with pytest.raises(UsageError, match="whole number of rows"):
        usage.sample_times(1.0, samples=2.5, spell=str)


def test_integration_settings():
    got = usage.integration_settings(
        "dop853", 10.0, tol=1e-9, max_steps=100, energy_tolerance="off", spell=str
    )
    assert got == dict(dt=None, tol=1e-9, max_steps=100, energy_tolerance=None)
    got = usage.integration_settings("rk4", 10.0, dt=0.1, max_steps=5, energy_tolerance=0.1)
    assert got["energy_tolerance"] == 0.1 and got["dt"] == 0.1
    with pytest.raises(UsageError, match=r"^rk4 takes .* \(dt\), not a tolerance \(tol\)$"):
        usage.integration_settings("rk4", 10.0, tol=1e-9, max_steps=5, energy_tolerance=None,
                                   spell=str)  # fmt: skip
    with pytest.raises(UsageError, match="^--max-steps must be a positive whole number, not 0$"):
        usage.integration_settings("rk4", 10.0, max_steps=0, energy_tolerance=None)
    with pytest.raises(UsageError, match="^energy_tolerance: "):
        usage.integration_settings("rk4", 10.0, max_steps=5, energy_tolerance="x", spell=str)


def test_map_options():
    assert usage.check_map_options(3, 4, "megno", None) is None  # the method's default
    assert usage.check_map_options(3, 4, "megno", 20) == 20.0
    with pytest.raises(UsageError, match="^--grid needs at least 2 starts a side .* not 1x9$"):
        usage.check_map_options(1, 9, "megno", None)
    with pytest.raises(UsageError, match="^indicator is megno or lyapunov, not 'sali'$"):
        usage.check_map_options(3, 3, "sali", None, spell=str)
    with pytest.raises(UsageError, match="^--t-end must be a positive finite time"):
        usage.check_map_options(3, 3, "megno", -1.0)
    assert usage.check_ranges({"y": (0, 1)}) == {"y": (0.0, 1.0)}
    with pytest.raises(UsageError, match="^ranges: y's low end must be below its high end$"):
        usage.check_ranges({"y": (1, 0)}, spell=str)
