"""Scenes: a mechanical system as text (TOML), read into a frozen, validated value.

The format is documented for users in ``docs/scenes.md``. Every expression is checked by
the whitelist parser when the scene is read, so a scene that loads will derive.

A file is read strictly: any problem is a ``SceneError``. The editor reads what the user
is typing with ``drop_unfit=True``: a drawing or a ``[view]`` setting that does not fit
the system (typically names left over after the coordinates changed) is then left out and
reported in ``Scene.warnings`` instead of refusing the whole system.

A scene may describe its bodies (``[particles]``) instead of its kinetic energy: the
table is read here, and ``systems.particles`` builds T and the gravitational V from the
parsed positions; ``Scene.energies`` hands both on to the derivation.
"""

from __future__ import annotations

import dataclasses
import math
import re
import tomllib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import sympy

from systems.expressions import ExpressionError, check_name, parse_expression
from systems.files import FileTooLarge, read_file
from systems.limits import MIN_T_END
from systems.particles import Particle, Transformation, depends_on_time, transformation

SCENES_DIR = Path(__file__).resolve().parent.parent / "resources" / "scenes"
SYSTEM_KINDS = ("energies", "lagrangian", "hamiltonian")
CONSTRAINT_KINDS = {
    "holonomic": ("each f(q, t) meaning f = 0", "x**2 + y**2 - l**2"),
    "nonholonomic": (
        "each linear in the velocities, a(q, t) . qdot + b(q, t), meaning = 0",
        "x_dot - R*cos(phi)*psi_dot",
    ),
    "unilateral": ("each g(q, t) meaning g >= 0", "y"),
}
"""The kinds of ``[constraints]``: what each entry means, and an example."""


class SceneError(ValueError):
    """A scene that cannot be read, with the file, the field and the position."""

    def __init__(
        self, reason: str, *, source: str = "<text>", field: str | None = None, position=None
    ):
        self.reason = reason
        self.source = source
        self.field = field
        self.position = position
        super().__init__(str(self))

    def __str__(self) -> str:
        where = f"{self.field}: " if self.field else ""
        at = f" (at position {self.position})" if self.position else ""
        return f"{self.source}: {where}{self.reason}{at}"


@dataclass(frozen=True)
class SceneWarning:
    """A part of a scene that did not fit the system and was left out (``drop_unfit``).

    ``field`` names it (``"drawing.points.bob.x"``, ``"view.phase"``), ``reason`` says
    what is wrong and ``position`` is the 1-based column in an expression, or None.
    """

    field: str
    reason: str
    position: int | None = None
    source: str = "<text>"

    @property
    def part(self) -> str:
        """What was left out: ``"drawing"``, or the ``[view]`` key such as ``"view.phase"``."""
        if self.field.startswith("drawing"):
            return "drawing"
        return ".".join(self.field.split(".")[:2])

    def __str__(self) -> str:
        at = f" (at position {self.position})" if self.position else ""
        left_out = "the drawing" if self.part == "drawing" else self.part
        return f"{self.source}: {self.field}: {self.reason}{at}; {left_out} left out"


@dataclass(frozen=True)
class Drawing:
    """Cartesian points of the mechanism, as expression text in q, t and parameters."""

    points: tuple[tuple[str, str, str], ...] = ()
    links: tuple[tuple[str, str], ...] = ()
    trace: tuple[str, ...] = ()

    @property
    def point_names(self) -> tuple[str, ...]:
        return tuple(name for name, _, _ in self.points)


@dataclass(frozen=True)
class CatalogueEntry:
    name: str
    title: str
    description: str
    path: Path


@dataclass(frozen=True)
class Scene:
    """A mechanical system with its parameters, effects, initial state and drawing.

    Exactly one of (``kinetic`` and ``potential``), (``particles`` and ``potential``),
    ``lagrangian`` or ``hamiltonian`` is given. Expressions are kept as text (what the
    user typed); ``symbols`` and ``expression`` give their sympy form. With
    ``particles``, ``gravity`` is the uniform field (a magnitude along -y, or a vector of
    as many components as the positions; None: no field), and ``drawing`` holds the
    particles' points (their x and y) with whatever ``[drawing]`` added. ``warnings``
    lists what was left out when the scene was read with ``drop_unfit=True`` (empty
    otherwise); it takes no part in comparisons. ``holonomic_constraints`` are the texts
    of ``[constraints] holonomic``, each f(q, t) = 0 (fields
    ``"constraints.holonomic[<i>]"``; see ``systems.constraints``);
    ``nonholonomic_constraints`` those of ``[constraints] nonholonomic``, each
    a(q, t) . qdot + b(q, t) = 0, linear in the velocities (``"constraints.nonholonomic[<i>]"``);
    ``unilateral_constraints`` those of ``[constraints] unilateral``, each g(q, t) >= 0
    (``"constraints.unilateral[<i>]"``). ``symmetries`` are the
    user's generators of ``[symmetries]``: (name, ((coordinate, xi text), ...)), fields
    ``"symmetries.<name>.<q>"`` (see ``systems.symmetries``).
    """

    title: str
    coordinates: tuple[str, ...]
    parameters: tuple[tuple[str, float], ...] = ()
    kinetic: str | None = None
    potential: str | None = None
    lagrangian: str | None = None
    hamiltonian: str | None = None
    dissipation: str | None = None
    forces: tuple[tuple[str, str], ...] = ()
    disabled: frozenset[str] = frozenset()
    initial: tuple[tuple[str, float], ...] = ()
    drawing: Drawing | None = None
    view: Mapping[str, Any] = field(default_factory=dict, hash=False)
    description: str = ""
    source: str = "<text>"
    name: str = ""
    particles: tuple[Particle, ...] = ()
    gravity: str | tuple[str, ...] | None = None
    holonomic_constraints: tuple[str, ...] = ()
    nonholonomic_constraints: tuple[str, ...] = ()
    unilateral_constraints: tuple[str, ...] = ()
    symmetries: tuple[tuple[str, tuple[tuple[str, str], ...]], ...] = ()
    warnings: tuple[SceneWarning, ...] = field(default=(), compare=False)

    def __post_init__(self) -> None:
        _validate(self)

    @property
    def kind(self) -> str:
        """``"energies"``, ``"lagrangian"`` or ``"hamiltonian"``."""
        if self.hamiltonian is not None:
            return "hamiltonian"
        if self.lagrangian is not None:
            return "lagrangian"
        return "energies"

    def energies(self) -> tuple[sympy.Expr, sympy.Expr]:
        """T and V of a scene of kind ``"energies"``, as sympy expressions.

        From ``kinetic`` and ``potential`` (0 if not given), or, for a scene with
        particles, T from the particles and V = the gravitational potential plus
        ``potential``.

        Raises
        ------
        ValueError
            For a scene given by a Lagrangian or a Hamiltonian.
        """
        if self.kind != "energies":
            raise ValueError(f"a scene given by its {self.kind} has no T and V")
        if self.particles:
            return self.expression("system.kinetic"), self.expression("system.potential")
        kinetic = self.expression("system.kinetic")
        return kinetic, self._expressions.get("system.potential", sympy.S.Zero)

    @cached_property
    def transformation(self) -> Transformation | None:
        """The particles' transformation equations r_i(q, t), their velocities and T
        split as T2 + T1 + T0 (``systems.particles``); None without particles."""
        if not self.particles:
            return None
        gravity = None
        if isinstance(self.gravity, tuple):
            gravity = tuple(
                self.expression(f"system.gravity[{i}]") for i in range(len(self.gravity))
            )
        elif self.gravity is not None:
            gravity = self.expression("system.gravity")
        symbols = self.symbols
        return transformation(
            [particle.name for particle in self.particles],
            [self.expression(f"particles.{particle.name}.mass") for particle in self.particles],
            self._positions,
            gravity,
            tuple(symbols[q] for q in self.coordinates),
            tuple(symbols[v] for v in self.velocity_names),
            symbols["t"],
        )

    @cached_property
    def transformation_depends_on_time(self) -> bool:
        """True exactly when some particle's position r_i(q, t) depends on t explicitly
        (a rheonomic transformation); False for a scene without particles.

        Read off the positions alone, without forming T.
        """
        return bool(self.particles) and depends_on_time(self._positions, self.symbols["t"])

    @property
    def _positions(self) -> tuple[tuple[sympy.Expr, ...], ...]:
        return tuple(
            tuple(
                self.expression(f"particles.{particle.name}.position[{i}]")
                for i in range(len(particle.position))
            )
            for particle in self.particles
        )

    @property
    def parameter_values(self) -> dict[str, float]:
        return dict(self.parameters)

    @property
    def initial_values(self) -> dict[str, float]:
        return dict(self.initial)

    @property
    def velocity_names(self) -> tuple[str, ...]:
        return tuple(f"{q}_dot" for q in self.coordinates)

    @property
    def momentum_names(self) -> tuple[str, ...]:
        return tuple(f"p_{q}" for q in self.coordinates)

    def effect_keys(self) -> list[str]:
        """Every effect the scene defines: ``"dissipation"`` and ``"forces.<q>"``."""
        keys = ["dissipation"] if self.dissipation is not None else []
        return keys + [f"forces.{q}" for q, _ in self.forces]

    def enabled_effects(self) -> list[str]:
        return [key for key in self.effect_keys() if key not in self.disabled]

    def with_effects(self, enabled: Iterable[str]) -> Scene:
        """A copy with exactly the effects in ``enabled`` switched on."""
        enabled = set(enabled)
        unknown = enabled - set(self.effect_keys())
        if unknown:
            raise SceneError(f"unknown effect {sorted(unknown)[0]!r}", source=self.source)
        return dataclasses.replace(self, disabled=frozenset(set(self.effect_keys()) - enabled))

    def with_parameters(self, **values: float) -> Scene:
        """A copy with some parameter values changed."""
        current = dict(self.parameters)
        for name, value in values.items():
            if name not in current:
                raise SceneError(f"unknown parameter {name!r}", source=self.source)
            current[name] = float(value)
        return dataclasses.replace(self, parameters=tuple(current.items()))

    def with_initial(self, **values: float) -> Scene:
        """A copy with some initial values (q, q_dot or p_q) changed."""
        current = dict(self.initial)
        current.update({name: float(value) for name, value in values.items()})
        return dataclasses.replace(self, initial=tuple(current.items()))

    # -- symbols and expressions ---------------------------------------------------------

    @cached_property
    def symbols(self) -> dict[str, sympy.Symbol]:
        """Every name a scene expression may use, mapped to a real sympy symbol."""
        names = ["t", *self.coordinates, *self.velocity_names, *self.momentum_names]
        names += [name for name, _ in self.parameters]
        return {name: sympy.Symbol(name, real=True) for name in names}

    def allowed(self, *groups: str) -> dict[str, sympy.Symbol]:
        """Symbols of the named groups: ``q``, ``qdot``, ``p``, ``t``, ``params``."""
        table = {
            "q": self.coordinates,
            "qdot": self.velocity_names,
            "p": self.momentum_names,
            "t": ("t",),
            "params": tuple(name for name, _ in self.parameters),
        }
        return {name: self.symbols[name] for group in groups for name in table[group]}

    def expression(self, field_name: str) -> sympy.Expr:
        """The parsed expression of a field such as ``"system.kinetic"`` or ``"forces.x"``.

        In a scene with particles, ``"system.kinetic"`` is T derived from them and
        ``"system.potential"`` the gravitational V plus the ``potential`` given; the
        particles' own fields are ``"particles.<name>.mass"``,
        ``"particles.<name>.position[<i>]"`` (from 0) and ``"system.gravity"`` (or
        ``"system.gravity[<i>]"`` for a vector).

        Raises
        ------
        KeyError
            For a field the scene does not have.
        """
        if self.particles and field_name in ("system.kinetic", "system.potential"):
            derived = self.transformation
            if field_name == "system.kinetic":
                return derived.kinetic
            given = self._expressions.get("system.potential", sympy.S.Zero)
            return derived.potential + given
        return self._expressions[field_name]

    @cached_property
    def _expressions(self) -> dict[str, sympy.Expr]:
        return _parse_all(self)

    def to_toml(self) -> str:
        """The scene as TOML text that ``parse_scene`` reads back to an equal scene."""
        return _to_toml(self)


# -- reading ---------------------------------------------------------------------------


def parse_scene(
    text: str, source: str = "<text>", name: str = "", *, drop_unfit: bool = False
) -> Scene:
    """Read a scene from TOML text.

    Parameters
    ----------
    text
        The scene document.
    source
        Where it came from (a path, ``"<editor>"``), named in every message.
    name
        The scene's short name (a file's stem).
    drop_unfit
        Leave out a drawing or ``[view]`` setting that does not fit the system and list it
        in ``Scene.warnings``, instead of raising (see ``scene_from_dict``).

    Raises
    ------
    SceneError
        Naming ``source``, the field and, for expressions, the position.
    """
    return scene_from_dict(
        read_document(text, source), source=source, name=name, drop_unfit=drop_unfit
    )


def read_document(text: str, source: str = "<text>") -> dict[str, Any]:
    """The tables of a scene document, decoded from TOML but not checked as a scene.

    The size and nesting limits of ``parse_scene`` apply.

    Raises
    ------
    SceneError
        If the text is too long, nested too deeply or not valid TOML.
    """
    if len(text) > MAX_SCENE_CHARACTERS:
        raise SceneError(
            f"the scene is {len(text):,} characters long; a scene may have at most "
            f"{MAX_SCENE_CHARACTERS:,}",
            source=source,
        )
    depth = _nesting(text)
    if depth > MAX_TOML_NESTING:
        raise SceneError(
            f"arrays and tables are nested {depth} deep; a scene needs at most {MAX_TOML_NESTING}",
            source=source,
        )
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"not valid TOML: {exc}", source=source) from None
    except RecursionError:
        raise SceneError("arrays or tables are nested too deeply", source=source) from None


MAX_SCENE_CHARACTERS = 1_000_000
"""Longest scene text read: a 64-particle chain written out by hand is about 20 000."""

MAX_TOML_NESTING = 8
"""Deepest nesting of TOML arrays and inline tables (a scene uses at most 3)."""


def _nesting(text: str) -> int:
    """The deepest nesting of ``[``/``{`` in ``text`` outside strings and comments.

    A cheap scan before ``tomllib``, whose recursive parser fails on a few hundred levels.
    Table headers (``[system]``, ``[[x]]``) open and close on one line and count as 1 or 2.
    """
    depth = deepest = 0
    i, size = 0, len(text)
    while i < size:
        c = text[i]
        if c == "#":
            end = text.find("\n", i)
            i = size if end < 0 else end
            continue
        if c in "\"'":
            triple = text.startswith(c * 3, i)
            quote = c * 3 if triple else c
            i += len(quote)
            while i < size and not text.startswith(quote, i):
                if c == '"' and text[i] == "\\":
                    i += 1
                elif not triple and text[i] == "\n":
                    break
                i += 1
            i += len(quote)
            continue
        if c in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif c in "]}":
            depth = max(0, depth - 1)
        i += 1
    return deepest


def scene_from_dict(
    data: Mapping[str, Any], source: str = "<text>", name: str = "", *, drop_unfit: bool = False
) -> Scene:
    """Build a scene from the tables of a TOML document (already decoded).

    Parameters
    ----------
    data
        The tables, as ``tomllib`` gives them; not modified.
    source, name
        As for ``parse_scene``.
    drop_unfit
        False (files, the command line): any problem raises ``SceneError``. True (the
        editor): a ``[drawing]`` with any problem (an expression naming a coordinate that
        no longer exists, a link to an unknown point, a wrong type) is left out whole, and
        a ``[view]`` key that is wrong (a phase pair, section or angle that is not a
        coordinate of the system; a range entry of an unknown name is left out alone) is
        left out; each is listed in ``Scene.warnings`` and the system is built without it.
        Problems of the system itself, the effects and the initial state still raise.

    Raises
    ------
    SceneError
        Naming ``source``, the field and, for expressions, the position.
    """
    reader = _Reader(data, source)
    warnings: list[SceneWarning] = []
    system = reader.table(data, "system", required=True)
    reader.check_keys(
        system,
        "system",
        {
            "coordinates",
            "parameters",
            "kinetic",
            "potential",
            "lagrangian",
            "hamiltonian",
            "gravity",
        },
    )
    coordinates = reader.names(system.get("coordinates"), "system.coordinates")
    parameters = reader.parameters(system.get("parameters", {}))
    particles = reader.particles(reader.table(data, "particles"))
    gravity = reader.gravity(system["gravity"]) if "gravity" in system else None
    effects = reader.table(data, "effects")
    reader.check_keys(effects, "effects", {"dissipation", "forces", "disabled"})
    forces_table = reader.table(effects, "forces", prefix="effects.")
    constraint_texts = reader.constraints(reader.table(data, "constraints"))
    top = {"title", "description", "system", "particles", "effects", "initial", "drawing", "view"}
    top.add("constraints")
    symmetries = reader.symmetries(reader.table(data, "symmetries"))
    top.add("symmetries")
    if drop_unfit:
        problems: list[SceneError] = []
        drawing = reader.drawing(
            _table_or_problem(reader, data, "drawing", problems), problems, particles
        )
        view = dict(_table_or_problem(reader, data, "view", problems))
        warnings += [_left_out(problem) for problem in problems]
        checked = drawing  # its expressions are checked too, so all is reported at once
        if any((problem.field or "").startswith("drawing") for problem in problems):
            drawing = _particle_drawing(particles)
    else:
        drawing = reader.drawing(reader.table(data, "drawing"), particles=particles)
        view = dict(reader.table(data, "view"))
    reader.check_keys(data, "", top)
    texts = {}
    for key in ("kinetic", "potential", "lagrangian", "hamiltonian"):
        if key in system:
            texts[key] = reader.text(system[key], f"system.{key}")
    dissipation = effects.get("dissipation")
    kwargs = dict(
        title=reader.text(data.get("title", name or "Untitled"), "title"),
        description=reader.text(data.get("description", ""), "description"),
        coordinates=coordinates,
        parameters=parameters,
        dissipation=None
        if dissipation is None
        else reader.text(dissipation, "effects.dissipation"),
        forces=tuple((q, reader.text(v, f"effects.forces.{q}")) for q, v in forces_table.items()),
        disabled=frozenset(reader.string_list(effects.get("disabled", []), "effects.disabled")),
        initial=tuple(
            (k, reader.number(v, f"initial.{k}", parameters))
            for k, v in reader.table(data, "initial").items()
        ),
        drawing=drawing,
        view=view,
        source=source,
        name=name,
        particles=particles,
        gravity=gravity,
        holonomic_constraints=constraint_texts["holonomic"],
        nonholonomic_constraints=constraint_texts["nonholonomic"],
        unilateral_constraints=constraint_texts["unilateral"],
        symmetries=symmetries,
        **texts,
    )
    if not drop_unfit:
        scene = _build(kwargs, source)
        scene._expressions  # noqa: B018 - parse every expression now, so errors surface on load
        return scene
    while True:
        try:
            scene = _build(kwargs, source)
            break
        except SceneError as exc:
            if not _drop_view_part(view, exc.field):
                raise
            warnings.append(_left_out(exc))
    drawing_problems = _drawing_problems(scene, checked)
    warnings += [_left_out(problem) for problem in drawing_problems]
    if warnings:
        left_out = {"drawing": _particle_drawing(particles)} if drawing_problems else {}
        scene = dataclasses.replace(scene, warnings=tuple(warnings), **left_out)
    scene._expressions  # noqa: B018 - the system's errors are the user's to fix: they raise
    return scene


def _particle_drawing(particles: tuple[Particle, ...]) -> Drawing | None:
    """The drawing of the particles alone: a point at each one's x and y, no links."""
    if not particles:
        return None
    return Drawing(tuple((p.name, p.position[0], p.position[1]) for p in particles))


def _table_or_problem(reader, data: Mapping, key: str, problems: list) -> Mapping[str, Any]:
    """``reader.table(data, key)``, or an empty table with the problem recorded."""
    try:
        return reader.table(data, key)
    except SceneError as exc:
        problems.append(exc)
        return {}


def _left_out(problem: SceneError) -> SceneWarning:
    return SceneWarning(problem.field or "", problem.reason, problem.position, problem.source)


def _drop_view_part(view: dict, field: str | None) -> bool:
    """Remove from ``view`` the part ``field`` names (a key, or one entry of ``ranges``).

    Returns False if ``field`` is not in the view (the problem is elsewhere). Nested tables
    are copied, never changed in place: they may belong to the caller's document.
    """
    if not field or not field.startswith("view."):
        return False
    parts = field[len("view.") :].split(".", 1)
    key = parts[0]
    if key not in view:
        return False
    ranges = view.get("ranges")
    if key == "ranges" and len(parts) == 2 and isinstance(ranges, Mapping) and parts[1] in ranges:
        kept = {k: v for k, v in ranges.items() if k != parts[1]}
        if kept:
            view["ranges"] = kept
        else:
            del view["ranges"]
        return True
    del view[key]
    return True


def _build(kwargs: dict, source: str) -> Scene:
    try:
        return Scene(**kwargs)
    except ExpressionError as exc:
        raise SceneError(
            exc.reason, source=source, field=exc.field, position=exc.position
        ) from None


def load_scene(name_or_path: str | Path) -> Scene:
    """Load a catalogue scene by name (``"simple_pendulum"``) or a ``.toml`` file by path.

    Read strictly (see ``scene_from_dict``).
    """
    path = scene_path(name_or_path)
    return parse_scene(read_scene_file(path), source=str(path), name=path.stem)


def scene_path(name_or_path: str | Path) -> Path:
    """The file of a catalogue scene name, or ``name_or_path`` itself if it is a path.

    Raises
    ------
    SceneError
        If it is neither a ``.toml`` path, an existing file, nor a catalogue name.
    """
    path = Path(name_or_path)
    if path.suffix != ".toml" and not path.exists():
        candidate = SCENES_DIR / f"{name_or_path}.toml"
        if not candidate.exists():
            names = ", ".join(entry.name for entry in catalogue())
            raise SceneError(
                f"no catalogue scene or file named {str(name_or_path)!r} (catalogue: {names})",
                source=str(name_or_path),
            )
        path = candidate
    return path


def read_scene_file(path: str | Path) -> str:
    """The text of a scene file, checked to be UTF-8 text of a sensible size (not parsed).

    For the window's File > Open, which shows the text in the editor
    (``SystemEditorPanel.show_document``) whether or not it is a valid scene yet.

    Raises
    ------
    SceneError
        If the file cannot be read, is no regular file (a named pipe, ``/dev/zero``, a
        folder: refused before anything is read, ``systems.files.read_file``), is too
        large, or is not UTF-8 text.
    """
    path = Path(path)
    try:
        raw = read_file(path, 4 * MAX_SCENE_CHARACTERS)
    except FileTooLarge as exc:
        raise SceneError(
            f"the file is {exc.size:,} bytes; a scene is a text file of at most "
            f"{MAX_SCENE_CHARACTERS:,} characters",
            source=str(path),
        ) from None
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise SceneError(f"cannot read the file: {reason}", source=str(path)) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SceneError(
            f"not a text file: byte {exc.start} is not UTF-8 text (is this a .toml scene?)",
            source=str(path),
        ) from None
    if "\x00" in text:
        raise SceneError("not a text file: it contains NUL bytes", source=str(path))
    return text


_CATALOGUE_READ: dict[Path, tuple[tuple[int, int, int], CatalogueEntry]] = {}
"""Each catalogue file's entry by path, with the file's (mtime, size, inode) when it was
read: every window's editor lists the catalogue, and reading its 25 files again took
7-9 ms of the GUI thread each time. A file that did not read is tried again."""


def catalogue() -> list[CatalogueEntry]:
    """The scenes shipped in ``resources/scenes``, sorted by name."""
    entries = []
    for path in sorted(SCENES_DIR.glob("*.toml")):
        try:
            stat = path.stat()
        except OSError:
            continue
        version = (stat.st_mtime_ns, stat.st_size, stat.st_ino)
        known = _CATALOGUE_READ.get(path)
        if known is None or known[0] != version:
            entry = _catalogue_entry(path)
            if entry is None:
                continue
            known = _CATALOGUE_READ[path] = (version, entry)
        entries.append(known[1])
    return entries


def _catalogue_entry(path: Path) -> CatalogueEntry | None:
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError):
        return None
    return CatalogueEntry(
        path.stem, str(data.get("title", path.stem)), str(data.get("description", "")), path
    )


class _Reader:
    def __init__(self, data: Mapping[str, Any], source: str):
        self.data = data
        self.source = source

    def fail(self, field: str, reason: str) -> SceneError:
        return SceneError(reason, source=self.source, field=field or None)

    def table(self, data: Mapping, key: str, required=False, prefix="") -> Mapping[str, Any]:
        value = data.get(key)
        if value is None:
            if required:
                raise self.fail(prefix + key, f"the table [{prefix + key}] is missing")
            return {}
        if not isinstance(value, Mapping):
            raise self.fail(prefix + key, "must be a table")
        return value

    def check_keys(self, table: Mapping, where: str, allowed: set[str]) -> None:
        for key in table:
            if key not in allowed:
                field = f"{where}.{key}" if where else key
                raise self.fail(
                    field, f"unknown key (expected one of: {', '.join(sorted(allowed))})"
                )

    def text(self, value: Any, field: str) -> str:
        if isinstance(value, bool) or not isinstance(value, str | int | float):
            raise self.fail(field, "must be a string (an expression in quotes)")
        return str(value)

    def names(self, value: Any, field: str) -> tuple[str, ...]:
        if not isinstance(value, list) or not value:
            raise self.fail(field, 'must be a non-empty list of names, e.g. ["x"]')
        return tuple(self._name(item, field) for item in value)

    def _name(self, item: Any, field: str) -> str:
        try:
            return check_name(item, field=field)
        except ExpressionError as exc:
            raise self.fail(field, exc.reason) from None

    def particles(self, table: Mapping[str, Any]) -> tuple[Particle, ...]:
        """The ``[particles]`` table: ``name = { mass = "m", position = ["x", "y"] }``."""
        if "particles" in self.data and not table:
            raise self.fail(
                "particles",
                'give at least one particle, e.g. bob = { mass = "m", '
                'position = ["l*sin(theta)", "-l*cos(theta)"] }',
            )
        result = []
        for name, entry in table.items():
            field = f"particles.{name}"
            self._name(name, field)
            if name == "origin":
                raise self.fail(
                    field,
                    "'origin' is the drawing's fixed point (0, 0); give the particle another name",
                )
            if not isinstance(entry, Mapping):
                raise self.fail(field, 'must be a table { mass = "m", position = ["x", "y"] }')
            self.check_keys(entry, field, {"mass", "position"})
            for key in ("mass", "position"):
                if key not in entry:
                    raise self.fail(f"{field}.{key}", f"the {key} is missing")
            mass = self.text(entry["mass"], f"{field}.mass")
            position = entry["position"]
            if not isinstance(position, list) or len(position) not in (2, 3):
                raise self.fail(
                    f"{field}.position",
                    "must be a list of 2 or 3 expressions (x, y or x, y, z), "
                    'e.g. ["l*sin(theta)", "-l*cos(theta)"]',
                )
            components = tuple(
                self.text(c, f"{field}.position[{i}]") for i, c in enumerate(position)
            )
            result.append(Particle(name, mass, components))
        return tuple(result)

    def gravity(self, value: Any) -> str | tuple[str, ...]:
        """``system.gravity``: a magnitude (along -y) or a vector of 2 or 3 expressions."""
        if isinstance(value, list):
            if len(value) not in (2, 3):
                raise self.fail(
                    "system.gravity",
                    'must be a magnitude, e.g. "g", or a vector of 2 or 3 expressions, '
                    'e.g. ["0", "0", "-g"]',
                )
            return tuple(self.text(c, f"system.gravity[{i}]") for i, c in enumerate(value))
        return self.text(value, "system.gravity")

    def constraints(self, table: Mapping[str, Any]) -> dict[str, tuple[str, ...]]:
        """The ``[constraints]`` table: ``holonomic = ["f(q, t)", ...]`` (each f = 0),
        ``nonholonomic = ["a(q, t) . qdot + b(q, t)", ...]`` (each = 0) and
        ``unilateral = ["g(q, t)", ...]`` (each g >= 0); a kind not given is empty."""
        self.check_keys(table, "constraints", set(CONSTRAINT_KINDS))
        result = {}
        for kind, (meaning, example) in CONSTRAINT_KINDS.items():
            if kind not in table:
                result[kind] = ()
                continue
            value = table[kind]
            if not isinstance(value, list) or not value:
                raise self.fail(
                    f"constraints.{kind}",
                    f'must be a non-empty list of expressions, {meaning}, e.g. ["{example}"]',
                )
            result[kind] = tuple(
                self.text(item, f"constraints.{kind}[{i}]") for i, item in enumerate(value)
            )
        return result

    def symmetries(self, table: Mapping[str, Any]) -> tuple:
        """The ``[symmetries]`` table: ``name = { <q> = "xi_q(q)", ... }``, a generator
        per entry (coordinates not named get 0)."""
        from systems.symmetries import RESERVED

        result = []
        for name, entry in table.items():
            field = f"symmetries.{name}"
            self._name(name, field)
            if name in RESERVED or name.startswith("p_"):
                raise self.fail(
                    field,
                    f"{name!r} is the name of a quantity Phase Explorer finds itself "
                    f"({', '.join(sorted(RESERVED))}, p_<q>); choose another name",
                )
            if not isinstance(entry, Mapping) or not entry:
                raise self.fail(
                    field,
                    'must be a table of coordinate = "xi(q)", e.g. { z = "1", phi = "c" }',
                )
            result.append(
                (name, tuple((q, self.text(v, f"{field}.{q}")) for q, v in entry.items()))
            )
        return tuple(result)

    def string_list(self, value: Any, field: str) -> list[str]:
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise self.fail(field, "must be a list of strings")
        return value

    def parameters(self, value: Any) -> tuple[tuple[str, float], ...]:
        if not isinstance(value, Mapping):
            raise self.fail("system.parameters", "must be a table of name = value")
        result: dict[str, float] = {}
        for key, raw in value.items():
            field = f"system.parameters.{key}"
            self._name(key, field)
            result[key] = self.number(raw, field, tuple(result.items()))
        return tuple(result.items())

    def number(self, value: Any, field: str, parameters) -> float:
        """A number, or a constant expression of earlier parameters, e.g. ``"pi/2"``."""
        if isinstance(value, bool):
            raise self.fail(field, "must be a number")
        if isinstance(value, str):
            params = dict(parameters)
            symbols = {k: sympy.Float(v) for k, v in params.items()}
            try:
                expr = parse_expression(value, symbols, field=field)
                value = float(expr.evalf())
            except ExpressionError as exc:
                raise SceneError(
                    exc.reason, source=self.source, field=field, position=exc.position
                ) from None
            except (TypeError, ValueError):
                raise self.fail(field, "must evaluate to a real number") from None
        if not isinstance(value, int | float) or not math.isfinite(value):
            raise self.fail(field, "must be a finite number")
        return float(value)

    def drawing(
        self,
        table: Mapping[str, Any],
        problems: list[SceneError] | None = None,
        particles: tuple[Particle, ...] = (),
    ) -> Drawing | None:
        """The ``[drawing]`` table with the particles' points, or None if there are none.

        Each particle is a point of its name at its x and y, first and in order; a point
        of ``[drawing]`` with a particle's name replaces that particle's point, the others
        follow. Links and the trace may name particles.

        With ``problems`` (a list), every problem found is appended to it instead of the
        first being raised, and the parts in error are skipped.
        """

        def fail(field: str, reason: str) -> None:
            if problems is None:
                raise self.fail(field, reason)
            problems.append(self.fail(field, reason))

        if not table:
            return _particle_drawing(particles)
        try:
            self.check_keys(table, "drawing", {"points", "links", "trace"})
        except SceneError as exc:
            if problems is None:
                raise
            problems.append(exc)
        points = []
        raw_points = table.get("points", {})
        if not isinstance(raw_points, Mapping):
            fail("drawing.points", 'must be a table: name = ["x", "y"]')
            raw_points = {}
        for name, xy in raw_points.items():
            field = f"drawing.points.{name}"
            if not isinstance(xy, list) or len(xy) != 2:
                fail(field, "must be a list of two expressions [x, y]")
                continue
            if not all(isinstance(v, str | int | float) and not isinstance(v, bool) for v in xy):
                fail(field, "must be a string (an expression in quotes)")
                continue
            points.append((name, str(xy[0]), str(xy[1])))
        given = {name: (name, x, y) for name, x, y in points}
        own = _particle_drawing(particles)
        points = [given.pop(name, (name, x, y)) for name, x, y in own.points] if own else []
        points += given.values()
        known = {name for name, _, _ in points} | {"origin"}
        links = []
        links_raw = table.get("links", [])
        if not isinstance(links_raw, list):
            fail("drawing.links", 'must be a list of pairs, e.g. [["origin", "bob"]]')
            links_raw = []
        for i, link in enumerate(links_raw):
            field = f"drawing.links[{i}]"
            if not isinstance(link, list) or len(link) != 2:
                fail(field, 'must be a pair of point names, e.g. ["origin", "bob"]')
                continue
            wrong = [end for end in link if not isinstance(end, str)]
            if wrong:
                fail(field, f"point names are strings, not {wrong[0]!r}")
                continue
            unknown = [end for end in link if end not in known]
            if unknown:
                fail(field, f"unknown point {unknown[0]!r}")
                continue
            links.append((link[0], link[1]))
        trace_raw = table.get("trace", [])
        if not isinstance(trace_raw, list) or not all(isinstance(v, str) for v in trace_raw):
            fail("drawing.trace", "must be a list of strings")
            trace_raw = []
        trace = []
        for name in trace_raw:
            if name not in known:
                fail("drawing.trace", f"unknown point {name!r}")
            else:
                trace.append(name)
        return Drawing(tuple(points), tuple(links), tuple(trace))


# -- validation and parsing ----------------------------------------------------------------


VIEW_KEYS = {"t_end", "phase", "ranges", "section", "angles"}


def _validate_view(scene: Scene, fail) -> None:
    """Every key of ``[view]`` checked for type, finiteness and meaning (docs/scenes.md)."""
    view = scene.view
    unknown = set(view) - VIEW_KEYS
    if unknown:
        allowed = ", ".join(sorted(VIEW_KEYS))
        raise fail(f"view.{sorted(unknown)[0]}", f"unknown key (allowed: {allowed})")
    if "t_end" in view and not _positive_finite(view["t_end"]):
        raise fail("view.t_end", f"must be a positive finite time, not {view['t_end']!r}")
    if "t_end" in view and view["t_end"] < MIN_T_END:
        raise fail("view.t_end", f"must be at least {MIN_T_END:g}, not {view['t_end']!r}")
    names = {*scene.coordinates, *scene.momentum_names, *scene.velocity_names}
    if "phase" in view:
        pair = view["phase"]
        if not (isinstance(pair, list) and len(pair) == 2 and all(p in names for p in pair)):
            raise fail(
                "view.phase",
                f"must be two names among the coordinates and momenta, such as "
                f'["{scene.coordinates[0]}", "{scene.momentum_names[0]}"], not {pair!r}',
            )
    if "ranges" in view:
        ranges = view["ranges"]
        if not isinstance(ranges, Mapping):
            raise fail("view.ranges", "must be a table: name = [low, high]")
        for name, span in ranges.items():
            if name not in names | {"x", "y"}:
                raise fail(f"view.ranges.{name}", "not a coordinate, momentum, x or y")
            ok = isinstance(span, list) and len(span) == 2 and all(map(_finite, span))
            if not ok or not span[0] < span[1]:
                raise fail(
                    f"view.ranges.{name}", f"must be [low, high] with low < high, not {span!r}"
                )
    if "section" in view:
        section = view["section"]
        if not isinstance(section, Mapping) or set(section) - {"coordinate", "value"}:
            raise fail("view.section", 'must be a table { coordinate = "x", value = 0.0 }')
        if "coordinate" in section and section["coordinate"] not in scene.coordinates:
            raise fail("view.section.coordinate", f"{section['coordinate']!r} is not a coordinate")
        if "value" in section and not _finite(section["value"]):
            raise fail("view.section.value", f"must be a finite number, not {section['value']!r}")
    if "angles" in view:
        angles = view["angles"]
        if not isinstance(angles, list) or not all(isinstance(a, str) for a in angles):
            raise fail(
                "view.angles",
                f'must be a list of coordinate names, e.g. ["{scene.coordinates[0]}"], '
                f"not {angles!r}",
            )
        for angle in angles:
            if angle not in scene.coordinates:
                raise fail(
                    "view.angles",
                    f"{angle!r} is not a coordinate (coordinates: {', '.join(scene.coordinates)})",
                )
            if angles.count(angle) > 1:
                raise fail("view.angles", f"{angle!r} is listed twice")


def _finite(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _positive_finite(value: Any) -> bool:
    return _finite(value) and value > 0


def _refuse_output_names(scene: Scene, fail) -> None:
    """Names the output itself uses are not a coordinate's or a parameter's: ``H`` (the
    CSV column and symbol of the Hamiltonian) and ``lambda_<k>`` (the multipliers'
    columns) as a coordinate, ``<q>_ddot`` (how the derivation prints the acceleration
    of q) as any name."""
    accelerations = {f"{q}_ddot": q for q in scene.coordinates}
    for name in scene.coordinates:
        if name == "H":
            raise fail(
                "system.coordinates",
                "'H' names the Hamiltonian in the output (the CSV's H column, the printed H); "
                "call the coordinate otherwise (h, z, ...)",
            )
        if re.fullmatch(r"lambda_\d+", name):
            raise fail(
                "system.coordinates",
                f"{name!r} names a Lagrange multiplier in the output (the CSV's multiplier "
                "columns); call the coordinate otherwise",
            )
    for name in [*scene.coordinates, *(n for n, _ in scene.parameters)]:
        if name in accelerations:
            field = "system.coordinates" if name in scene.coordinates else "system.parameters"
            raise fail(
                field,
                f"{name!r} is how the derivation writes the acceleration of "
                f"{accelerations[name]}; choose another name",
            )


def _validate(scene: Scene) -> None:
    def fail(field: str, reason: str) -> SceneError:
        return SceneError(reason, source=scene.source, field=field)

    if not scene.coordinates:
        raise fail("system.coordinates", "at least one coordinate is needed")
    names = [*scene.coordinates, *scene.velocity_names, *scene.momentum_names]
    seen: set[str] = set()
    for name in names + [name for name, _ in scene.parameters]:
        if name in seen:
            field = "system.parameters" if name in dict(scene.parameters) else "system.coordinates"
            raise fail(
                field,
                f"the name {name!r} is used twice (as coordinate, velocity, momentum or parameter)",
            )
        seen.add(name)
    _refuse_output_names(scene, fail)
    _validate_particles(scene, fail)
    for name, entries in scene.symmetries:
        for q, _ in entries:
            if q not in scene.coordinates:
                raise fail(
                    f"symmetries.{name}.{q}",
                    f"{q!r} is not a coordinate (coordinates: {', '.join(scene.coordinates)})",
                )
    given = {
        "energies": scene.kinetic is not None
        or scene.potential is not None
        or bool(scene.particles),
        "lagrangian": scene.lagrangian is not None,
        "hamiltonian": scene.hamiltonian is not None,
    }
    if sum(given.values()) != 1:
        raise fail(
            "system",
            "give either kinetic (and potential), or [particles] (and potential), or "
            "lagrangian, or hamiltonian: exactly one",
        )
    if given["energies"] and scene.kinetic is None and not scene.particles:
        raise fail("system.kinetic", "the kinetic energy is missing")
    for q, _ in scene.forces:
        if q not in scene.coordinates:
            raise fail(f"effects.forces.{q}", f"{q!r} is not a coordinate")
    unknown = set(scene.disabled) - set(scene.effect_keys())
    if unknown:
        raise fail("effects.disabled", f"unknown effect {sorted(unknown)[0]!r}")
    _validate_view(scene, fail)
    valid_initial = set(scene.coordinates) | set(scene.velocity_names) | set(scene.momentum_names)
    for name, _ in scene.initial:
        if name not in valid_initial:
            raise fail(
                f"initial.{name}", "not a coordinate, velocity (<q>_dot) or momentum (p_<q>)"
            )
    for v, p in zip(scene.velocity_names, scene.momentum_names, strict=True):
        if v in dict(scene.initial) and p in dict(scene.initial):
            raise fail(f"initial.{p}", f"give either {v} or {p}, not both")


def _validate_particles(scene: Scene, fail) -> None:
    """Particles with T, L or H, gravity without particles, mixed dimensions."""
    if not scene.particles:
        if scene.gravity is not None:
            raise fail(
                "system.gravity",
                "gravity acts on particles: describe the bodies in [particles], or write "
                "the gravitational energy into the potential",
            )
        return
    if scene.kinetic is not None:
        raise fail(
            "system.kinetic",
            "give either kinetic or [particles], not both: the particles give T",
        )
    for key in ("lagrangian", "hamiltonian"):
        if getattr(scene, key) is not None:
            raise fail(
                f"system.{key}",
                f"[particles] give T and V, so the scene cannot also give a {key}",
            )
    seen: set[str] = set()
    first = scene.particles[0]
    for particle in scene.particles:
        if particle.name in seen:
            raise fail(f"particles.{particle.name}", "the name is used twice")
        seen.add(particle.name)
        if len(particle.position) not in (2, 3):
            raise fail(f"particles.{particle.name}.position", "must have 2 or 3 components")
        if len(particle.position) != len(first.position):
            raise fail(
                f"particles.{particle.name}.position",
                f"has {len(particle.position)} components, but particles.{first.name} has "
                f"{len(first.position)}: all particles move in the same plane or space",
            )
    dimension = len(first.position)
    if isinstance(scene.gravity, tuple) and len(scene.gravity) != dimension:
        raise fail(
            "system.gravity",
            f"the vector has {len(scene.gravity)} components, but the positions have {dimension}",
        )


CONSTANT_FIELDS = ("particles.", "system.gravity")
"""Fields that are constants of the scene (masses, the field of gravity): numbers and
parameters only."""


def _parse_all(scene: Scene) -> dict[str, sympy.Expr]:
    fields: list[tuple[str, str | None, tuple[str, ...]]] = [
        ("system.kinetic", scene.kinetic, ("q", "qdot", "t", "params")),
        ("system.potential", scene.potential, ("q", "t", "params")),
        ("system.lagrangian", scene.lagrangian, ("q", "qdot", "t", "params")),
        ("system.hamiltonian", scene.hamiltonian, ("q", "p", "t", "params")),
        ("effects.dissipation", scene.dissipation, ("q", "qdot", "t", "params")),
    ]
    fields += [
        (f"effects.forces.{q}", text, ("q", "qdot", "t", "params")) for q, text in scene.forces
    ]
    for particle in scene.particles:
        fields.append((f"particles.{particle.name}.mass", particle.mass, ("params",)))
        fields += [
            (f"particles.{particle.name}.position[{i}]", text, ("q", "t", "params"))
            for i, text in enumerate(particle.position)
        ]
    if isinstance(scene.gravity, tuple):
        fields += [
            (f"system.gravity[{i}]", text, ("params",)) for i, text in enumerate(scene.gravity)
        ]
    elif scene.gravity is not None:
        fields.append(("system.gravity", scene.gravity, ("params",)))
    for kind, groups in (
        ("holonomic", ("q", "t", "params")),
        ("nonholonomic", ("q", "qdot", "t", "params")),
        ("unilateral", ("q", "t", "params")),
    ):
        fields += [
            (f"constraints.{kind}[{i}]", text, groups)
            for i, text in enumerate(getattr(scene, f"{kind}_constraints"))
        ]
    fields += [
        (f"symmetries.{name}.{q}", text, ("q", "params"))
        for name, entries in scene.symmetries
        for q, text in entries
    ]
    if scene.drawing:
        for name, x, y in scene.drawing.points:
            fields.append((f"drawing.points.{name}.x", x, ("q", "t", "params")))
            fields.append((f"drawing.points.{name}.y", y, ("q", "t", "params")))
    result = {}
    for field_name, text, groups in fields:
        if text is not None:
            result[field_name] = _parse_field(scene, field_name, text, groups)
    coordinates = {scene.symbols[q] for q in scene.coordinates}
    velocities = {scene.symbols[v] for v in scene.velocity_names}
    for kind in CONSTRAINT_KINDS:
        for i in range(len(getattr(scene, f"{kind}_constraints"))):
            field_name = f"constraints.{kind}[{i}]"
            expr = result[field_name]
            if kind == "nonholonomic":
                _check_linear_in_velocities(scene, field_name, expr, velocities)
            elif not expr.free_symbols & coordinates:
                raise SceneError(
                    "a constraint must depend on the coordinates "
                    f"({', '.join(scene.coordinates)}): this one restricts no motion",
                    source=scene.source,
                    field=field_name,
                )
    return result


def _check_linear_in_velocities(scene, field_name: str, expr, velocities) -> None:
    """A nonholonomic constraint is a(q, t) . qdot + b(q, t) = 0: it must contain some
    velocity, and only linearly."""
    used = expr.free_symbols & velocities
    if not used:
        raise SceneError(
            "a nonholonomic constraint restricts the velocities and must contain at least "
            f"one of them ({', '.join(scene.velocity_names)}); a constraint f(q, t) = 0 "
            "belongs in 'holonomic'",
            source=scene.source,
            field=field_name,
        )
    for v in used:
        coefficient = sympy.diff(expr, v)
        if coefficient.free_symbols & velocities:
            raise SceneError(
                f"a nonholonomic constraint must be linear in the velocities, "
                f"a(q, t) . qdot + b(q, t) = 0; this one is not linear in {v}",
                source=scene.source,
                field=field_name,
            )


def _drawing_problems(scene: Scene, drawing: Drawing | None) -> list[SceneError]:
    """Every expression of ``drawing`` that does not parse in ``scene``, one error each
    (none raised)."""
    problems = []
    for name, x, y in drawing.points if drawing else ():
        for axis, text in (("x", x), ("y", y)):
            try:
                _parse_field(scene, f"drawing.points.{name}.{axis}", text, ("q", "t", "params"))
            except SceneError as exc:
                problems.append(exc)
    return problems


def _parse_field(scene: Scene, field_name: str, text: str, groups) -> sympy.Expr:
    allowed = scene.allowed(*groups)
    try:
        return parse_expression(text, allowed, field=field_name)
    except ExpressionError as exc:
        hint = _misplaced_name_hint(scene, exc, groups, field_name)
        reason = exc.reason if hint is None else hint
        raise SceneError(
            reason, source=scene.source, field=field_name, position=exc.position
        ) from None


def _misplaced_name_hint(scene, exc, groups, field_name) -> str | None:
    """A clearer reason when a known name is used where it is not allowed."""
    if not exc.reason.startswith("unknown name"):
        return None
    name = exc.reason.split("'")[1]
    if groups == ("params",) and name in scene.symbols and field_name.startswith(CONSTANT_FIELDS):
        what = "a mass" if field_name.endswith(".mass") else "the field of gravity"
        return f"{what} is a constant: it may use numbers and parameters, not {name!r}"
    if name in scene.velocity_names and field_name.startswith("constraints.holonomic"):
        return (
            f"a holonomic constraint f(q, t) = 0 may not contain the velocity {name!r}; "
            "a constraint on the velocities belongs in 'nonholonomic'"
        )
    if field_name.startswith("symmetries.") and name in scene.symbols:
        return f"a generator xi(q) may use the coordinates, numbers and parameters, not {name!r}"
    if name in scene.velocity_names and "qdot" not in groups:
        if field_name == "system.potential":
            return (
                f"the potential may not depend on the velocity {name!r}; "
                "write a lagrangian instead for velocity-dependent potentials"
            )
        return f"{name!r} (a velocity) is not allowed here"
    if name in scene.momentum_names and "p" not in groups:
        return f"{name!r} (a momentum) is only allowed in a hamiltonian"
    if name in scene.velocity_names and "p" in groups:
        return f"{name!r}: a hamiltonian is written in momenta (p_<q>), not velocities"
    return None


# -- writing ------------------------------------------------------------------------------


def _to_toml(scene: Scene) -> str:
    lines = [f"title = {_str(scene.title)}"]
    if scene.description:
        lines.append(f"description = {_str(scene.description)}")
    lines += ["", "[system]", f"coordinates = [{', '.join(_str(q) for q in scene.coordinates)}]"]
    lines.append(f"parameters = {_inline({k: v for k, v in scene.parameters})}")
    for key in ("kinetic", "potential", "lagrangian", "hamiltonian"):
        value = getattr(scene, key)
        if value is not None:
            lines.append(f"{key} = {_str(value)}")
    if scene.gravity is not None:
        lines.append(f"gravity = {_value(scene.gravity)}")
    if scene.particles:
        lines += ["", "[particles]"]
        lines += [
            f"{_key(p.name)} = {_inline({'mass': p.mass, 'position': list(p.position)})}"
            for p in scene.particles
        ]
    kinds = [k for k in CONSTRAINT_KINDS if getattr(scene, f"{k}_constraints")]
    if kinds:
        lines += ["", "[constraints]"]
        lines += [f"{k} = {_value(list(getattr(scene, f'{k}_constraints')))}" for k in kinds]
    if scene.symmetries:
        lines += ["", "[symmetries]"]
        lines += [f"{_key(name)} = {_inline(dict(entries))}" for name, entries in scene.symmetries]
    if scene.dissipation is not None or scene.forces:
        lines += ["", "[effects]"]
        if scene.dissipation is not None:
            lines.append(f"dissipation = {_str(scene.dissipation)}")
        if scene.forces:
            lines.append(f"forces = {_inline(dict(scene.forces))}")
        if scene.disabled:
            lines.append(f"disabled = [{', '.join(_str(k) for k in sorted(scene.disabled))}]")
    if scene.initial:
        lines += ["", "[initial]"] + [f"{k} = {_value(v)}" for k, v in scene.initial]
    own = _particle_drawing(scene.particles)
    own_points = set(own.points) if own else set()
    d = scene.drawing
    # the particles' own points come from [particles]; only the others are written
    points = (
        {name: [x, y] for name, x, y in d.points if (name, x, y) not in own_points} if d else {}
    )
    if d and (own is None or points or d.links or d.trace):
        lines += ["", "[drawing]"]
        if points or own is None:
            lines.append(f"points = {_inline(points)}")
        if d.links:
            lines.append(f"links = {_value([list(link) for link in d.links])}")
        if d.trace:
            lines.append(f"trace = {_value(list(d.trace))}")
    if scene.view:
        lines += ["", "[view]"] + [f"{k} = {_value(v)}" for k, v in scene.view.items()]
    return "\n".join(lines) + "\n"


def document_toml(data: Mapping[str, Any]) -> str:
    """The tables of a scene document as TOML text, whether or not they make a valid scene.

    The layout is that of ``Scene.to_toml``: the top-level keys (``title``,
    ``description``), then ``[system]``, ``[particles]``, ``[constraints]``,
    ``[symmetries]``, ``[effects]``, ``[initial]``, ``[drawing]`` and ``[view]`` (and any
    other table, in its order), one key a line, nested arrays and tables written inline;
    an empty table other than ``[system]`` is left out. Reading the text with
    ``read_document`` gives the same tables back (an empty table aside).

    Raises
    ------
    TypeError
        For a value TOML cannot hold (None, an object).
    """
    order = [
        "system",
        "particles",
        "constraints",
        "symmetries",
        "effects",
        "initial",
        "drawing",
        "view",
    ]
    tables = [key for key in order if isinstance(data.get(key), Mapping)]
    tables += [k for k, v in data.items() if isinstance(v, Mapping) and k not in tables]
    top = sorted(
        (k for k in data if k not in tables), key=lambda k: (k != "title", k != "description")
    )
    lines = [f"{_key(k)} = {_value(data[k])}" for k in top]
    for key in tables:
        table = data[key]
        if not table and key != "system":
            continue
        if lines:
            lines.append("")
        lines.append(f"[{_key(key)}]")
        lines += [f"{_key(k)} = {_value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


def _str(text: str) -> str:
    escaped = text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
    escaped = "".join(
        f"\\u{ord(c):04x}" if (ord(c) < 32 and c != "\t") or ord(c) == 127 else c for c in escaped
    )
    return f'"{escaped}"'


def _value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(float(value)) if isinstance(value, float) else str(value)
    if isinstance(value, str):
        return _str(value)
    if isinstance(value, Mapping):
        return _inline(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {value!r} as TOML")


def _inline(table: Mapping[str, Any]) -> str:
    items = ", ".join(f"{_key(k)} = {_value(v)}" for k, v in table.items())
    return "{ " + items + " }" if items else "{}"


def _key(key: str) -> str:
    """A TOML key: bare where TOML allows it (ASCII letters, digits, _ and -), else quoted
    (``str.isalnum`` also takes θ and ¹, which TOML refuses bare)."""
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else _str(key)
