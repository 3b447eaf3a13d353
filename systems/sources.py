"""A scene as the window sends it (TOML text, the editor's tables or a ``Scene``), read,
derived and its system functions written: the symbolic work of a build, which runs in a
worker process (``systems.processes``)."""

from __future__ import annotations

from systems.compiled import SystemCode, system_code
from systems.cpu_limit import cpu_limit, limit_seconds
from systems.mechanics import Mechanics, derive
from systems.scene import Scene, parse_scene, scene_from_dict


def derive_source(source: str | dict | Scene) -> Mechanics:
    """Read ``source`` and derive its mechanics; raises the core's errors.

    A ``Scene`` is derived as it is and TOML text is read strictly (``parse_scene``). A
    dict is the editor's document: it is read with ``drop_unfit=True``, so a drawing or
    ``[view]`` setting that does not fit the system is left out and listed in
    ``mechanics.scene.warnings`` instead of failing the build.
    """
    if isinstance(source, Scene):
        scene = source
    elif isinstance(source, dict):  # the editor's document: what does not fit is left out
        scene = scene_from_dict(source, source="<editor>", drop_unfit=True)
    else:
        scene = parse_scene(source, source="<editor>")
    return derive(scene)


def wants_for(mechanics: Mechanics) -> tuple[str, ...]:
    """The system functions the window compiles for ``mechanics``: its motion, energy and
    velocities, and the drawing and separable parts where the scene has them."""
    wants = ["rhs", "hamiltonian", "velocities"]
    scene = mechanics.scene
    if scene.drawing is not None and scene.drawing.points:
        wants.append("drawing")
    if mechanics.classification.separable and mechanics.separable_parts is not None:
        wants.append("separable")
    return tuple(wants)


def build_code(source: str | dict | Scene) -> tuple[Mechanics, SystemCode]:
    """``derive_source``, then the code of the window's system functions (``wants_for``),
    each step within the derivation's CPU-time limit (``systems.cpu_limit``): all of a
    build but turning that code into machine code, which the window's process does."""
    mechanics = derive_source(source)
    with cpu_limit(limit_seconds(), "writing the system's functions"):
        code = system_code(mechanics, wants_for(mechanics))
    return mechanics, code


KNOWN_SOURCE_CHARS = 20_000
"""The longest scene ``build_code.from_cache`` reads in the caller's process: reading is
bounded only by the worker's CPU limit, so a longer text goes to a worker."""


def _build_code_known(source: str | dict | Scene):
    """``build_code(source)`` from the disk alone (the derivation and the code written
    before), in the caller's process, or ``derivation_cache.MISSING``."""
    from systems import derivation_cache

    if not isinstance(source, Scene) and len(str(source)) > KNOWN_SOURCE_CHARS:
        return derivation_cache.MISSING
    try:
        with derivation_cache.only_known():
            mechanics = derive_source(source)
            return mechanics, system_code(mechanics, wants_for(mechanics))
    except derivation_cache.NotKnown:
        return derivation_cache.MISSING


build_code.from_cache = _build_code_known
