"""Poincaré sections for the window: the section, its forbidden region and the state a
click puts on it live in ``systems.section`` (the chaos maps solve the missing momentum
the same way); this module keeps the window's name for them."""

from systems.section import Section, forbidden, state_on_section, states_on_section

__all__ = ["Section", "forbidden", "state_on_section", "states_on_section"]
