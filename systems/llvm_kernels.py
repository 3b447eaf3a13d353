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
instead. Loops are not written: a system in matrix form calls the drivers'
``solve_augmented`` (``FunctionSpec.solve``), and a constrained scene's multipliers,
projections and impacts are the drivers' own, given its straight-line ``PRIMITIVES``
(``systems.constraints``).
"""

from __future__ import annotations

import contextlib
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
    """

    name: str
    arguments: tuple[str, ...]
    bindings: tuple[tuple[str, str, int | None], ...]
    exprs: tuple
    returns: bool = False
    solve: tuple | None = None
    targets: tuple | None = None
    pre: tuple | None = None


@functools.cache
def _llvm():
    """llvmlite's binding, initialised, with C's math library loaded into the process."""
    import llvmlite.binding as llvm

    llvm.initialize_native_target()
    llvm.initialize_native_asmprinter()
    path = ctypes.util.find_library("m")
    if path:
        llvm.load_library_permanently(path)
    return llvm


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
        function = self.module.globals.get(name)
        if function is None:
            ir = self.ir
            function_type = ir.FunctionType(self.double, [self.double] * len(args))
            function = ir.Function(self.module, function_type, name=name)
        return self.b.call(function, args)


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
    for spec in specs:
        _Writer(module, spec, rename).write()
    return str(module)


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
