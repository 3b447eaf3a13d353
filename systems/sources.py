"""A scene as the window sends it (TOML text, the editor's tables or a ``Scene``), read
and derived: the work of a build that runs in a worker process (``systems.processes``)."""

from __future__ import annotations

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
