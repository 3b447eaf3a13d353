"""The variational equations of a derived system, as machine code in milliseconds.

The tangent dynamics of Hamilton's equations ``dy/dt = f(y, t)`` (effects included) is
``dV/dt = J(y, t) V`` with ``J = df/dy`` the Jacobian, formed symbolically (symengine)
from ``Mechanics.hamilton_equations`` and written, after one common-subexpression
elimination with ``f`` itself, as LLVM IR (``systems.llvm_kernels``). Only the entries of
J that are not identically zero are multiplied.

**The extended state.** For n coordinates and k tangent vectors ``v_j = (dq_j, dp_j)``
the extended state is::

    Y = (q, dq_1, ..., dq_k,  p, dp_1, ..., dp_k),   shape (2 n (1 + k),)

positions first, momenta second (``extended`` and ``split`` convert). The tangent
functions read n from their code and k from the length of the array, so one compiled
function serves any number of vectors, and they have the types of the functions the
drivers already take (``systems.codegen.SIGNATURES``):

- ``tangent_rhs(t, Y, P, out)``: ``out = (f, J v_1, ..., J v_k)`` in the same layout;
  any family that steps ``rhs`` (DOP853, explicit and Gauss-Legendre Runge-Kutta)
  integrates the extended system with its own compiled driver. A Runge-Kutta method
  applied to the extended system *is* the tangent map of the method (the stages of the
  tangent are the derivatives of the stages), so Gauss-Legendre integrates it with the
  same symplectic scheme;
- ``tangent_grad_kinetic(Y, P, out)`` and ``tangent_grad_potential(t, Y, P, out)``, for
  a separable H = T(p) + V(q, t): ``out = (T_p, T_pp dp_1, ..., T_pp dp_k)`` and
  ``(V_q, V_qq dq_1, ..., V_qq dq_k)``, shape (n (1 + k),). The composition family
  drifts the first half of a state by ``grad_kinetic`` and kicks the second by
  ``grad_potential``: on the extended state, these are the exact derivatives of each
  drift and kick, so a Yoshida composition steps the tangent map of itself.

``tangent_code`` writes the IR (symbolic work, remembered on disk per scene);
``load_tangent`` turns it into machine code (``Tangent``), which quacks like a
``CompiledSystem`` for the runners of ``systems.integrators``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import sympy

from systems import calculus, llvm_kernels
from systems.expressions import as_expr

TANGENT_NAMES = {
    "rhs": "tangent_rhs",
    "grad_kinetic": "tangent_grad_kinetic",
    "grad_potential": "tangent_grad_potential",
}
"""The function a driver's ``fns`` name stands for on the extended state."""


class NotApplicable(ValueError):
    """A system whose variational equations are not written, with the reason."""


def refusal(mechanics) -> str | None:
    """None when the variational equations of ``mechanics`` can be written, else why not."""
    from systems import constraints

    if constraints.constrained(mechanics.scene):
        return (
            "the scene has [constraints]: the variational equations of the projected "
            "motion (with its multipliers, contacts and impacts) are not derived, so "
            "Lyapunov exponents and the fast indicators are for scenes without "
            "constraints; write the system in coordinates that satisfy them instead"
        )
    return None


def extended(y: np.ndarray, V: np.ndarray) -> np.ndarray:
    """The extended state of ``y`` (2n,) and the tangent vectors ``V`` (2n, k) as columns;
    returns shape (2 n (1 + k),)."""
    y = np.asarray(y, dtype=float)
    V = np.asarray(V, dtype=float)
    n = len(y) // 2
    k = V.shape[1]
    positions = np.concatenate([y[None, :n], V[:n].T]).reshape(n * (1 + k))
    momenta = np.concatenate([y[None, n:], V[n:].T]).reshape(n * (1 + k))
    return np.concatenate([positions, momenta])


def split(Y: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``(y, V)`` of extended states: ``Y`` (..., 2 n (1 + k)) -> ``y`` (..., 2n) and the
    tangent vectors ``V`` (..., 2n, k) as columns."""
    Y = np.asarray(Y, dtype=float)
    half = Y.shape[-1] // 2
    k = half // n - 1
    lead = Y.shape[:-1]
    positions = Y[..., :half].reshape(*lead, 1 + k, n)
    momenta = Y[..., half:].reshape(*lead, 1 + k, n)
    y = np.concatenate([positions[..., 0, :], momenta[..., 0, :]], axis=-1)
    V = np.concatenate([positions[..., 1:, :], momenta[..., 1:, :]], axis=-1)
    return y, np.swapaxes(V, -1, -2)


# -- writing the IR ------------------------------------------------------------------------


@dataclass(frozen=True)
class _Shape:
    """What one tangent function computes, in the halves of the extended state.

    ``reads``: (symbol name, half, index): the symbol is ``Y[half * N + index]``, N the
    length of a half (known only at run time). ``values``: (expression, half, index),
    stored at ``out[half * N + index]``. ``products``: (out half, i, in half, l,
    expression): for every tangent vector j, ``out[offset(out half) + i] += expression *
    Y[offset(in half) + l]``, offset(h) = h N + n j. ``halves``: the halves written
    for each vector (every one of their n entries, zero where no product goes).

    A system in matrix form (``solve``: ``FunctionSpec.solve``, the velocities solved
    from M qdot = p - a before anything else) has two more places: products into
    "half" 2 are the right-hand side b of ``M dqdot = b`` for each vector, solved with
    ``mass`` ((i, j, M_ij) of the upper triangle) by the drivers' ``solve_augmented``;
    products from "half" 2 read that dqdot.
    """

    n: int
    reads: tuple
    values: tuple
    products: tuple
    halves: tuple = (0, 1)
    solve: tuple | None = None
    mass: tuple | None = None


class _Writer(llvm_kernels._Writer):
    """One tangent function: the values of the state, then a loop over the vectors."""

    def __init__(self, module, spec: llvm_kernels.FunctionSpec, shape: _Shape, rename: dict):
        super().__init__(module, spec, rename)
        self.shape = shape

    def write(self) -> None:
        ir, b = self.ir, self.b
        i64 = ir.IntType(64)
        shape = self.shape
        n = ir.Constant(i64, shape.n)
        for symbol, argument, index in self.spec.bindings:  # t and the parameters
            if index is None:
                value = self.scalars[argument]
            else:
                value = b.load(b.gep(self.data[argument], [ir.Constant(i64, index)]), name=symbol)
            self.names[symbol] = value
        y_argument = self.function.args[self.spec.arguments.index("y")]
        size = b.extract_value(y_argument, [5, 0], name="size")
        half = b.sdiv(size, ir.Constant(i64, 2), name="half")
        vectors = b.sub(b.sdiv(half, n), ir.Constant(i64, 1), name="k")
        y, out = self.data["y"], self.data["out"]

        def at(pointer, offset, index):
            return b.gep(pointer, [b.add(offset, ir.Constant(i64, index))])

        zero = ir.Constant(i64, 0)
        offsets = (zero, half)
        for symbol, which, index in shape.reads:
            self.names[symbol] = b.load(at(y, offsets[which], index), name=symbol)
        symbolic = [i for i, term in enumerate(shape.products) if not _number(term[4])]
        exprs = [e for e, _, _ in shape.values] + [shape.products[i][4] for i in symbolic]
        mass = [e for _, _, e in shape.mass or ()]
        results = self._phase(exprs + mass, shape.solve)
        for (_, which, index), value in zip(shape.values, results, strict=False):
            b.store(value, at(out, offsets[which], index))
        factors = {}
        for i, value in zip(symbolic, results[len(shape.values) : len(exprs)], strict=True):
            factors[i] = value
        mass_values = results[len(exprs) :]
        if shape.mass:
            width = shape.n + 2
            with b.goto_entry_block():
                W = b.alloca(self.double, size=ir.Constant(i64, shape.n * width), name="Wt")
        entry = b.block
        header = self.function.append_basic_block("vectors")
        body = self.function.append_basic_block("vector")
        done = self.function.append_basic_block("done")
        b.branch(header)
        b.position_at_end(header)
        j = b.phi(i64, name="j")
        j.add_incoming(ir.Constant(i64, 1), entry)
        b.cbranch(b.icmp_signed("<=", j, vectors), body, done)
        b.position_at_end(body)
        shift = b.mul(n, j)
        starts = (shift, b.add(half, shift))
        deltas = {}
        for _, _, which, index, _ in shape.products:
            if (which, index) not in deltas and which < 2:
                deltas[which, index] = b.load(at(y, starts[which], index))
        sums: dict = {}

        def accumulate(stage) -> None:
            for number, (which_out, i, which_in, index, expr) in enumerate(shape.products):
                if (which_out == 2) != (stage == 2):
                    continue
                delta = deltas[which_in, index]
                constant = _number(expr)
                if constant is None:
                    term = b.fmul(factors[number], delta)
                elif constant == 1.0:
                    term = delta
                elif constant == -1.0:
                    term = b.fneg(delta)
                else:
                    term = b.fmul(self.const(constant), delta)
                key = (which_out, i)
                sums[key] = term if key not in sums else b.fadd(sums[key], term)

        if shape.mass:  # dqdot from M dqdot = b, M as the state's (filled again: solved in place)
            accumulate(2)

            def cell(i: int, k: int):
                return b.gep(W, [ir.Constant(i64, i * width + k)])

            for (i, k), value in zip([(i, k) for i, k, _ in shape.mass], mass_values, strict=True):
                b.store(value, cell(i, k))
                b.store(value, cell(k, i) if i != k else cell(i, shape.n + 1))
            for i in range(shape.n):
                b.store(sums.get((2, i), self.const(0.0)), cell(i, shape.n))
            self._call_solver(W, shape.n)
            for i in range(shape.n):
                deltas[2, i] = b.load(cell(i, shape.n))
        accumulate(0)
        for which_out in shape.halves:  # a row of zeros in J is a zero, written too
            for i in range(shape.n):
                total = sums.get((which_out, i), self.const(0.0))
                b.store(total, at(out, starts[which_out], i))
        following = b.add(j, ir.Constant(i64, 1))
        j.add_incoming(following, b.block)
        b.branch(header)
        b.position_at_end(done)
        b.ret(ir.Constant(self.result_type, None))


def _number(expr) -> float | None:
    """The value of a numeric expression (a constant entry of J), else None. ``as_expr``,
    never ``sympify``: no text is ever parsed here."""
    expr = as_expr(expr)
    if expr.is_Number:
        return float(expr)
    return None


def _nonzero(expr) -> bool:
    expr = as_expr(expr)
    return not (expr.is_Number and expr == 0)


def _shapes(mechanics) -> list[tuple[str, tuple, _Shape]]:
    """(name, arguments, shape) of each tangent function of ``mechanics``."""

    scene = mechanics.scene
    n = mechanics.n
    calc = calculus.Calculus(scene.symbols.values())
    q_reads = tuple((f"v_{name}", 0, i) for i, name in enumerate(scene.coordinates))
    p_reads = tuple((f"v_{name}", 1, i) for i, name in enumerate(scene.momentum_names))
    f = [as_expr(e) for e in mechanics.hamilton_equations]
    values = tuple((e, i // n, i % n) for i, e in enumerate(f))
    if mechanics.matrix_form is not None:
        shape = _matrix_form_shape(mechanics, calc, f, q_reads + p_reads, values)
        return [("tangent_rhs", ("t", "y", "P", "out"), shape)]
    variables = (*mechanics.q, *mechanics.p)
    products = []
    for i, row in enumerate(f):
        for col, entry in enumerate(calc.gradient(row, variables)):
            if _nonzero(entry):
                products.append((i // n, i % n, col // n, col % n, entry))
    shapes = [("tangent_rhs", ("t", "y", "P", "out"), _Shape(n, q_reads + p_reads, values,
                                                              tuple(products)))]  # fmt: skip
    if mechanics.separable_parts is not None:
        T, V = (as_expr(e) for e in mechanics.separable_parts)
        for name, arguments, part, symbols, which, reads in (
            ("tangent_grad_kinetic", ("y", "P", "out"), T, mechanics.p, 1, p_reads),
            ("tangent_grad_potential", ("t", "y", "P", "out"), V, mechanics.q, 0, q_reads),
        ):
            gradient = calc.gradient(part, symbols)
            hessian = []
            for i, g in enumerate(gradient):
                for col, entry in enumerate(calc.gradient(g, symbols)):
                    if _nonzero(entry):
                        hessian.append((0, i, which, col, entry))
            values = tuple((g, 0, i) for i, g in enumerate(gradient))
            shapes.append((name, arguments, _Shape(n, reads, values, tuple(hessian), (0,))))
    return shapes


def _matrix_form_shape(mechanics, calc, f, reads, values) -> _Shape:
    """``tangent_rhs`` of a system in matrix form: qdot solves M(q, t) qdot = p - a(q, t),
    so for a vector (dq, dp) dqdot solves ``M dqdot = dp - R dq`` with
    ``R_ik = sum_j dM_ij/dq_k qdot_j + da_i/dq_k`` (qdot held), and
    ``dpdot = g_q dq + g_qdot dqdot + g_p dp`` for ``pdot = g(q, qdot, p, t)``."""

    form = mechanics.matrix_form
    n = mechanics.n
    q, qdot, p = mechanics.q, mechanics.qdot, mechanics.p
    M = form.mass_matrix
    shift = [as_expr(e) for e in form.shift]
    products = [(0, i, 2, i, sympy.Integer(1)) for i in range(n)]  # dq' = dqdot
    for i in range(n):
        products.append((2, i, 1, i, sympy.Integer(1)))  # b = dp - R dq
        momentum = sum((as_expr(M[i, j]) * qdot[j] for j in range(n)), sympy.Integer(0))
        for k, entry in enumerate(calc.gradient(momentum + shift[i], q)):
            if _nonzero(entry):
                products.append((2, i, 0, k, -entry))
    for i, row in enumerate(f[n:]):
        for which, symbols in ((0, q), (2, qdot), (1, p)):
            for k, entry in enumerate(calc.gradient(row, symbols)):
                if _nonzero(entry):
                    products.append((1, i, which, k, entry))
    upper = [(i, j) for i in range(n) for j in range(i, n)]
    entries = tuple(as_expr(M[i, j]) for i, j in upper) + tuple(shift)
    scene = mechanics.scene
    solve = (
        entries,
        tuple(f"v_{name}" for name in scene.momentum_names),
        tuple(f"v_{name}" for name in scene.velocity_names),
    )
    mass = tuple((i, j, as_expr(M[i, j])) for i, j in upper)
    return _Shape(n, reads, values, tuple(products), (0, 1), solve, mass)


def write_tangent_ir(mechanics) -> tuple[str, tuple[str, ...]]:
    """(LLVM IR text, names of its functions) of the tangent functions of ``mechanics``.

    Raises
    ------
    NotApplicable
        For a system ``refusal`` names, or an expression the IR writer does not take.
    """
    reason = refusal(mechanics)
    if reason:
        raise NotApplicable(reason)
    if llvm_kernels.symengine is None:
        raise NotApplicable("symengine is not installed: the variational equations need it")
    from llvmlite import ir

    from systems.compiled import _KernelWriter

    rename = _KernelWriter(mechanics).rename
    scene = mechanics.scene
    module = ir.Module(name="pe_tangent")
    names = []
    for name, arguments, shape in _shapes(mechanics):
        bindings = tuple(
            [("v_t", "t", None)] * ("t" in arguments)
            + [(f"v_{p}", "P", i) for i, (p, _) in enumerate(scene.parameters)]
        )
        spec = llvm_kernels.FunctionSpec(name, arguments, bindings, ())
        try:
            _Writer(module, spec, shape, rename).write()
        except llvm_kernels.Unsupported as exc:
            raise NotApplicable(
                f"the variational equations contain what cannot be compiled ({exc})"
            ) from None
        names.append(name)
    return str(module), tuple(names)


@dataclass(frozen=True)
class TangentCode:
    """The tangent functions as LLVM IR text (picklable: written in a worker process)."""

    text: str
    names: tuple[str, ...]
    seconds: float = 0.0


def tangent_code(mechanics) -> TangentCode:
    """Write (or read from the disk cache) the tangent functions of ``mechanics``.

    Raises
    ------
    NotApplicable
        With the reason, for systems whose variational equations are not written.
    """
    import sys

    import llvmlite

    from systems import derivation_cache

    start = time.perf_counter()
    reason = refusal(mechanics)
    if reason:
        raise NotApplicable(reason)
    code = derivation_cache.code_hash(sys.modules[__name__], llvm_kernels, calculus)
    tag = f"tangent {code} llvmlite {llvmlite.__version__}"
    text = derivation_cache.remembered(mechanics.scene, tag, lambda: write_tangent_ir(mechanics)[0])
    return TangentCode(text, _names(mechanics), time.perf_counter() - start)


def _names(mechanics) -> tuple[str, ...]:
    """The tangent functions written for ``mechanics`` (as ``_shapes`` makes them)."""
    separable = ("tangent_grad_kinetic", "tangent_grad_potential")
    return ("tangent_rhs",) + (separable if mechanics.separable_parts is not None else ())


class Tangent:
    """The tangent functions of a compiled system, as machine code.

    For the runners of ``systems.integrators`` it stands in for the ``CompiledSystem``:
    ``functions(("rhs",))`` gives ``tangent_rhs`` and so on (``TANGENT_NAMES``), and
    ``parameters``, ``mechanics``, ``n`` are the system's.

    Parameters
    ----------
    compiled : CompiledSystem
    code : TangentCode
    """

    def __init__(self, compiled, code: TangentCode):
        start = time.perf_counter()
        self.compiled = compiled
        self.code = code
        self.kernels = llvm_kernels.LLVMKernels(code.text, code.names)
        self.build_seconds = code.seconds + time.perf_counter() - start
        self._batch = None

    @property
    def n(self) -> int:
        return self.compiled.n

    @property
    def mechanics(self):
        return self.compiled.mechanics

    @property
    def parameters(self) -> np.ndarray:
        return self.compiled.parameters

    def functions(self, names) -> tuple:
        """The tangent functions standing for the system functions ``names``."""
        missing = [name for name in names if TANGENT_NAMES.get(name) not in self.code.names]
        if missing:
            raise NotApplicable(f"no tangent function for {', '.join(missing)}")
        return tuple(self.kernels.functions[TANGENT_NAMES[name]] for name in names)

    def rhs(self, t: float, Y: np.ndarray) -> np.ndarray:
        """The extended right-hand side at one extended state ``Y`` (2 n (1 + k),)."""
        Y = np.ascontiguousarray(Y, dtype=float)
        out = np.empty_like(Y)
        self.kernels.tangent_rhs(float(t), Y, self.parameters, out)
        return out

    def rhs_rows(self, t: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """The extended right-hand side at many states: ``t`` (N,), ``Y`` (N, m) -> (N, m)."""
        from systems.codegen import driver_module, entry_point

        (function,) = self.functions(("rhs",))
        t = np.ascontiguousarray(t, dtype=float)
        Y = np.ascontiguousarray(Y, dtype=float)
        out = np.empty_like(Y)
        args = (function, t, Y, self.parameters, out)
        if self._batch is None:
            self._batch = entry_point(driver_module().batch_vector, args)
        self._batch(*args)
        return out

    def jacobian(self, t: float, y: np.ndarray) -> np.ndarray:
        """J = df/dy at one state ``y`` (2n,); returns (2n, 2n)."""
        m = len(y)
        Y = extended(y, np.eye(m))
        return split(self.rhs(t, Y), self.n)[1]


def load_tangent(compiled, code: TangentCode | None = None) -> Tangent:
    """The tangent functions of ``compiled`` as machine code (``code`` written by
    ``tangent_code``, or written here)."""
    return Tangent(compiled, tangent_code(compiled.mechanics) if code is None else code)
