"""A scene nobody compiled yet runs at once, interpreted, and switches to numba's code."""

from __future__ import annotations

import uuid

from tests.explorer.conftest import wait_for_points


def _new_pendulum_text() -> str:
    tag = "u" + uuid.uuid4().hex[:10]  # a parameter name no kernel module has yet
    return f"""
title = "Pendulum {tag}"
[system]
coordinates = ["theta"]
parameters = {{ m = 1.0, g = 9.81, l = 1.0, {tag} = 0.0 }}
kinetic = "m*l**2*theta_dot**2/2"
potential = "-m*g*l*cos(theta) + {tag}*theta"
[initial]
theta = 2.0
[drawing]
points = {{ bob = ["l*sin(theta)", "-l*cos(theta)"] }}
links = [["origin", "bob"]]
"""


def test_a_new_scene_runs_interpreted_then_hands_over_to_numba(qtbot, window):
    from systems.native_build import cached

    window.builder.request(_new_pendulum_text())
    qtbot.waitUntil(
        lambda: window.compiled is not None and "Pendulum u" in window.built.scene.title,
        timeout=60000,
    )
    compiled = window.compiled
    assert compiled.kernels.__class__.__name__ == "KernelHandover"
    wait_for_points(qtbot, window, 5)
    qtbot.waitUntil(lambda: compiled.handed_over, timeout=240000)
    assert compiled.kernels.error is None
    assert cached(compiled, window.built.method)
    count = len(window.store.main.t)
    wait_for_points(qtbot, window, count + 20)
    # the label is empty between rate measurements (a busy machine): wait for a rate
    qtbot.waitUntil(lambda: window.rate_label.text().endswith("steps/s"), timeout=10000)
    assert "interpreted" not in window.rate_label.text()
