"""Compilation: the derived expressions a caller asks for -> numba kernels.

Each wanted function is printed from sympy (after common-subexpression elimination) as
plain scalar Python, placed in the scene's generated module (``systems.codegen``), and
compiled by numba with ``nogil=True``, an explicit signature and an on-disk cache: a
fraction of a second for a new scene, a load from disk for one seen before. The
stepping loops are not part of it: they are compiled once per installation and take
these functions as arguments (``CompiledSystem.functions``). Parameters are an array
argument, so changing a parameter value needs no recompilation. What was not asked for
is neither printed nor compiled.
"""

from __future__ import annotations

import dataclasses
import hashlib
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from types import ModuleType

import numpy as np
import sympy

from systems import calculus, constraints, llvm_kernels, matrix_solve
from systems.codegen import build_module, driver_module, entry_point, system_function
from systems.expressions import as_expr
from systems.kernel_printer import SympyPrinter, Unprintable, engine_text
from systems.mechanics import DerivationError, Mechanics

WANTS = frozenset(
    {"rhs", "hamiltonian", "velocities", "momenta", "separable", "drawing", "lagrangian"}
)


@dataclass(frozen=True, eq=False)
class CompiledSystem:
    """Fast numerical functions of one derived system.

    Attributes
    ----------
    mechanics : Mechanics
    kernels : module or LLVMKernels
        The system functions: compiled from LLVM IR (``systems.llvm_kernels``), or, where
        that writer does not apply, the generated module of numba dispatchers.
    parameters : ndarray, shape (k,)
        Parameter values in ``parameter_names`` order (the array ``P`` of the kernels).
    wanted : frozenset of str
    build_seconds : float
        Time spent printing the system functions and compiling (or loading) them.
    """

    mechanics: Mechanics
    kernels: ModuleType | llvm_kernels.LLVMKernels
    parameter_names: tuple[str, ...]
    parameters: np.ndarray
    wanted: frozenset[str]
    point_names: tuple[str, ...] = ()
    build_seconds: float = 0.0
    hidden: frozenset[str] = frozenset()
    """System functions this value does not offer though its kernels have them
    (``without``)."""
    _numeric: dict = field(default_factory=dict, repr=False)

    @property
    def n(self) -> int:
        return self.mechanics.n

    def __reduce__(self):
        # machine code does not cross between processes: the worker compiles it again
        # (``systems.processes``), a fraction of a second
        wanted = tuple(sorted(self.wanted))
        return (_compiled_again, (self.mechanics, wanted, self.parameters, tuple(self.hidden)))

    def with_parameters(self, values: Sequence[float] | dict[str, float]) -> CompiledSystem:
        """The same kernels with other parameter values (no recompilation)."""
        if isinstance(values, dict):
            current = dict(zip(self.parameter_names, self.parameters, strict=True))
            unknown = set(values) - set(current)
            if unknown:
                raise KeyError(f"unknown parameter {sorted(unknown)[0]!r}")
            current.update(values)
            array = np.array([current[name] for name in self.parameter_names], dtype=float)
        else:
            array = np.asarray(values, dtype=float).copy()
        return dataclasses.replace(self, parameters=array)

    def offers(self, name: str) -> bool:
        """Whether the kernels have the system function ``name`` (``SIGNATURES``): the
        LLVM backend's ``compose_stages``, say, which the numba backend does not write."""
        if name in self.hidden:
            return False
        kernels = self.kernels
        if isinstance(kernels, llvm_kernels.LLVMKernels):
            return name in kernels.functions
        return hasattr(kernels, name)

    def without(self, *names: str) -> CompiledSystem:
        """The same kernels, not offering the system functions ``names``: the drivers then
        take the path they take where a backend does not write them (the warm-up
        compiles both; tests compare them)."""
        return dataclasses.replace(self, hidden=self.hidden | frozenset(names), _numeric={})

    def functions(self, names: Sequence[str]) -> tuple:
        """The system functions ``names`` as the drivers take them (``fns``: numba
        first-class function values)."""
        key = ("functions", tuple(names))
        if key not in self._numeric:
            self._numeric[key] = tuple(self._function(name) for name in names)
        return self._numeric[key]

    def _function(self, name: str):
        if name in self.hidden:
            raise KeyError(f"the system has no function {name!r}")
        kernels = self.kernels
        if isinstance(kernels, llvm_kernels.LLVMKernels):
            if name in kernels.functions:
                return kernels.functions[name]
        elif hasattr(kernels, name):
            return system_function(getattr(kernels, name))
        # the taylor family's, built on first use: its module only then (25 ms of a
        # constrained scene's 50 ms when it opened again)
        from systems.taylor.compiled import BATCH_NAME
        from systems.taylor.compiled import NAME as TAYLOR

        if name == TAYLOR:
            return self.taylor().function
        if name == BATCH_NAME:
            return self.taylor().batch()[0]
        raise KeyError(f"the system has no function {name!r}")

    def taylor(self):
        """The Taylor coefficients of the solution (``systems.taylor.compiled``): LLVM
        code written from the decomposition of Hamilton's equations on first use (or read
        from the disk cache), kept with the system, whichever backend compiled the rest.

        Returns
        -------
        systems.taylor.compiled.TaylorKernels

        Raises
        ------
        systems.taylor.decompose.NotDecomposable
            With the reason, for a system the taylor family refuses.
        """
        found = self._numeric.get("taylor")
        if found is None:
            from systems.taylor.compiled import load_taylor

            found = self._numeric["taylor"] = load_taylor(self.mechanics)
        return found

    def __job_key__(self) -> str:
        """The scene and the parameter values (``derivation_cache.remembered_job``): what
        a job's answer depends on."""
        from systems import derivation_cache

        values = np.ascontiguousarray(self.parameters, dtype=float).tobytes()
        scene = derivation_cache.scene_key(self.mechanics.scene)
        return f"{scene}:{hashlib.sha256(values).hexdigest()[:32]}"

    def require(self, want: str) -> None:
        if want not in self.wanted:
            raise ValueError(f"{want!r} was not compiled; ask compile_system for it")

    # -- array wrappers ------------------------------------------------------------------

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """dy/dt at one state; ``y`` shape (2n,), returns shape (2n,). With constraints,
        the bilateral ones' force included (no contact acts)."""
        self.require("rhs")
        out = np.empty(2 * self.n)
        y = np.ascontiguousarray(y, dtype=float)
        if constraints.constrained(self.mechanics.scene):
            self.constrained("c_bilateral_rhs", float(t), y, self.parameters, out)
        else:
            self.kernels.rhs(float(t), y, self.parameters, out)
        return out

    def constraint_functions(self) -> tuple:
        """The drivers' ``cs`` for a constrained scene: its ``constraints.PRIMITIVES`` and
        ``constraints.sizes``."""
        key = "constraint functions"
        if key not in self._numeric:
            sizes = constraints.sizes(self.mechanics)
            self._numeric[key] = (*self.functions(constraints.PRIMITIVES), sizes)
        return self._numeric[key]

    def constrained(self, name: str, *args):
        """The drivers' constrained function ``name`` (``c_multipliers``,
        ``c_constraint_values``, ``c_project``, ...) of this scene, called with ``args``
        after its ``cs``."""
        cs = self.constraint_functions()
        key = ("constrained", name)
        if key not in self._numeric:
            self._numeric[key] = entry_point(getattr(driver_module(), name), (cs, *args))
        return self._numeric[key](cs, *args)

    def hamiltonian(self, t: np.ndarray | float, Y: np.ndarray) -> np.ndarray:
        """H at many states; ``Y`` shape (N, 2n), ``t`` scalar or (N,); returns (N,)."""
        self.require("hamiltonian")
        ts, Y = _batch(t, Y, 2 * self.n)
        out = np.empty(len(Y))
        rows = getattr(self.kernels, "rows", {}).get("hamiltonian")
        if rows is None:
            self._batch("batch_scalar", "hamiltonian", ts, Y, out)
            return out
        # several rows at a time in vector registers, the last ones padded to a whole
        # vector: each state's H is the same whatever batch it came in
        lanes = llvm_kernels.vector_target()[1]
        count, width = Y.shape
        whole, P = count - count % lanes, _address(self.parameters)
        if whole:
            rows(_address(ts), _address(Y), width, P, _address(out), whole // lanes)
        if whole < count:
            last_t, last_Y, last = np.empty(lanes), np.empty((lanes, width)), np.empty(lanes)
            last_t[: count - whole], last_t[count - whole :] = ts[whole:], ts[-1]
            last_Y[: count - whole], last_Y[count - whole :] = Y[whole:], Y[-1]
            rows(_address(last_t), _address(last_Y), width, P, _address(last), 1)
            out[whole:] = last[: count - whole]
        return out

    def velocities(self, t: np.ndarray | float, Y: np.ndarray) -> np.ndarray:
        """qdot at many states; ``Y`` shape (N, 2n); returns (N, n)."""
        self.require("velocities")
        ts, Y = _batch(t, Y, 2 * self.n)
        out = np.empty((len(Y), self.n))
        self._batch("batch_vector", "velocities", ts, Y, out)
        return out

    def momenta(self, t: np.ndarray | float, Q: np.ndarray, Qdot: np.ndarray) -> np.ndarray:
        """p from (q, qdot); ``Q``, ``Qdot`` shape (N, n); returns (N, n)."""
        self.require("momenta")
        ts, Q = _batch(t, Q, self.n)
        Qdot = np.ascontiguousarray(np.atleast_2d(Qdot), dtype=float)
        out = np.empty((len(Q), self.n))
        self._batch("batch_pairs", "momenta", ts, Q, Qdot, out)
        return out

    def drawing(self, t: np.ndarray | float, Y: np.ndarray) -> np.ndarray:
        """Mechanism points at many states; ``Y`` shape (N, 2n); returns (N, npoints, 2)."""
        self.require("drawing")
        ts, Y = _batch(t, Y, 2 * self.n)
        out = np.empty((len(Y), len(self.point_names), 2))
        self._batch("batch_vector", "drawing", ts, Y, out)
        return out

    def _batch(self, loop: str, name: str, *arrays: np.ndarray) -> None:
        """``loop`` of the drivers over the rows of ``arrays`` (C-contiguous float arrays,
        the last one written) with the system function ``name``."""
        (function,) = self.functions((name,))
        *inputs, out = arrays
        args = (function, *inputs, self.parameters, out)
        key = ("batch", loop, name)
        if key not in self._numeric:  # the arrays' types never change between calls
            self._numeric[key] = entry_point(getattr(driver_module(), loop), args)
        self._numeric[key](*args)

    # -- initial state -----------------------------------------------------------------------

    def initial_state(self, t0: float = 0.0) -> np.ndarray:
        """The scene's initial state as canonical ``(q, p)``, shape (2n,).

        Missing entries are 0. Velocities are turned into momenta with p = dL/dqdot. A
        scene with constraints has its state moved onto them (``constraints.Numeric``).
        """
        scene = self.mechanics.scene
        values = scene.initial_values
        q = np.array([values.get(name, 0.0) for name in scene.coordinates])
        given_p = {i: values[name] for i, name in enumerate(scene.momentum_names) if name in values}
        qdot = np.array([values.get(name, 0.0) for name in scene.velocity_names])
        if len(given_p) == self.n:
            p = np.array([given_p[i] for i in range(self.n)])
        elif not given_p:
            p = self.momenta_from_velocities(t0, q, qdot)
        else:
            p = self._mixed_momenta(t0, q, qdot, given_p)
        y = np.concatenate([q, p])
        numeric = self.constraints()
        return y if numeric is None else numeric.project(t0, y)

    def constraints(self) -> constraints.Numeric | None:
        """The scene's constraints (every kind) evaluated with numpy (multipliers, violation,
        projection), or None for a scene without constraints."""
        if not constraints.constrained(self.mechanics.scene):
            return None
        if "constraints" not in self._numeric:  # shared with copies of other parameters
            self._numeric["constraints"] = constraints.Numeric(self)
        numeric = self._numeric["constraints"]
        return numeric if numeric.compiled is self else numeric.bound_to(self)

    def _mixed_momenta(self, t0, q, qdot, given_p: dict[int, float]) -> np.ndarray:
        """Momenta when some p_i and the other velocities are given: solve for the rest.

        The velocities of the coordinates whose momentum is given are unknown; they are
        found so that p(q, qdot) matches, which matters where M(q) couples coordinates.
        """
        from scipy.optimize import fsolve

        unknown = sorted(given_p)
        target = np.array([given_p[i] for i in unknown])

        def residual(v: np.ndarray) -> np.ndarray:
            trial = qdot.copy()
            trial[unknown] = v
            return self.momenta_from_velocities(t0, q, trial)[unknown] - target

        solution, _, ok, message = fsolve(residual, target, full_output=True)
        if ok != 1:
            raise DerivationError(f"could not match the given initial momenta: {message}")
        full = qdot.copy()
        full[unknown] = solution
        p = self.momenta_from_velocities(t0, q, full)
        p[unknown] = target
        return p

    def momenta_from_velocities(self, t: float, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
        """p(q, qdot, t) for one state, shape (n,), evaluated with numpy (no compilation)."""
        mech = self.mechanics
        if mech.momenta is not None:
            f = self._lambdified("momenta", (mech.t, mech.q, mech.qdot), mech.momenta)
            return np.array(f(t, q, qdot), dtype=float).reshape(self.n)
        from scipy.optimize import fsolve

        f = self._lambdified("velocities", (mech.t, mech.q, mech.p), mech.velocities)
        solution, _, ok, message = fsolve(
            lambda p: np.array(f(t, q, p), dtype=float) - qdot, qdot, full_output=True
        )
        if ok != 1:
            raise DerivationError(f"could not find momenta for the initial velocities: {message}")
        return solution

    def _lambdified(self, key, args, exprs):
        """``exprs`` as a numpy function ``f(t, a, b)`` of ``args = (t, a_symbols,
        b_symbols)`` at this system's parameter values.

        The parameters are an argument of the function rather than values substituted
        into ``exprs``: substitution made sympy re-derive assumptions, about 80 ms for the
        double pendulum's momenta, on the way to a scene's first block. Made by
        ``calculus.fast_function`` (sympy.lambdify took 0.1 s for a ten-link chain's
        momenta).
        """
        if key not in self._numeric:
            params = tuple(self.mechanics.params[name] for name in self.parameter_names)
            t, first, second = args
            self._numeric[key] = calculus.fast_function(
                (t, *first, *second, *params), [as_expr(e) for e in exprs]
            )
        function = self._numeric[key]
        return lambda t, a, b: function(np.concatenate(([t], a, b, self.parameters)))


def _address(array: np.ndarray) -> int:
    return array.__array_interface__["data"][0]


def _batch(t, Y, width: int) -> tuple[np.ndarray, np.ndarray]:
    Y = np.ascontiguousarray(np.atleast_2d(Y), dtype=float)
    if Y.shape[1] != width:
        raise ValueError(f"states must have {width} columns, got shape {Y.shape}")
    ts = np.ascontiguousarray(np.broadcast_to(np.asarray(t, dtype=float), (len(Y),)))
    return ts, Y


BACKENDS = ("auto", "llvm", "numba")


def default_backend() -> str:
    """``PHASE_EXPLORER_KERNELS`` (``auto``, ``llvm`` or ``numba``), else ``auto``."""
    import os

    return os.environ.get("PHASE_EXPLORER_KERNELS", "auto").strip().lower() or "auto"


def _compiled_again(
    mechanics: Mechanics, wanted: tuple[str, ...], parameters, hidden: tuple[str, ...] = ()
) -> CompiledSystem:
    """A ``CompiledSystem`` unpickled in another process: compiled there again."""
    compiled = compile_system(mechanics, wanted).with_parameters(parameters)
    return compiled.without(*hidden) if hidden else compiled


@dataclass(frozen=True)
class SystemCode:
    """A system's functions as code, before machine code: the symbolic part of a build.

    ``system_code`` writes it (in a worker process, under the build's CPU-time limit,
    or from the disk cache); ``load_system`` turns it into machine code in the process
    that runs the scene.

    Attributes
    ----------
    wanted : frozenset of str
    backend : {"llvm", "numba"}
        LLVM IR text (``systems.llvm_kernels.write_ir``) or the Python source numba
        compiles (``systems.codegen.build_module``).
    text : str
    names : tuple of str
        The functions in ``text`` (LLVM) that the drivers take.
    seconds : float
        Time spent writing ``text`` (or reading it from the cache).
    """

    wanted: frozenset[str]
    backend: str
    text: str
    names: tuple[str, ...] = ()
    seconds: float = 0.0


NAMES_LINE = "; functions: "
"""The first line of a system's LLVM IR text (a comment to LLVM): the names of its
functions, so that a text read from the disk needs no symbolic work (the functions'
specifications took 3 ms of the rolling disk's reopening: its constraints' rows)."""


def system_code(
    mechanics: Mechanics,
    wanted: Iterable[str] = ("rhs", "hamiltonian"),
    *,
    backend: str | None = None,
) -> SystemCode:
    """Write the code of the wanted functions of ``mechanics`` (remembered on disk).

    Parameters
    ----------
    mechanics
        From ``systems.mechanics.derive``.
    wanted
        Names from ``WANTS``. ``"separable"`` adds T(p), V(q, t) and their gradients and is
        only possible when the classification says separable.
    backend : {"auto", "llvm", "numba"}
        How the system's functions become machine code: LLVM IR written from the
        expressions (milliseconds; ``systems.llvm_kernels``), or numba (a tenth of a
        second and more per function). ``"auto"`` takes LLVM wherever it applies
        (everything but an expression node it does not write);
        ``"llvm"`` raises ``llvm_kernels.Unsupported`` where it does not. None: the
        environment's ``PHASE_EXPLORER_KERNELS``, else ``"auto"``.

    Returns
    -------
    SystemCode
    """
    start = time.perf_counter()
    wanted = frozenset(wanted)
    unknown = wanted - WANTS
    if unknown:
        raise ValueError(f"unknown wants {sorted(unknown)}; choose from {sorted(WANTS)}")
    backend = default_backend() if backend is None else backend
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, not {backend!r}")
    if backend != "numba":
        writer = _KernelWriter(mechanics)

        def write() -> str:
            specs = writer.specs(wanted)
            text = llvm_kernels.write_ir(specs, writer.rename)
            names = " ".join(llvm_kernels.written(text, [spec.name for spec in specs]))
            return f"{NAMES_LINE}{names}\n" + text

        try:
            text = _remembered(mechanics, "llvm", wanted, write)
        except llvm_kernels.Unsupported:
            if backend == "llvm":
                raise
        else:
            names = tuple(text[len(NAMES_LINE) : text.index("\n")].split())
            return SystemCode(wanted, "llvm", text, names, time.perf_counter() - start)
    text = _remembered(
        mechanics, "kernel source", wanted, lambda: _KernelWriter(mechanics).source(wanted)
    )
    return SystemCode(wanted, "numba", text, seconds=time.perf_counter() - start)


def load_system(mechanics: Mechanics, code: SystemCode) -> CompiledSystem:
    """Machine code of ``code`` (written by ``system_code`` for this ``mechanics``)."""
    start = time.perf_counter()
    if code.backend == "llvm":
        module = llvm_kernels.LLVMKernels(code.text, code.names)
    else:
        module = build_module(code.text)
    scene = mechanics.scene
    return CompiledSystem(
        mechanics=mechanics,
        kernels=module,
        parameter_names=tuple(name for name, _ in scene.parameters),
        parameters=np.array([value for _, value in scene.parameters], dtype=float),
        wanted=code.wanted,
        point_names=scene.drawing.point_names if scene.drawing else (),
        build_seconds=code.seconds + time.perf_counter() - start,
    )


def compile_system(
    mechanics: Mechanics,
    wanted: Iterable[str] = ("rhs", "hamiltonian"),
    *,
    backend: str | None = None,
) -> CompiledSystem:
    """Write and load the wanted functions of ``mechanics`` in this process: ``system_code``
    then ``load_system`` (which see)."""
    return load_system(mechanics, system_code(mechanics, wanted, backend=backend))


def _remembered(mechanics: Mechanics, kind: str, wanted: frozenset[str], compute) -> str:
    """``compute()``, the code of the system functions ``wanted``, remembered on disk per
    scene; the tag names every module and version the text depends on."""
    import sys

    import llvmlite
    import numba

    from systems import derivation_cache

    code = derivation_cache.code_hash(
        sys.modules[__name__], constraints, llvm_kernels, calculus, matrix_solve
    )
    versions = f"numba {numba.__version__} llvmlite {llvmlite.__version__}"
    if kind == "llvm":
        versions += f" {llvm_kernels.vector_tag()}"
    tag = f"{kind} {code} {versions} {sorted(wanted)}"
    return derivation_cache.remembered(mechanics.scene, tag, compute)


class _KernelWriter:
    def __init__(self, mechanics: Mechanics):
        self.mech = mechanics
        self.scene = mechanics.scene
        self.printer = SympyPrinter()
        names = [
            "t",
            *self.scene.coordinates,
            *self.scene.velocity_names,
            *self.scene.momentum_names,
            *(n for n, _ in self.scene.parameters),
        ]
        self.rename = {
            self.scene.symbols[name]: sympy.Symbol(f"v_{name}", real=True) for name in names
        }

    def source(self, wanted: frozenset[str]) -> str:
        mech, scene = self.mech, self.scene
        parts = []
        state = self.unpack_state()
        if mech.matrix_form is not None and wanted & {"rhs", "hamiltonian", "velocities"}:
            parts.append(matrix_solve.kernel_source())
        if "rhs" in wanted and constraints.constrained(scene):
            parts.append(constraints.kernel_source(self, mech))  # rhs with the multipliers
        elif "rhs" in wanted:
            parts.append(self.function("rhs(t, y, P, out)", state, mech.hamilton_equations))
        if "hamiltonian" in wanted:
            parts.append(self.scalar("hamiltonian(t, y, P)", state, mech.hamiltonian))
        if "velocities" in wanted:
            parts.append(self.function("velocities(t, y, P, out)", state, mech.velocities))
        if "momenta" in wanted:
            self._require_momenta()
            unpack = self.unpack("q", scene.coordinates) + self.unpack("qdot", scene.velocity_names)
            parts.append(self.function("momenta(t, q, qdot, P, out)", unpack, mech.momenta))
        if "lagrangian" in wanted and mech.lagrangian is not None:
            unpack = self.unpack("q", scene.coordinates) + self.unpack("qdot", scene.velocity_names)
            parts.append(self.scalar("lagrangian(t, q, qdot, P)", unpack, mech.lagrangian))
        if "separable" in wanted:
            if mech.separable_parts is None:
                raise DerivationError(
                    "the Hamiltonian is not separable (H != T(p) + V(q))", source=scene.source
                )
            # T(p) and V(q, t) read the whole state y = (q, p): a slice y[n:] handed to a
            # compiled function costs reference counting on every call, which made the
            # leapfrog four times slower
            T, V = mech.separable_parts
            n = mech.n
            pu = [f"v_{name} = y[{n + i}]" for i, name in enumerate(scene.momentum_names)]
            qu = self.unpack("y", scene.coordinates)
            parts.append(self.scalar("kinetic(y, P)", pu, T))
            parts.append(self.scalar("potential(t, y, P)", qu, V))
            gradient = calculus.Calculus(scene.symbols.values()).gradient
            parts.append(self.function("grad_kinetic(y, P, out)", pu, gradient(T, mech.p)))
            parts.append(self.function("grad_potential(t, y, P, out)", qu, gradient(V, mech.q)))
        if "drawing" in wanted:
            exprs = []
            for name, _, _ in scene.drawing.points if scene.drawing else ():
                exprs.append(scene.expression(f"drawing.points.{name}.x"))
                exprs.append(scene.expression(f"drawing.points.{name}.y"))
            parts.append(self.function("drawing(t, y, P, out)", state, exprs, pairs=True))
        return "\n\n".join(parts)

    def specs(self, wanted: frozenset[str]) -> list[llvm_kernels.FunctionSpec]:
        """The wanted functions for ``systems.llvm_kernels``, as ``source`` writes them
        for numba (in matrix form, the functions of the state solve for the velocities
        first; with constraints, ``rhs`` is the constraints' ``PRIMITIVES``)."""
        mech, scene = self.mech, self.scene
        n = mech.n
        Spec = llvm_kernels.FunctionSpec
        state, pairs = self.bindings()
        params = [b for b in state if b[1] == "P"]
        time = [("v_t", "t", None)]
        specs = []
        solve = self._solve_spec()
        velocity_symbols = set(mech.qdot)

        def of_state(name: str, exprs, returns: bool = False) -> None:
            uses = any(as_expr(e).free_symbols & velocity_symbols for e in exprs)
            arguments = ("t", "y", "P") if returns else ("t", "y", "P", "out")
            specs.append(Spec(name, arguments, tuple(state), tuple(exprs), returns=returns,
                              solve=solve if uses else None))  # fmt: skip

        if "rhs" in wanted and constraints.constrained(scene):
            specs += constraints.specs(self, mech)
        elif "rhs" in wanted:
            of_state("rhs", mech.hamilton_equations)
        if "hamiltonian" in wanted:
            of_state("hamiltonian", [mech.hamiltonian], returns=True)
        if "velocities" in wanted:
            of_state("velocities", mech.velocities)
        if "momenta" in wanted:
            self._require_momenta()
            specs.append(Spec("momenta", ("t", "q", "qdot", "P", "out"), tuple(pairs),
                              tuple(mech.momenta)))  # fmt: skip
        if "lagrangian" in wanted and mech.lagrangian is not None:
            specs.append(Spec("lagrangian", ("t", "q", "qdot", "P"), tuple(pairs),
                              (mech.lagrangian,), returns=True))  # fmt: skip
        if "separable" in wanted:
            self._require_separable()
            T, V = mech.separable_parts
            pu = tuple(
                (f"v_{name}", "y", n + i) for i, name in enumerate(scene.momentum_names)
            ) + tuple(params)
            qu = tuple(time + [(f"v_{name}", "y", i) for i, name in enumerate(scene.coordinates)])
            qu += tuple(params)
            gradient = calculus.Calculus(scene.symbols.values()).gradient
            specs.append(Spec("kinetic", ("y", "P"), pu, (T,), returns=True))
            specs.append(Spec("potential", ("t", "y", "P"), qu, (V,), returns=True))
            grad_kinetic = Spec("grad_kinetic", ("y", "P", "out"), pu, tuple(gradient(T, mech.p)))
            grad_potential = Spec(
                "grad_potential", ("t", "y", "P", "out"), qu, tuple(gradient(V, mech.q))
            )
            specs += [grad_kinetic, grad_potential]
            # a composition step's stages with both gradients inline: one call a step
            # (``kernels.composef_step``); the numba backend has no such function
            stages = llvm_kernels.stages_spec(grad_kinetic, grad_potential)
            if stages is not None:
                specs.append(stages)
        if "drawing" in wanted:
            exprs = []
            for name, _, _ in scene.drawing.points if scene.drawing else ():
                exprs.append(scene.expression(f"drawing.points.{name}.x"))
                exprs.append(scene.expression(f"drawing.points.{name}.y"))
            of_state("drawing", exprs)
        return specs

    def _require_momenta(self) -> None:
        if self.mech.momenta is None:
            raise DerivationError(
                "this Hamiltonian has no Lagrangian, so momenta from velocities are not defined",
                source=self.scene.source,
            )

    def _require_separable(self) -> None:
        if self.mech.separable_parts is None:
            raise DerivationError(
                "the Hamiltonian is not separable (H != T(p) + V(q, t))", source=self.scene.source
            )

    def bindings(self) -> tuple[tuple, tuple]:
        """``FunctionSpec.bindings`` of a function of the state (t, y, P) and of one of
        (t, q, qdot, P)."""
        scene = self.scene
        params = [(f"v_{name}", "P", i) for i, (name, _) in enumerate(scene.parameters)]
        time = [("v_t", "t", None)]
        names = (*scene.coordinates, *scene.momentum_names)
        state = time + [(f"v_{name}", "y", i) for i, name in enumerate(names)] + params
        pairs = time + [(f"v_{name}", "q", i) for i, name in enumerate(scene.coordinates)]
        pairs += [(f"v_{name}", "qdot", i) for i, name in enumerate(scene.velocity_names)]
        return tuple(state), tuple(pairs + params)

    def _solve_spec(self) -> tuple | None:
        """``FunctionSpec.solve`` of a system in matrix form, else None."""
        form = self.mech.matrix_form
        if form is None:
            return None
        n = self.mech.n
        upper = [(i, j) for i in range(n) for j in range(i, n)]
        entries = tuple(form.mass_matrix[i, j] for i, j in upper) + tuple(form.shift)
        momenta = tuple(f"v_{name}" for name in self.scene.momentum_names)
        velocities = tuple(f"v_{name}" for name in self.scene.velocity_names)
        return entries, momenta, velocities

    def unpack(self, array: str, names: Sequence[str]) -> list[str]:
        return [f"v_{name} = {array}[{i}]" for i, name in enumerate(names)]

    def unpack_state(self) -> list[str]:
        names = (*self.scene.coordinates, *self.scene.momentum_names)
        return self.unpack("y", names)

    def header(self, signature: str, unpack: list[str]) -> list[str]:
        params = [f"v_{name} = P[{i}]" for i, (name, _) in enumerate(self.scene.parameters)]
        lines = [f"def {signature}:"]
        arguments = [a.strip() for a in signature.split("(", 1)[1].rstrip(")").split(",")]
        if "t" in arguments:
            lines.append("v_t = t")
        return lines + unpack + params

    def body(self, exprs: Sequence[sympy.Expr]) -> tuple[list[str], list[str]]:
        temporaries, reduced = self._reduced(exprs)
        return [f"{name} = {text}" for name, text, _ in temporaries], reduced

    def _reduced(self, exprs: Sequence) -> tuple[list[tuple[str, str, set[str]]], list[str]]:
        """Common-subexpression elimination of ``exprs``, printed: (temporaries as
        (name, source, names of the symbols it uses), sources of the reduced ``exprs``).
        Printed from symengine where ``kernel_printer.engine_text`` can, else through
        sympy."""
        exprs = [as_expr(e) for e in exprs]
        try:
            temporaries, reduced = calculus.engine_cse(exprs, self.rename)
            return (
                [
                    (name, engine_text(e), {str(s) for s in e.free_symbols})
                    for name, e in temporaries
                ],
                [engine_text(e) for e in reduced],
            )
        except (calculus.Unsupported, Unprintable):
            pass
        temporaries, reduced = calculus.cse(exprs, self.rename)
        return (
            [
                (str(symbol), self.printer.doprint(e), {str(s) for s in e.free_symbols})
                for symbol, e in temporaries
            ],
            [self.printer.doprint(e) for e in reduced],
        )

    def solved_body(self, exprs: Sequence[sympy.Expr]) -> tuple[list[str], list[str]]:
        """``body`` for a system in matrix form: the velocities in ``exprs`` are solved
        from ``M(q, t) qdot = p - a(q, t)`` first (``systems.matrix_solve``).

        One common-subexpression pass covers M, a and ``exprs``; the temporaries free of
        velocities go before the solve, the others after it. The solve's array is
        ``W_v``, a name no other function's argument takes (the constrained ``c_saddle``
        fills its own ``W`` after these lines).
        """
        form = self.mech.matrix_form
        qd = set(self.mech.qdot)
        if form is None or not any(as_expr(e).free_symbols & qd for e in exprs):
            return self.body(exprs)
        n = self.mech.n
        upper = [(i, j) for i in range(n) for j in range(i, n)]
        entries = [form.mass_matrix[i, j] for i, j in upper] + list(form.shift)
        temporaries, printed = self._reduced([*entries, *exprs])
        velocity_names = {self.rename[v].name for v in qd}
        before, after = [], []
        for name, text, uses in temporaries:
            if uses & velocity_names:
                velocity_names.add(name)
                after.append(f"{name} = {text}")
            else:
                before.append(f"{name} = {text}")
        lines = [*before, f"W_v = np.empty(({n}, {n + 2}))"]
        for (i, j), value in zip(upper, printed, strict=False):
            lines.append(f"W_v[{i}, {j}] = {value}")
            lines.append(
                f"W_v[{j}, {i}] = W_v[{i}, {j}]" if i != j else f"W_v[{i}, {n + 1}] = W_v[{i}, {i}]"
            )
        for i, (name, value) in enumerate(
            zip(self.scene.momentum_names, printed[len(upper) :], strict=False)
        ):
            lines.append(f"W_v[{i}, {n}] = v_{name} - ({value})")
        lines.append(f"solve_augmented(W_v, {n})")
        lines += [f"v_{name} = W_v[{i}, {n}]" for i, name in enumerate(self.scene.velocity_names)]
        return lines + after, printed[len(entries) :]

    def _body_for(self, signature: str, exprs) -> tuple[list[str], list[str]]:
        """Functions of the state y = (q, p) solve for the velocities of a system in
        matrix form; functions given (q, qdot) (momenta, the Lagrangian) take them as is."""
        if "qdot" in signature:
            return self.body(exprs)
        return self.solved_body(exprs)

    def function(self, signature, unpack, exprs, pairs=False) -> str:
        lines = self.header(signature, unpack)
        temps, values = self._body_for(signature, exprs)
        lines += temps
        for i, value in enumerate(values):
            target = f"out[{i // 2}, {i % 2}]" if pairs else f"out[{i}]"
            lines.append(f"{target} = {value}")
        return _indent(lines)

    def scalar(self, signature, unpack, expr) -> str:
        lines = self.header(signature, unpack)
        temps, values = self._body_for(signature, [expr])
        return _indent(lines + temps + [f"return {values[0]}"])


def _indent(lines: list[str]) -> str:
    return lines[0] + "\n" + "\n".join("    " + line for line in lines[1:]) + "\n"
