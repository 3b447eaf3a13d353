"""A scene's system functions as machine code in milliseconds: LLVM IR written from
symengine's common-subexpression elimination and compiled by llvmlite (numba's own
dependency).

numba needs a tenth of a second and more per function however small (its type
inference and lowering pipeline), and seconds for a ten-link chain's straight-line
code; the same functions written as LLVM IR and optimised by LLVM alone take
milliseconds. They have the calling convention numba uses for a first-class function's
C wrapper (each argument's LLVM value type, arrays as numba's array structure by value),
so the drivers, compiled once (``systems.codegen.driver_module``), call them exactly as
they call numba-compiled ones (``systems.codegen.function_value``: numba's
wrapper-address protocol).

Only what the scene language produces is written: numbers, symbols, sums, products,
powers and the functions of ``INTRINSICS`` and ``LIBM``; anything else raises
``Unsupported`` and ``systems.compiled`` compiles the scene's functions with numba
instead. The only loops written are H over rows in vector registers (``_RowsWriter``)
and a composition step's stages with both separable gradients inline
(``_StagesWriter``, ``compose_stages``: one call a step of the drivers'
``composef_step``, bitwise ``compose_step``'s two calls a stage): a
system in matrix form calls the drivers' ``solve_augmented`` (``FunctionSpec.solve``),
and a constrained scene's multipliers, projections and impacts are the drivers' own,
given its straight-line ``PRIMITIVES`` (``systems.constraints``).
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import functools
import signal
import threading
from collections.abc import Sequence
from dataclasses import dataclass

try:
    import symengine
except ImportError:  # pragma: no cover - a dependency
    symengine = None

INTRINSICS = {
    "sin": "llvm.sin.f64",
    "cos": "llvm.cos.f64",
    "log": "llvm.log.f64",
    "Abs": "llvm.fabs.f64",
}
LIBM = ("tan", "sinh", "cosh", "tanh", "asin", "acos", "atan", "atan2")
"""symengine's function types written as calls of C's math library (``atan2`` takes
two arguments)."""


class Unsupported(Exception):
    """An expression or a system this writer does not take: numba compiles it instead."""


@dataclass(frozen=True)
class FunctionSpec:
    """One system function to write.

    Attributes
    ----------
    name : str
        A key of ``systems.codegen.SIGNATURES`` (which gives the argument types).
    arguments : tuple of str
        The argument names, in order (``("t", "y", "P", "out")``).
    bindings : tuple of (str, str, int or None)
        (symbol name, argument, index): the symbol is ``argument[index]``, or the
        scalar argument itself where the index is None.
    exprs : sequence of sympy expressions
    returns : bool
        Return ``exprs[0]`` (a scalar function); otherwise ``out.flat[i] = exprs[i]``.
    solve : (entries, momenta, velocities) or None
        A system in matrix form: the velocity symbols ``velocities`` (n names) are the
        solution of ``M qdot = p - a`` (``systems.matrix_solve.solve_augmented``), with
        ``entries`` the upper triangle of M row by row and then a (expressions free of
        the velocities), ``momenta`` the names of the symbols of p.
    targets : tuple of index tuples, optional
        Where each expression goes in ``out``: ``(i,)`` or ``(i, j)`` (by the array's
        strides); by default ``out[i] = exprs[i]``.
    pre : (names, exprs, solve) or None
        Symbols set before ``exprs`` are written, each to its expression (a CSE of their
        own; with ``solve``, by the velocity solve instead).
    parts : tuple of FunctionSpec
        ``compose_stages`` (``STAGES``): the specs of ``grad_kinetic`` and
        ``grad_potential`` it writes inline (``_StagesWriter``).
    """

    name: str
    arguments: tuple[str, ...]
    bindings: tuple[tuple[str, str, int | None], ...]
    exprs: tuple
    returns: bool = False
    solve: tuple | None = None
    targets: tuple | None = None
    pre: tuple | None = None
    parts: tuple = ()


@functools.cache
def _llvm():
    """llvmlite's binding, initialised, with C's math library loaded into the process."""
    import llvmlite.binding as llvm

    llvm.initialize_native_target()
    llvm.initialize_native_asmprinter()
    path = _library("libm.so.6", "m")
    if path:
        llvm.load_library_permanently(path)
    return llvm


def _library(soname: str, name: str) -> str | None:
    """``soname`` if the dynamic loader finds it (glibc's names on Linux), else
    ``ctypes.util.find_library(name)``, which runs ``ldconfig`` (1-3 ms a process)."""
    try:
        ctypes.CDLL(soname)
    except OSError:
        return ctypes.util.find_library(name)
    return soname


def _target_machine(host: bool = False):
    """A new target machine: an execution engine owns (and frees) the one it is given.
    ``host``: for this CPU and its features (FMA, AVX), not a generic x86-64 one."""
    llvm = _llvm()
    target = llvm.Target.from_default_triple()
    if not host:
        return target.create_target_machine(opt=3, jit=True)
    return target.create_target_machine(
        cpu=llvm.get_host_cpu_name(),
        features=llvm.get_host_cpu_features().flatten(),
        opt=3,
        jit=True,
    )


@functools.cache
def _signature(name: str):
    """numba's signature of the system function ``name`` (``codegen.SIGNATURES``)."""
    from numba.core import sigutils

    from systems.codegen import SIGNATURES

    args, result = sigutils.normalize_signature(SIGNATURES[name])
    from numba.core.typing import signature

    return signature(result, *args)


def _value_type(numba_type):
    from numba.core.datamodel import default_manager

    return default_manager.lookup(numba_type).get_value_type()


class _Writer:
    """Writes the IR of one function with llvmlite's IR builder."""

    def __init__(self, module, spec: FunctionSpec, rename: dict, symbol: str | None = None):
        """``symbol``: the function's name in the module, if not ``spec.name`` (whose
        signature it has)."""
        from llvmlite import ir

        self.ir = ir
        self.module = module
        self.spec = spec
        self.rename = rename
        self.double = ir.DoubleType()
        sig = _signature(spec.name)
        argument_types = [_value_type(a) for a in sig.args]
        self.result_type = _value_type(sig.return_type)
        function_type = ir.FunctionType(self.result_type, argument_types)
        self.function = ir.Function(module, function_type, name=symbol or spec.name)
        block = self.function.append_basic_block("entry")
        self.b = ir.IRBuilder(block)
        self.names: dict[str, object] = {}  # symbols and temporaries by name
        self.memo: dict = {}  # expression nodes of the current CSE
        self.calls: set[str] = set()  # the functions called
        self.data: dict[str, object] = {}
        self.rows: dict[str, object] = {}  # a 2-D array's row length, in elements
        self.scalars: dict[str, object] = {}
        i64 = ir.IntType(64)
        for name, argument, numba_type in zip(
            spec.arguments, self.function.args, sig.args, strict=True
        ):
            argument.name = name
            if hasattr(numba_type, "ndim"):
                self.data[name] = self.b.extract_value(argument, 4, name=f"{name}_data")
                if numba_type.ndim == 2:
                    stride = self.b.extract_value(argument, [6, 0])
                    self.rows[name] = self.b.sdiv(stride, ir.Constant(i64, 8))
            else:
                self.scalars[name] = argument

    def write(self) -> None:
        spec = self.spec
        ir = self.ir
        i64 = ir.IntType(64)
        for symbol, argument, index in spec.bindings:
            if index is None:
                value = self.scalars[argument]
            else:
                pointer = self.b.gep(self.data[argument], [ir.Constant(i64, index)])
                value = self.b.load(pointer, name=symbol)
            self.names[symbol] = value
        if spec.pre is not None:
            names, exprs, solve = spec.pre
            if solve is not None:  # the solve itself binds the velocity symbols
                self._phase((), solve)
            else:
                for name, value in zip(names, self._phase(exprs, None), strict=True):
                    self.names[name] = value
        results = self._phase(spec.exprs, spec.solve)
        if spec.returns:
            self.b.ret(results[0])
            return
        argument = spec.arguments[-1]
        out = self.data[argument]
        targets = spec.targets or [(i,) for i in range(len(results))]
        for target, value in zip(targets, results, strict=True):
            if len(target) == 1:
                index = ir.Constant(i64, target[0])
            else:
                row = self.b.mul(ir.Constant(i64, target[0]), self.rows[argument])
                index = self.b.add(row, ir.Constant(i64, target[1]))
            self.b.store(value, self.b.gep(out, [index]))
        self.b.ret(ir.Constant(self.result_type, None))

    def _phase(self, exprs, solve) -> list:
        """One common-subexpression elimination of ``exprs`` (after the velocity solve's
        entries, with ``solve``), written; returns the values of ``exprs``."""
        from systems.calculus import Unsupported as CalculusUnsupported
        from systems.calculus import engine_cse

        self.memo = {}  # the temporaries' names are reused by each elimination
        entries = () if solve is None else tuple(solve[0])
        try:
            temporaries, reduced = engine_cse([*entries, *exprs], self.rename)
        except CalculusUnsupported as exc:
            raise Unsupported(str(exc)) from None
        if solve is not None:
            temporaries = self._solve(temporaries, reduced[: len(entries)], solve)
            reduced = reduced[len(entries) :]
        for name, expr in temporaries:
            self.names[name] = self.value(expr)
        return [self.value(expr) for expr in reduced]

    def _solve(self, temporaries: list, entries: list, solve: tuple) -> list:
        """Write the temporaries free of the velocities, fill ``W = [M | p - a | diag M]``,
        solve it (``solve_augmented`` of the drivers, through its C wrapper) and bind the
        velocity symbols; returns the temporaries left, those that use the velocities,
        as ``systems.compiled._KernelWriter.solved_body`` orders them."""
        ir, b = self.ir, self.b
        _, momenta, velocities = solve
        n = len(velocities)
        pending = set(velocities)
        after = []
        for name, expr in temporaries:
            if {str(s) for s in expr.free_symbols} & pending:
                pending.add(name)
                after.append((name, expr))
            else:
                self.names[name] = self.value(expr)
        width = n + 2
        i64 = ir.IntType(64)
        with b.goto_entry_block():
            W = b.alloca(self.double, size=ir.Constant(i64, n * width), name="W")

        def cell(i: int, j: int):
            return b.gep(W, [ir.Constant(i64, i * width + j)])

        upper = [(i, j) for i in range(n) for j in range(i, n)]
        for (i, j), expr in zip(upper, entries, strict=False):
            value = self.value(expr)
            b.store(value, cell(i, j))
            b.store(value, cell(j, i) if i != j else cell(i, n + 1))
        for i, (p, expr) in enumerate(zip(momenta, entries[len(upper) :], strict=True)):
            b.store(b.fsub(self.names[p], self.value(expr)), cell(i, n))
        self._call_solver(W, n)
        for i, name in enumerate(velocities):
            self.names[name] = b.load(cell(i, n), name=name)
        return after

    def _call_solver(self, W, n: int) -> None:
        """``solve_augmented(W, n)`` through the C wrapper of the drivers' copy, an
        external symbol (``SOLVER_SYMBOL``) that ``LLVMKernels`` binds to its address in
        the process that loads the code: its arguments are numba's value types, the array
        as its structure by value."""
        ir, b = self.ir, self.b
        i64, i8p = ir.IntType(64), ir.IntType(8).as_pointer()
        argument_types, result_type = _solver_types()
        structure = argument_types[0]
        value = ir.Constant(structure, ir.Undefined)
        parts = [
            ir.Constant(i8p, None),
            ir.Constant(i8p, None),
            ir.Constant(i64, n * (n + 2)),
            ir.Constant(i64, 8),
            W,
            ir.Constant(ir.ArrayType(i64, 2), [ir.Constant(i64, n), ir.Constant(i64, n + 2)]),
            ir.Constant(ir.ArrayType(i64, 2), [ir.Constant(i64, 8 * (n + 2)), ir.Constant(i64, 8)]),
        ]
        for k, part in enumerate(parts):
            value = b.insert_value(value, part, k)
        function = self.module.globals.get(SOLVER_SYMBOL)
        if function is None:
            function_type = ir.FunctionType(result_type, argument_types)
            function = ir.Function(self.module, function_type, name=SOLVER_SYMBOL)
        b.call(function, [value, ir.Constant(i64, n)])

    # -- expressions ----------------------------------------------------------------------

    def const(self, value: float):
        return self.ir.Constant(self.double, float(value))

    def value(self, expr):
        """The IR value of a symengine expression (each distinct node once)."""
        try:
            return self.memo[expr]
        except (KeyError, TypeError):
            pass
        try:
            value = self._node(expr)
        except RecursionError:
            raise Unsupported("nested too deeply") from None
        self.memo[expr] = value
        return value

    def _node(self, expr):
        if isinstance(expr, symengine.Integer):
            return self.const(float(int(expr)))
        if isinstance(expr, symengine.Rational):
            p, q = expr.get_num_den()
            return self.const(float(int(p)) / float(int(q)))
        if isinstance(expr, symengine.RealDouble):
            return self.const(float(expr))
        if isinstance(expr, symengine.Symbol):
            found = self.names.get(str(expr))
            if found is None:
                raise Unsupported(f"unknown symbol {expr}")
            return found
        kind = type(expr).__name__
        b = self.b
        if kind == "Add":
            values = [self.value(a) for a in expr.args]
            total = values[0]
            for v in values[1:]:
                total = b.fadd(total, v)
            return total
        if kind == "Mul":
            values = [self.value(a) for a in expr.args]
            total = values[0]
            for v in values[1:]:
                total = b.fmul(total, v)
            return total
        if kind == "Pow":
            return self._power(*expr.args)
        if kind == "Pi":
            return self.const(3.141592653589793)
        if kind == "Exp1":
            return self.const(2.718281828459045)
        if kind == "sign":
            x = self.value(expr.args[0])
            unit = self._call("llvm.copysign.f64", [self.const(1.0), x])
            return b.select(b.fcmp_ordered("==", x, self.const(0.0)), self.const(0.0), unit)
        if kind in INTRINSICS:
            return self._call(INTRINSICS[kind], [self.value(a) for a in expr.args])
        if kind in LIBM:
            return self._call(kind, [self.value(a) for a in expr.args])
        raise Unsupported(f"no machine code for {kind}")

    def _power(self, base, exponent):
        b = self.b
        if type(base).__name__ == "Exp1":
            return self._call("llvm.exp.f64", [self.value(exponent)])
        if isinstance(exponent, symengine.Integer):
            k = int(exponent)
            if 2 <= abs(k) <= 4:
                x = self.value(base)
                product = x
                for _ in range(abs(k) - 1):
                    product = b.fmul(product, x)
                return product if k > 0 else b.fdiv(self.const(1.0), product)
            if k == -1:
                return b.fdiv(self.const(1.0), self.value(base))
        if isinstance(exponent, symengine.Rational) and not isinstance(exponent, symengine.Integer):
            p, q = (int(v) for v in exponent.get_num_den())
            if (p, q) == (1, 2):
                return self._call("llvm.sqrt.f64", [self.value(base)])
            if (p, q) == (-1, 2):
                root = self._call("llvm.sqrt.f64", [self.value(base)])
                return b.fdiv(self.const(1.0), root)
        return self._call("llvm.pow.f64", [self.value(base), self.value(exponent)])

    def _call(self, name: str, args: list):
        self.calls.add(name)
        function = self.module.globals.get(name)
        if function is None:
            ir = self.ir
            function_type = ir.FunctionType(self.double, [self.double] * len(args))
            function = ir.Function(self.module, function_type, name=name)
        return self.b.call(function, args)


STAGES = "compose_stages"
"""A composition step's stages with the separable gradients inline (``_StagesWriter``)."""
STAGES_MAX_INSTRUCTIONS = 200
"""``compose_stages`` is written only where ``grad_kinetic`` and ``grad_potential`` have
at most this many instructions together: where a call's 4-5 ns is a part of a stage
that counts. Measured (yoshida4 steps, fused against two calls a stage): the simple
pendulum (37 instructions) 62 against 92 ns, an FPU chain of 8 (155) 76 against 120, of
16 (299) 159 against 171, of 32 (about 600) 330 against 265, slower; the fused function
doubled the 32-chain's compile (56 -> 108 ms)."""
STAGES_ARGUMENTS = ("t", "h", "y", "comp", "P", "F", "G", "kick", "drift", "ns", "kahan")
STAGES_ARRAYS = ("y", "comp", "P", "F", "G", "kick", "drift")
"""``compose_stages``' arrays, passed as the addresses of their first doubles: seven of
numba's array structures by value were 392 bytes copied a call, more than the leapfrog
step saved by calling once."""


def stages_spec(grad_kinetic: FunctionSpec, grad_potential: FunctionSpec) -> FunctionSpec | None:
    """The spec of ``compose_stages`` with these gradients written inline; None where one
    solves for the velocities first or sets symbols of its own (not a separable system's)."""
    parts = (grad_kinetic, grad_potential)
    if any(part.solve is not None or part.pre is not None for part in parts):
        return None
    return FunctionSpec(STAGES, STAGES_ARGUMENTS, (), (), parts=parts)


class _StagesWriter(_Writer):
    """Writes ``compose_stages(t, h, y, comp, P, F, G, kick, drift, ns, kahan)`` (the
    arrays as the addresses of their data, C-contiguous doubles; ``ns = len(drift)``):
    the loop ``for j in range(ns + 1)`` of ``systems.integrators.kernels.compose_step``
    (kick p with F, drift q with G = dT/dp, tau += a, F = dV/dq at tau), in place on ``y``,
    ``comp`` (Kahan terms where ``kahan`` is not 0), ``F`` and ``G``: the same operations
    in the same order as the numba-compiled step calling ``grad_kinetic`` and
    ``grad_potential`` (whose specs are ``spec.parts``, each written with its own
    common-subexpression elimination), so the results are bitwise that step's. The
    drivers call it once a step (``composef_step``) instead of two functions a stage."""

    def write(self) -> None:
        ir, b = self.ir, self.b
        i64 = ir.IntType(64)
        kinetic, potential = self.spec.parts
        n = len(kinetic.exprs)
        if len(potential.exprs) != n:
            raise Unsupported("the gradients of T and V differ in length")
        h, kahan, stages = self.scalars["h"], self.scalars["kahan"], self.scalars["ns"]
        pointer = self.double.as_pointer()
        for name in STAGES_ARRAYS:
            self.data[name] = b.inttoptr(self.scalars[name], pointer, name=f"{name}_data")
        F, G = self.data["F"], self.data["G"]
        kick, drift = self.data["kick"], self.data["drift"]
        compensated = b.icmp_signed("!=", kahan, ir.Constant(i64, 0), name="compensated")
        # the parameters, read once: the drivers never pass P as one of the other arrays
        parameters = {}
        for symbol, argument, index in (*kinetic.bindings, *potential.bindings):
            if argument == "P" and symbol not in parameters:
                pointer = b.gep(self.data["P"], [ir.Constant(i64, index)])
                parameters[symbol] = b.load(pointer, name=symbol)
        entry = b.block
        loop = self.function.append_basic_block("stage")
        drifting = self.function.append_basic_block("drift")
        done = self.function.append_basic_block("done")
        b.branch(loop)
        b.position_at_end(loop)
        j = b.phi(i64, name="j")
        tau = b.phi(self.double, name="tau")
        # a = kick[j] * h; y[n + k] += -a * F[k]
        a = b.fmul(b.load(b.gep(kick, [j])), h, name="a")
        minus_a = b.fneg(a)
        self._adds(compensated, [n + k for k in range(n)],
                   lambda k: b.fmul(minus_a, b.load(b.gep(F, [ir.Constant(i64, k)]))))  # fmt: skip
        b.cbranch(b.icmp_signed("<", j, stages), drifting, done)
        b.position_at_end(drifting)
        # a = drift[j] * h; G = dT/dp; y[k] += a * G[k]; tau += a; F = dV/dq(tau)
        a = b.fmul(b.load(b.gep(drift, [j])), h, name="a")
        velocities = self._gradient(kinetic, G, parameters, None)
        self._adds(compensated, list(range(n)), lambda k: b.fmul(a, velocities[k]))
        later = b.fadd(tau, a, name="tau")
        self._gradient(potential, F, parameters, later)
        following = b.add(j, ir.Constant(i64, 1))
        last = b.block
        b.branch(loop)
        j.add_incoming(ir.Constant(i64, 0), entry)
        j.add_incoming(following, last)
        tau.add_incoming(self.scalars["t"], entry)
        tau.add_incoming(later, last)
        b.position_at_end(done)
        b.ret(ir.Constant(self.result_type, None))

    def _adds(self, compensated, indices: list, increment) -> None:
        """``_add(y, comp, i, increment(k), kahan)`` of the kernels for each index ``i =
        indices[k]`` in order: Kahan-compensated in one branch, plain in the other."""
        ir, b = self.ir, self.b
        i64 = ir.IntType(64)
        y, comp = self.data["y"], self.data["comp"]
        with b.if_else(compensated) as (kahan, plain):
            with kahan:
                for k, i in enumerate(indices):
                    d = increment(k)
                    x, c = b.gep(y, [ir.Constant(i64, i)]), b.gep(comp, [ir.Constant(i64, i)])
                    dd = b.fsub(d, b.load(c))
                    s = b.fadd(b.load(x), dd)
                    b.store(b.fsub(b.fsub(s, b.load(x)), dd), c)
                    b.store(s, x)
            with plain:
                for k, i in enumerate(indices):
                    d = increment(k)
                    x = b.gep(y, [ir.Constant(i64, i)])
                    b.store(b.fadd(b.load(x), d), x)

    def _gradient(self, spec: FunctionSpec, out, parameters: dict, t) -> list:
        """``spec``'s values (a gradient of T or V) at the state in ``y`` now and the time
        ``t``, stored into ``out``; returns them."""
        ir, b = self.ir, self.b
        i64 = ir.IntType(64)
        self.names = {}
        for symbol, argument, index in spec.bindings:
            if argument == "P":
                self.names[symbol] = parameters[symbol]
            elif index is None:
                self.names[symbol] = t
            else:
                pointer = b.gep(self.data["y"], [ir.Constant(i64, index)])
                self.names[symbol] = b.load(pointer, name=symbol)
        values = self._phase(spec.exprs, None)
        for i, value in enumerate(values):
            b.store(value, b.gep(out, [ir.Constant(i64, i)]))
        return values


ROWS_PREFIX = "pe_rows_"
"""``pe_rows_<name>``: a scalar function (``hamiltonian``) over rows, several at a time."""
ROWS_NAMES = ("hamiltonian",)
"""The functions written over rows too, where they have no velocity solve: H at every
row of ``run``'s output, its energy check (0.31 ms of 10 001 rows on the double
pendulum, most of it three cosines a row)."""
_VECTOR_OPS = ("fabs", "sqrt", "copysign")
"""LLVM intrinsics that are single instructions on vectors; the other functions are
glibc's vector math library (``libmvec``) where it has them, else one call a lane."""


@functools.cache
def _vector_library() -> frozenset[str] | None:
    """The names of glibc's vector math library (``libmvec``), loaded into the process
    for the machine code; None where there is none (the rows are then not written)."""
    path = _library("libmvec.so.1", "mvec")
    if not path:
        return None
    try:
        library = ctypes.CDLL(path)
    except OSError:
        return None
    _llvm().load_library_permanently(path)
    names = [*INTRINSICS, "exp", "pow", *LIBM]
    letter, lanes = vector_target()[:2]
    return frozenset(name for name in names if hasattr(library, _vector_name(letter, lanes, name)))


_ROWS_TYPE = ctypes.CFUNCTYPE(
    None,
    ctypes.c_void_p,
    ctypes.c_void_p,
    ctypes.c_int64,
    ctypes.c_void_p,
    ctypes.c_void_p,
    ctypes.c_int64,
)


def _base_name(name: str) -> str:
    """``cos`` of ``llvm.cos.f64``; a C function's name as it is."""
    return name[len("llvm.") : -len(".f64")] if name.startswith("llvm.") else name


def _vector_name(letter: str, lanes: int, name: str) -> str:
    """libmvec's symbol (the x86-64 vector ABI's mangling) for ``lanes`` lanes."""
    arguments = "vv" if name in ("pow", "atan2") else "v"
    return f"_ZGV{letter}N{lanes}{arguments}_{name}"


@functools.cache
def vector_target() -> tuple[str, int, str, str]:
    """(vector ABI letter, lanes, CPU, features) of the rows functions: eight lanes with
    AVX-512, four with AVX2, else two (SSE). The CPU and features become the function's
    own (the rest of the module is compiled for a generic x86-64): libmvec's wide
    variants take their arguments in the wide registers."""
    llvm = _llvm()
    features = llvm.get_host_cpu_features().flatten()
    enabled = set(features.split(","))
    letter, lanes = (
        ("e", 8) if "+avx512f" in enabled else ("d", 4) if "+avx2" in enabled else ("b", 2)
    )
    return letter, lanes, llvm.get_host_cpu_name(), features


def vector_tag() -> str:
    """What the written rows functions depend on beyond the expressions (for the key of
    the remembered IR text)."""
    library = _vector_library()
    if library is None:
        return "no rows"
    return f"rows {vector_target()} {sorted(library)}"


class _RowsWriter(_Writer):
    """Writes ``pe_rows_<name>(ts, Y, width, P, out, blocks)`` of a scalar function
    ``name(t, y, P)``: ``out[i] = name(ts[i], Y[i], P)`` for the first ``blocks * lanes``
    rows of ``Y`` (``width`` doubles each), ``lanes`` rows at a time in vector registers,
    with C's calling convention (pointers to the arrays' first doubles)."""

    def __init__(self, module, spec: FunctionSpec, rename: dict, library: frozenset[str]):
        from llvmlite import ir

        self.ir = ir
        self.module = module
        self.spec = spec
        self.rename = rename
        self.library = library
        self.letter, self.lanes, cpu, features = vector_target()
        self.scalar = ir.DoubleType()
        self.double = ir.VectorType(self.scalar, self.lanes)
        pointer, i64 = self.scalar.as_pointer(), ir.IntType(64)
        function_type = ir.FunctionType(
            ir.VoidType(), [pointer, pointer, i64, pointer, pointer, i64]
        )
        self.function = ir.Function(module, function_type, name=ROWS_PREFIX + spec.name)
        for argument, name in zip(
            self.function.args, ("ts", "Y", "width", "P", "out", "blocks"), strict=True
        ):
            argument.name = name
        # llvmlite's attribute set takes only enum attributes: these are string ones
        set.add(self.function.attributes, f'"target-cpu"="{cpu}"')
        set.add(self.function.attributes, f'"target-features"="{features}"')
        self.names: dict[str, object] = {}
        self.memo: dict = {}

    def write(self) -> None:
        ir, spec = self.ir, self.spec
        i64 = ir.IntType(64)
        ts, Y, width, P, out, blocks = self.function.args
        entry = self.function.append_basic_block("entry")
        loop = self.function.append_basic_block("loop")
        done = self.function.append_basic_block("done")
        b = self.b = ir.IRBuilder(entry)
        splat: dict[str, object] = {}
        for symbol, argument, index in spec.bindings:
            if argument == "P":
                value = b.load(b.gep(P, [ir.Constant(i64, index)]))
                splat[symbol] = self._splat(value)
        b.cbranch(b.icmp_signed(">", blocks, ir.Constant(i64, 0)), loop, done)
        b.position_at_end(loop)
        block = b.phi(i64, name="block")
        first = b.mul(block, ir.Constant(i64, self.lanes), name="first")
        vector_pointer = self.double.as_pointer()
        for symbol, argument, index in spec.bindings:
            if argument == "P":
                self.names[symbol] = splat[symbol]
            elif index is None:  # the time: one per row
                pointer = b.bitcast(b.gep(ts, [first]), vector_pointer)
                self.names[symbol] = b.load(pointer, align=8, name=symbol)
            else:  # a state variable: column ``index`` of the rows
                value = ir.Constant(self.double, ir.Undefined)
                for lane in range(self.lanes):
                    row = b.add(first, ir.Constant(i64, lane))
                    at = b.add(b.mul(row, width), ir.Constant(i64, index))
                    element = b.load(b.gep(Y, [at]))
                    value = b.insert_element(value, element, ir.Constant(i64, lane))
                self.names[symbol] = value
        if spec.pre is not None:
            names, exprs, _ = spec.pre
            for name, value in zip(names, self._phase(exprs, None), strict=True):
                self.names[name] = value
        (result,) = self._phase(spec.exprs, None)
        b.store(result, b.bitcast(b.gep(out, [first]), vector_pointer), align=8)
        following = b.add(block, ir.Constant(i64, 1))
        block.add_incoming(ir.Constant(i64, 0), entry)
        block.add_incoming(following, loop)
        b.cbranch(b.icmp_signed("<", following, blocks), loop, done)
        b.position_at_end(done)
        b.ret_void()

    def const(self, value: float):
        return self.ir.Constant(self.double, [float(value)] * self.lanes)

    def _splat(self, value):
        ir, b = self.ir, self.b
        i64 = ir.IntType(64)
        one = b.insert_element(ir.Constant(self.double, ir.Undefined), value, ir.Constant(i64, 0))
        zeros = ir.Constant(ir.VectorType(ir.IntType(32), self.lanes), [0] * self.lanes)
        return b.shuffle_vector(one, ir.Constant(self.double, ir.Undefined), zeros)

    def _call(self, name: str, args: list):
        ir, b = self.ir, self.b
        base = _base_name(name)
        if base in _VECTOR_OPS:
            symbol = f"llvm.{base}.v{self.lanes}f64"
        elif base in self.library:
            symbol = _vector_name(self.letter, self.lanes, base)
        else:  # one call of the scalar function a lane
            function = self._declare(name, self.scalar, len(args))
            i64 = ir.IntType(64)
            vector = ir.Constant(self.double, ir.Undefined)
            for lane in range(self.lanes):
                index = ir.Constant(i64, lane)
                value = b.call(function, [b.extract_element(a, index) for a in args])
                vector = b.insert_element(vector, value, index)
            return vector
        return b.call(self._declare(symbol, self.double, len(args)), args)

    def _declare(self, name: str, kind, count: int):
        function = self.module.globals.get(name)
        if function is None:
            function_type = self.ir.FunctionType(kind, [kind] * count)
            function = self.ir.Function(self.module, function_type, name=name)
        return function


SOLVER_SIGNATURE = "void(float64[:, ::1], int64)"
SOLVER_SYMBOL = "pe_solve_augmented"
"""The name under which the written IR calls the drivers' ``solve_augmented``: the IR
text holds no address, so it can be written in a worker process and kept on disk."""


def _solver_types() -> tuple[list, object]:
    """(LLVM argument types, LLVM result type) of the C wrapper of ``solve_augmented``."""
    from numba.core import sigutils

    args, result = sigutils.normalize_signature(SOLVER_SIGNATURE)
    return [_value_type(a) for a in args], _value_type(result)


@functools.cache
def _bind_solver() -> None:
    """Bind ``SOLVER_SYMBOL`` in this process to the C wrapper of the drivers'
    ``solve_augmented`` (compiled once per installation, loaded from numba's cache)."""
    from numba.core import sigutils

    from systems.codegen import driver_module

    dispatcher = getattr(driver_module(), "solve_augmented", None)
    if dispatcher is None:
        raise Unsupported("the drivers have no solve_augmented")
    dispatcher.compile(SOLVER_SIGNATURE)
    args, _ = sigutils.normalize_signature(SOLVER_SIGNATURE)
    compiled = dispatcher.overloads[tuple(args)]
    address = compiled.library.get_pointer_to_function(compiled.fndesc.llvm_cfunc_wrapper_name)
    _llvm().add_symbol(SOLVER_SYMBOL, address)


def write_ir(specs: Sequence[FunctionSpec], rename: dict) -> str:
    """The LLVM IR of the system functions ``specs``, as text (no address in it).

    This is the symbolic part of compiling a system (symengine's common-subexpression
    elimination, then the IR builder): it may run in a worker process, and its text can
    be kept on disk. ``LLVMKernels`` turns it into machine code.

    Raises
    ------
    Unsupported
        An expression this writer does not take.
    """
    if symengine is None:
        raise Unsupported("symengine is not installed")
    from llvmlite import ir

    module = ir.Module(name="pe_system")
    calls = {}
    for spec in specs:
        if spec.name == STAGES and not _small(module, spec.parts):
            continue
        writer = (_StagesWriter if spec.name == STAGES else _Writer)(module, spec, rename)
        writer.write()
        calls[spec.name] = writer.calls
    library = _vector_library()
    for spec in specs:
        if library is None or spec.name not in ROWS_NAMES or spec.solve is not None:
            continue
        if spec.pre is not None and spec.pre[2] is not None:
            continue
        # arithmetic alone is a few nanoseconds a row: vectors would not repay the
        # 10-20 ms that compiling them adds to a scene's first opening
        if all(_base_name(name) in _VECTOR_OPS for name in calls[spec.name]):
            continue
        _RowsWriter(module, spec, rename, library).write()
    return str(module)


def _small(module, parts: Sequence[FunctionSpec]) -> bool:
    """Whether the functions ``parts`` (written into ``module`` already, or not at all)
    have at most ``STAGES_MAX_INSTRUCTIONS`` instructions together."""
    count = 0
    for part in parts:
        function = module.globals.get(part.name)
        if function is None:
            return False
        count += sum(len(block.instructions) for block in function.blocks)
    return count <= STAGES_MAX_INSTRUCTIONS


def written(text: str, names: Sequence[str]) -> list[str]:
    """Those of the functions ``names`` that ``write_ir``'s ``text`` defines (it leaves
    out ``compose_stages`` of large gradients)."""
    return [name for name in names if f'@"{name}"(' in text]


_compile_lock = threading.Lock()


@contextlib.contextmanager
def _stop_signals_held():
    """Ctrl+C (and SIGTERM, SIGHUP) wait until LLVM has made the machine code: it calls
    back into Python (the object cache), where a KeyboardInterrupt is only printed as
    "Exception ignored" with a traceback. Held in the main thread, which alone runs
    Python's handlers; they run as soon as the signals are let through."""
    # get_ident: current_thread() would register a dummy for a Qt thread, left for ever
    if threading.get_ident() != threading.main_thread().ident:
        yield
        return
    held = {signal.SIGINT, signal.SIGTERM, signal.SIGHUP}
    before = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)


class _ObjectFile:
    """The machine code of one IR text on disk (LLVM's object cache for MCJIT), so that
    a scene opened again loads its functions instead of optimising and compiling them
    (80 ms for a ten-link chain). Keyed by the text and by what the code is for (LLVM's
    version, this CPU and its features); checked like every cache file
    (``systems.cache_integrity``), and off with the derivation cache."""

    def __init__(self, ir_text: str):
        import hashlib

        from systems import derivation_cache
        from systems.cache_integrity import cache_root, read_checked, usable_directory

        self.path = None
        self.code: bytes | None = None
        if not derivation_cache.enabled():
            return
        llvm = _llvm()
        self.version = " ".join(
            ("llvm object", str(llvm.llvm_version_info), llvm.get_process_triple(),
             llvm.get_host_cpu_name(), llvm.get_host_cpu_features().flatten())
        )  # fmt: skip
        key = hashlib.sha256(f"{self.version}\n{ir_text}".encode()).hexdigest()[:32]
        self.path = usable_directory(cache_root() / "machine-code") / f"{key}.o"
        self.code = read_checked(self.path, self.version)

    def give(self, module) -> bytes | None:
        return self.code

    def keep(self, module, code: bytes) -> None:
        from systems.cache_integrity import write_checked

        if self.path is not None and self.code is None:
            write_checked(self.path, bytes(code), self.version)


class LLVMKernels:
    """A scene's system functions compiled from LLVM IR (``write_ir``'s text; ``names``
    the functions in it): optimised (LLVM's pipeline at ``speed_level``: the module's,
    or with ``optimise`` the function simplification pipeline on those functions alone,
    or the function ``passes`` named so (llvmlite's ``add_<name>_pass``), the others
    left as written) and turned into machine code by LLVM alone, for a generic x86-64
    or (``host``) this CPU.

    ``functions[name]`` are the values the drivers take; attribute access gives a
    function callable from Python with the arguments of ``systems.codegen.SIGNATURES``
    (through a small caller compiled once among the drivers).
    """

    def __init__(
        self,
        ir_text: str,
        names: Sequence[str],
        speed_level: int = 3,
        host: bool = False,
        optimise: Sequence[str] | None = None,
        passes: Sequence[str] | None = None,
    ):
        llvm = _llvm()
        if SOLVER_SYMBOL in ir_text:
            _bind_solver()
        if ROWS_PREFIX in ir_text and _vector_library() is None:
            raise Unsupported("the code calls glibc's vector math library, absent here")
        # the machine code is keyed by what made it: the text, and a level other than 3,
        # the host's own instructions (the key has the CPU and its features already) or
        # optimising some functions only
        options = ""
        if (speed_level, host, optimise, passes) != (3, False, None, None):
            options = f"; {speed_level} {host} {optimise} {passes}\n"
        stored = _ObjectFile(options + ir_text)
        with _compile_lock:  # LLVM's optimiser and MCJIT are not thread-safe here
            parsed = llvm.parse_assembly(ir_text)
            parsed.triple = llvm.get_process_triple()
            parsed.verify()
            machine = _target_machine(host)
            if stored.code is None:  # optimised only where machine code is made of it
                options = llvm.create_pipeline_tuning_options(speed_level=speed_level)
                builder = llvm.create_pass_builder(machine, options)
                if optimise is None:
                    builder.getModulePassManager().run(parsed, builder)
                else:
                    if passes is None:
                        manager = builder.getFunctionPassManager()
                    else:
                        manager = llvm.create_new_function_pass_manager()
                        for name in passes:
                            getattr(manager, f"add_{name}_pass")()
                    for name in optimise:
                        manager.run(parsed.get_function(name), builder)
            self._engine = llvm.create_mcjit_compiler(parsed, machine)
            self._engine.set_object_cache(stored.keep, stored.give)
            with _stop_signals_held():
                self._engine.finalize_object()
        from systems.codegen import function_value

        self.functions = {
            name: function_value(self._engine.get_function_address(name), _signature(name), self)
            for name in names
        }
        self._callers: dict[str, object] = {}
        self.rows = {}
        """``rows[name](ts, Y, width, P, out, blocks)``: ``_RowsWriter``'s function of
        ``name`` (array arguments as addresses), where the text has one."""
        for name in ROWS_NAMES:
            if f'@"{ROWS_PREFIX}{name}"' in ir_text:
                address = self._engine.get_function_address(ROWS_PREFIX + name)
                self.rows[name] = _ROWS_TYPE(address)

    def __getattr__(self, name: str):
        functions = self.__dict__.get("functions", {})
        if name not in functions:
            raise AttributeError(name)
        function = functions[name]
        callers = self._callers

        def call(*args):
            caller = callers.get(name)
            if caller is None:
                from systems.codegen import driver_module, entry_point

                loop = getattr(driver_module(), f"call{len(args)}")
                caller = callers[name] = entry_point(loop, (function, *args))
            return caller(function, *args)

        call.__name__ = name
        setattr(self, name, call)  # found without __getattr__ from now on (probe loops)
        return call
