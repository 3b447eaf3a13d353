"""The Equilibria tab: ``search_equilibria`` at the current parameter values."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from systems.derivation_cache import remembered_job
from systems.textbook.equilibria import EquilibriumSearch, search_equilibria
from systems.textbook.jobs._cancel import NEVER, Cancel
from systems.textbook.jobs._run import names_of, parameters_of

if TYPE_CHECKING:
    from systems.compiled import CompiledSystem


@dataclass(frozen=True)
class EquilibriaResult:
    """``search_equilibria`` on the current system (see ``systems.textbook.equilibria``)."""

    search: EquilibriumSearch
    names: tuple[str, ...]


@remembered_job
def equilibria(compiled: CompiledSystem, cancel: Cancel = NEVER) -> EquilibriaResult:
    """The equilibria of the compiled system at its parameter values (sliders included)."""
    cancel.check()
    search = search_equilibria(compiled.mechanics, parameters=parameters_of(compiled))
    return EquilibriaResult(search, names_of(compiled))
