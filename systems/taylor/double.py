"""The state's orders 1 and 2 of a scene's Taylor series in double-double arithmetic,
for tolerances below machine epsilon: a function of its own, in a module of its own,
written, compiled (and cached on disk) only the first time a run asks for it, so that a
scene's default build (``systems.taylor.compiled``) is the same code with or without it.

The function has the drivers' calling convention (``systems.codegen.SIGNATURES``)::

    taylor_double(t, y, comp, P, out)     out (4, m), C-contiguous

for the state ``y - comp`` (the stepping loop's compensated state): ``out[0, i] +
out[1, i]`` is ``[y_i]_1`` and ``out[2, i] + out[3, i]`` is ``[y_i]_2`` to
double-double accuracy where the nodes allow it. It computes every node's orders 0 and 1
again, in double (the unrolled form's recurrences at k = 1), then once more in
double-double for the kinds where that is exact with little code (``COMPENSATED``:
sums, products, quotients, squares, square roots and half powers, time; parameters and
numbers are exact); any other node (exp, log, sin, cos, other powers, ...) enters with
its double values and a zero low part. The stepping loop (``kernels.taylor_step``, the
batch loop) calls it after the coefficient function when the runner asks
(``runners.TaylorRunner``: ``coef[5]``) and sums the first two orders and adds them to
the state in double-double; at any other tolerance the drivers get ``no_double()`` in
its place and never call it.
"""

from __future__ import annotations

import functools
import time

import numpy as np

from systems import llvm_kernels
from systems.taylor import compiled as taylor_compiled
from systems.taylor import decompose as taylor_decompose
from systems.taylor.decompose import Arg, Decomposition

NAME = "taylor_double"
"""The function's name (a key of ``systems.codegen.SIGNATURES``)."""

ARGUMENTS = ("t", "y", "comp", "P", "out")

COMPENSATED = frozenset({"time", "neg", "add", "sub", "mul", "square", "div", "sqrt"})
"""The node kinds whose orders 0 and 1 are evaluated in double-double (TwoSum, TwoProd
by a fused multiply-add, a corrected quotient and square root), and ``pow`` of a number
exponent k/2 with |k| <= ``HALF_POWERS`` (``compensated``: a square root, products by
squaring and a quotient). Integer powers are squares and products (``decompose``), so
those are compensated too. Every other kind (``pow`` of another exponent, exp, log, the
trigonometric and hyperbolic functions, abs, sign) keeps its double values with a zero
low part."""

HALF_POWERS = 16
"""The largest |2 e| of a ``pow`` node computed in double-double."""


def compensated(node) -> bool:
    """Whether ``node``'s orders 0 and 1 are evaluated in double-double."""
    if node.op in COMPENSATED:
        return True
    if node.op != "pow" or node.args[1].kind != "num":
        return False
    twice = 2.0 * node.args[1].value
    return twice.is_integer() and 0 < abs(twice) <= HALF_POWERS


class _Writer(taylor_compiled._Writer):
    """``taylor_double`` of one decomposition: the coefficient function's order-0 values
    and its unrolled recurrences at k = 1 (in double), then ``write_compensated``."""

    def __init__(self, module, decomposition: Decomposition):
        spec = llvm_kernels.FunctionSpec(NAME, ARGUMENTS, (), ())
        llvm_kernels._Writer.__init__(self, module, spec, {})
        self.unrolled = None
        self.looped = None
        self.d = decomposition
        self.m = decomposition.m
        self.width = decomposition.m  # out (4, m): ``at(i, k)`` is out[k, i]
        self.i64 = self.ir.IntType(64)
        self.order0: dict[int, object] = {}
        self.parameters: dict[int, object] = {}

    def write(self) -> None:
        d, m = self.d, self.m
        y = self.data["y"]
        for j in range(len(d.parameters)):
            self.value0(Arg("par", j))
        for i in range(m):
            self.order0[i] = self.state_value(y, i)
        for index, node in enumerate(d.nodes):
            self.order0[m + index] = self.value_of(node)
        # order 1 in double of every varying node, as the unrolled form's k = 1: the
        # values of the nodes computed in double below, and the arguments of those
        self.V: dict[tuple[int, int], object] = {}
        self.inverses: dict[tuple, object] = {}
        self.weighted: dict[tuple, object] = {}
        for column, value in self.order0.items():
            self.V[column, 0] = value
        for i, output in enumerate(d.outputs):
            self.V[i, 1] = self.cv(output, 0)
        for index, node in enumerate(d.nodes):
            if not node.constant:
                self.V[m + index, 1] = self.unrolled_recurrence(node, m + index, 1)
        self.write_compensated()
        self.b.ret(self.ir.Constant(self.result_type, None))

    def write_compensated(self) -> None:
        """The state's orders 1 and 2 in double-double from ``y - comp``: high parts into
        ``out[0 | 2, i]``, low parts into ``out[1 | 3, i]``. ``COMPENSATED`` nodes are
        evaluated in double-double at orders 0 and 1, the others keep their double
        values (``order0``, ``V[column, 1]``; None where zero) with a zero low part."""
        b, d, m = self.b, self.d, self.m
        zero = self.const(0.0)
        comp = self.data["comp"]
        v0: dict[int, tuple] = {}
        for i in range(m):
            v0[i] = self._two_sum(self.order0[i], b.fneg(self.state_value(comp, i)))

        def arg0(arg: Arg):
            return v0[arg.value] if arg.kind == "u" else (self.value0(arg), zero)

        for index, node in enumerate(d.nodes):
            column = m + index
            if compensated(node):
                v0[column] = self._dd_value(node, [arg0(a) for a in node.args])
            else:
                v0[column] = (self.order0[column], zero)
        v1: dict[int, tuple | None] = {}
        for i, output in enumerate(d.outputs):
            v1[i] = arg0(output) if self.varying(Arg("u", i)) else None

        def arg1(arg: Arg):
            return v1[arg.value] if self.varying(arg) else None

        for index, node in enumerate(d.nodes):
            column = m + index
            if node.constant:
                continue
            if compensated(node):
                v1[column] = self._dd_first(node, column, v0, arg0, arg1)
            else:
                value = self.V.get((column, 1))
                v1[column] = None if value is None else (value, zero)
        for i, output in enumerate(d.outputs):
            first, second = v1[i], arg1(output)
            first = first or (zero, zero)
            second = (zero, zero) if second is None else self._dd_scale(second, 0.5)
            b.store(first[0], self.at(i, 0))
            b.store(first[1], self.at(i, 1))
            b.store(second[0], self.at(i, 2))
            b.store(second[1], self.at(i, 3))

    def _two_sum(self, x, y):
        b = self.b
        s = b.fadd(x, y)
        back = b.fsub(s, x)
        error = b.fadd(b.fsub(x, b.fsub(s, back)), b.fsub(y, back))
        return s, error

    def _fast_two_sum(self, x, y):
        """x + y exactly as (s, e) when |x| >= |y| (or x = 0)."""
        b = self.b
        s = b.fadd(x, y)
        return s, b.fsub(y, b.fsub(s, x))

    def _two_product(self, x, y):
        p = self.b.fmul(x, y)
        return p, self._call("llvm.fma.f64", [x, y, self.b.fneg(p)])

    def _dd_add(self, x, y):
        s, e = self._two_sum(x[0], y[0])
        return self._fast_two_sum(s, self.b.fadd(e, self.b.fadd(x[1], y[1])))

    def _dd_neg(self, x):
        return self.b.fneg(x[0]), self.b.fneg(x[1])

    def _dd_mul(self, x, y):
        b = self.b
        p, e = self._two_product(x[0], y[0])
        e = b.fadd(e, b.fadd(b.fmul(x[0], y[1]), b.fmul(x[1], y[0])))
        return self._fast_two_sum(p, e)

    def _dd_div(self, x, y):
        """x / y: the double quotient and one correction from the double-double
        remainder x - q y (the subtraction of nearly equal values is exact)."""
        b = self.b
        q = b.fdiv(x[0], y[0])
        p, e = self._two_product(q, y[0])
        e = b.fadd(e, b.fmul(q, y[1]))
        remainder = b.fadd(b.fsub(b.fsub(x[0], p), e), x[1])
        return self._fast_two_sum(q, b.fdiv(remainder, y[0]))

    def _dd_sqrt(self, x):
        b = self.b
        s = self._call("llvm.sqrt.f64", [x[0]])
        p, e = self._two_product(s, s)
        remainder = b.fadd(b.fsub(b.fsub(x[0], p), e), x[1])
        return self._fast_two_sum(s, b.fdiv(remainder, b.fmul(self.const(2.0), s)))

    def _dd_scale(self, x, factor: float):
        """x times a power of two (exact)."""
        return self.b.fmul(x[0], self.const(factor)), self.b.fmul(x[1], self.const(factor))

    def _dd_value(self, node, a: list):
        """A ``COMPENSATED`` node's order-0 value from its arguments' (double-double)."""
        op = node.op
        if op == "time":
            return self.time(), self.const(0.0)
        if op == "neg":
            return self._dd_neg(a[0])
        if op == "add":
            return self._dd_add(a[0], a[1])
        if op == "sub":
            return self._dd_add(a[0], self._dd_neg(a[1]))
        if op == "mul":
            return self._dd_mul(a[0], a[1])
        if op == "square":
            return self._dd_mul(a[0], a[0])
        if op == "div":
            return self._dd_div(a[0], a[1])
        if op == "sqrt":
            return self._dd_sqrt(a[0])
        # pow, a^(k/2): (sqrt(a) or a)^|n| by squaring, inverted for k < 0
        twice = int(2.0 * node.args[1].value)
        base, n = (self._dd_sqrt(a[0]), abs(twice)) if twice % 2 else (a[0], abs(twice) // 2)
        result = None
        while n:
            if n & 1:
                result = base if result is None else self._dd_mul(result, base)
            n >>= 1
            if n:
                base = self._dd_mul(base, base)
        if twice < 0:
            result = self._dd_div((self.const(1.0), self.const(0.0)), result)
        return result

    def _dd_first(self, node, column: int, v0: dict, arg0, arg1):
        """A ``COMPENSATED`` node's order-1 coefficient (double-double, None where zero)
        from the order-0 values ``v0`` and the order-1 ones ``arg1(arg)``."""
        op = node.op
        if op == "time":
            return self.const(1.0), self.const(0.0)
        a = node.args[0]
        a0, a1 = arg0(a), arg1(a)
        if op == "neg":
            return None if a1 is None else self._dd_neg(a1)
        if op == "sqrt":  # [r]_1 = [a]_1 / (2 r_0)
            return None if a1 is None else self._dd_div(a1, self._dd_scale(v0[column], 2.0))
        if op == "square":  # 2 a_0 [a]_1
            return None if a1 is None else self._dd_scale(self._dd_mul(a0, a1), 2.0)
        if op == "pow":  # e r_0 [a]_1 / a_0
            if a1 is None:
                return None
            exponent = (self.const(node.args[1].value), self.const(0.0))
            scaled = self._dd_mul(self._dd_mul(exponent, v0[column]), a1)
            return self._dd_div(scaled, a0)
        c = node.args[1]
        c0, c1 = arg0(c), arg1(c)
        if op in ("add", "sub"):
            if c1 is None:
                return a1
            if op == "sub":
                c1 = self._dd_neg(c1)
            return c1 if a1 is None else self._dd_add(a1, c1)
        if op == "mul":
            left = None if c1 is None else self._dd_mul(a0, c1)
            right = None if a1 is None else self._dd_mul(a1, c0)
            if left is None or right is None:
                return left or right
            return self._dd_add(left, right)
        # div: ([a]_1 - q_0 [c]_1) / c_0
        top = a1
        if c1 is not None:
            correction = self._dd_neg(self._dd_mul(v0[column], c1))
            top = correction if top is None else self._dd_add(top, correction)
        return None if top is None else self._dd_div(top, c0)


def write_double_ir(decomposition: Decomposition) -> str:
    """The LLVM IR text of ``taylor_double`` for ``decomposition``."""
    from llvmlite import ir

    module = ir.Module(name=f"pe_{NAME}")
    _Writer(module, decomposition).write()
    return str(module)


PASSES = taylor_compiled.LOOPED_PASSES
"""LLVM's passes on ``taylor_double``: instcombine drops the double values nothing reads
(a compensated node's own), GVN shares the loads."""


class DoubleKernels:
    """``taylor_double`` of one scene as machine code.

    Attributes
    ----------
    function
        The value the drivers take (``fns[1]`` of the taylor family).
    seconds : float
        Writing (or reading) the IR and making (or loading) the machine code.
    """

    def __init__(self, mechanics):
        import sys

        import llvmlite

        from systems import derivation_cache

        start = time.perf_counter()
        code = derivation_cache.code_hash(
            sys.modules[__name__], taylor_compiled, taylor_decompose, llvm_kernels
        )
        tag = f"taylor double {code} llvmlite {llvmlite.__version__}"

        def write() -> str:
            return write_double_ir(taylor_compiled.decomposition_of(mechanics))

        self.text = derivation_cache.remembered(mechanics.scene, tag, write)
        self.kernels = llvm_kernels.LLVMKernels(
            self.text, (NAME,), host=True, optimise=(NAME,), passes=PASSES
        )
        self.function = self.kernels.functions[NAME]
        self.seconds = time.perf_counter() - start

    def orders(self, t: float, y: np.ndarray, comp: np.ndarray, P: np.ndarray) -> np.ndarray:
        """``out`` (4, m) of ``taylor_double`` at the state ``y - comp`` (each (m,)):
        rows [y]_1, its low part, [y]_2, its low part."""
        y = np.ascontiguousarray(y, dtype=float)
        out = np.zeros((4, len(y)))
        comp = np.ascontiguousarray(comp, dtype=float)
        P = np.ascontiguousarray(P, dtype=float)
        self.kernels.taylor_double(float(t), y, comp, P, out)
        return out


@functools.cache
def no_double():
    """A ``taylor_double`` that writes nothing, the same for every scene: what the
    drivers take in its place where the double-double orders are not asked for (they
    never call it then), so that their loops have one type either way: 2.6 ms of CPU
    once per process, from the object cache (numba refuses a typed placeholder at
    address 0, ``warmup.preload_drivers``' kind, as an argument)."""
    from llvmlite import ir

    module = ir.Module(name="pe_taylor_no_double")
    writer = llvm_kernels._Writer(module, llvm_kernels.FunctionSpec(NAME, ARGUMENTS, (), ()), {})
    writer.b.ret(ir.Constant(writer.result_type, None))
    return llvm_kernels.LLVMKernels(str(module), (NAME,), host=True).functions[NAME]
