"""The Equilibria tab with [constraints]: the multipliers that hold each equilibrium in
their own column, contacts marked, and the kinds said to be on the constraints."""

from __future__ import annotations

from types import SimpleNamespace

from explorer.textbook.equilibria_view import EquilibriaView, force_text, kind_text
from systems.mechanics import derive
from systems.scene import load_scene
from systems.textbook import jobs
from systems.textbook.equilibria import search_equilibria


def _view(qtbot, name: str) -> EquilibriaView:
    mechanics = derive(load_scene(name))
    view = EquilibriaView(runner=None)
    qtbot.addWidget(view)
    view.compiled = SimpleNamespace(mechanics=mechanics)
    result = jobs.EquilibriaResult(
        search_equilibria(mechanics, symbolic=False), tuple(mechanics.scene.coordinates)
    )
    view._on_search_done(result, view.generation)
    return view


def test_the_cartesian_pendulum_shows_the_multiplier_that_holds_each_equilibrium(qtbot):
    view = _view(qtbot, "cartesian_pendulum")
    headers = [view.table.horizontalHeaderItem(c).text() for c in range(view.table.columnCount())]
    assert "constraint force (multipliers)" in headers
    column = headers.index("constraint force (multipliers)")
    bottom, top = view.row_texts()
    assert bottom[column] == "λ₁ = 4.905" and top[column] == "λ₁ = −4.905"
    assert "stable (minimum of U on the constraints)" in bottom
    assert "ω = 3.13209" in " ".join(bottom)
    assert "constraint force −Aᵀλ balances" in view.status.text()
    assert "must push" not in view.status.text()


def test_the_ball_on_the_floor_is_a_contact_that_pushes(qtbot):
    view = _view(qtbot, "bouncing_ball")
    (row,) = view.row_texts()
    assert "λ₁ = −9.81 (contact)" in row
    assert "must push" in view.status.text() and "free (any value)" in view.status.text()
    e = view.result.search.equilibria[0]
    assert force_text(e) == "λ₁ = −9.81 (contact)"
    assert kind_text(e) == "stable (minimum of U on the constraints)"
