"""The Taylor coefficients of a scene's solution as machine code: one LLVM function per
scene, written from its decomposition (``systems.taylor.decompose``) with the
recurrences of ``systems.taylor.coefficients``.

The function has the drivers' calling convention (``systems.codegen.SIGNATURES``)::

    taylor_coefficients(t, y, P, out)     out (N + 1, m + nodes), C-contiguous

It writes ``out[k, i] = [u_i]_k``: the state variables' coefficients (columns 0..m-1)
for k = 0..N, every node's (columns m..) at k = 0 and, in the looped form, for
k = 1..N-1 (order N of a node is not needed for the state's). N is read from ``out``'s
shape at run time, so one function serves every tolerance. A constant node (free of
the state and of time, or of a conserved variable: ``Decomposition.conserved``) is
written at order 0 only: its higher coefficients are zero and no recurrence reads them
(a product with it is a scaling, a sum with it touches order 0 only; elsewhere a read
of a constant's order k > 0 is the number 0).

Each form is a prologue (order 0: the parameters read, the state copied, every node's
value, the constant nodes among them, once), then the orders:

- *unrolled*, ``taylor_coefficients`` itself for N = ``UNROLLED`` (the order at the
  default tolerance) where the scene's products (``unrolled_terms``) are at most
  ``UNROLL_BUDGET``: every order's terms written out as IR text (``_Text``), a
  constant's terms dropped, the sums of products pairs of a product and a fused
  multiply-add summed pairwise (``FMA_GROUP``), the nodes' coefficients kept in
  registers (only the state's are stored, as soon as made: node columns of orders >= 1
  are left as they were), divisions by an order-0 value products with its reciprocal;
  no LLVM pass runs on it (straight-line code, already folded);
- *looped*, ``taylor_coefficients_looped`` (``LOOPED``), which ``taylor_coefficients``
  calls for any other N (for every N where the budget is exceeded): a loop over k, each
  node's sum an inner loop over j: small IR, compiled (``LOOPED_PASSES``) in
  milliseconds whatever the order.

``taylor_code`` writes it (remembered on disk per scene, like the tangent functions'
IR); ``TaylorKernels`` turns it into machine code (``TaylorCode.seconds``,
``TaylorKernels.seconds``).
"""

from __future__ import annotations

import re
import struct
import time
from dataclasses import dataclass

import numpy as np

from systems import llvm_kernels
from systems.taylor import decompose as taylor_decompose
from systems.taylor.decompose import Arg, Decomposition

NAME = "taylor_coefficients"
"""The function's name (a key of ``systems.codegen.SIGNATURES``)."""

_HEADER = re.compile(r"^; taylor m=(\d+) width=(\d+)$", re.MULTILINE)

_LIBM = {"sinh", "cosh", "tan", "tanh", "asin", "acos", "atan", "atan2"}
_INTRINSIC = {
    "sqrt": "llvm.sqrt.f64",
    "exp": "llvm.exp.f64",
    "log": "llvm.log.f64",
    "sin": "llvm.sin.f64",
    "cos": "llvm.cos.f64",
    "abs": "llvm.fabs.f64",
    "pow": "llvm.pow.f64",
}


LOOPED = "_looped"
"""The looped form's name: the function's with this suffix."""

FMA_GROUP = 2
"""Products of a sum of the unrolled form per fused multiply-add chain (``_Writer.dot``):
x0 y0 + x1 y1 as fma(x1, y1, x0 y0), the pairs summed pairwise. Against a product each
(then pairwise): the double pendulum compiled 11% faster and ran 11% faster (0.84
against 0.95 us a call), Kepler and Hénon–Heiles alike; chains of 3, 4 or 6 made
Kepler 5-20% slower a call."""

UNROLLED = 20
"""The order written out in full (the order at the default tolerance, machine epsilon)."""
UNROLL_BUDGET = 3000
"""The most products of the unrolled form (``unrolled_terms``) written out; a larger
system has the looped form alone (the double pendulum's 2970 compile in about 0.3 s)."""
LOOPED_PASSES = ("instruction_combine", "new_gvn")
"""LLVM's passes on the looped form (``LLVMKernels(optimise=..., passes=...)``): at order
15 the level-1 pipeline made calls 1-2% faster (the double pendulum 0.917 against 0.936
us, Hénon–Heiles 0.213 against 0.216, Kepler alike) and cost 2.5-6 ms more to compile;
no pass at all, 2-7% slower calls for 4-15 ms less. The unrolled form has no pass
(straight-line code already folded: LLVM's level 2 cost Kepler 40 ms and changed
nothing a call; level 3 had made it 1.3-1.5x slower). Both compiled for this CPU
(``LLVMKernels(host=True)``): Kepler 0.32 us a call against 0.36 for a generic x86-64.
Pairwise sums (``_Writer.total``) took Kepler from 0.32 to 0.26 us a call and
Hénon–Heiles from 0.14 to 0.11."""


def unrolled_terms(decomposition: Decomposition, order: int) -> int:
    """About how many products the unrolled form of ``order`` has: a convolution of k
    terms per order for each product, square, quotient and function node."""
    linear = {"time", "neg", "add", "sub", "sign", "abs"}
    count = 0
    for node in decomposition.nodes:
        if node.constant or node.op in linear:
            continue
        if node.op == "mul" and any(
            a.kind != "u"
            or a.value in decomposition.conserved
            or (
                a.value >= decomposition.m
                and decomposition.nodes[a.value - decomposition.m].constant
            )
            for a in node.args
        ):
            count += order  # a scaling
            continue
        count += order * (order + 1) // 2
    return count


class _Writer(llvm_kernels._Writer):
    """``taylor_coefficients`` of one decomposition."""

    def __init__(
        self,
        module,
        decomposition: Decomposition,
        unrolled: int | None = None,
        name=NAME,
        looped=None,
    ):
        """``looped`` None: the looped form, named ``name + LOOPED``; else the function
        ``name``, calling ``looped`` (the looped form's function) for every order but
        ``unrolled`` (None: for all), whose terms it has written out."""
        spec = llvm_kernels.FunctionSpec(name, ("t", "y", "P", "out"), (), ())
        super().__init__(module, spec, {}, name if looped is not None else name + LOOPED)
        self.unrolled = unrolled
        self.looped = looped
        self.d = decomposition
        self.m = decomposition.m
        self.width = decomposition.m + len(decomposition.nodes)
        self.i64 = self.ir.IntType(64)
        self.order0: dict[int, object] = {}  # column -> its value at order 0
        self.parameters: dict[int, object] = {}

    # -- helpers ---------------------------------------------------------------------------

    def int(self, value: int):
        return self.ir.Constant(self.i64, value)

    def varying(self, arg: Arg) -> bool:
        """Whether ``arg`` has coefficients of order > 0 (a column written at each k)."""
        if arg.kind != "u":
            return False
        if arg.value < self.m:
            return arg.value not in self.d.conserved
        return not self.d.nodes[arg.value - self.m].constant

    def value0(self, arg: Arg):
        """``arg``'s value at order 0."""
        if arg.kind == "num":
            return self.const(arg.value)
        if arg.kind == "par":
            found = self.parameters.get(arg.value)
            if found is None:
                pointer = self.b.gep(self.data["P"], [self.int(arg.value)])
                found = self.parameters[arg.value] = self.b.load(pointer, name=f"P{arg.value}")
            return found
        return self.order0[arg.value]

    def state_value(self, y, i: int):
        """``y[i]`` at the start."""
        return self.b.load(self.b.gep(y, [self.int(i)]), name=f"y{i}")

    def at(self, column: int, k):
        """Pointer to ``out[k, column]`` (k an i64 value or a number)."""
        b = self.b
        if isinstance(k, int):
            return b.gep(self.data["out"], [self.int(k * self.width + column)])
        index = b.add(b.mul(k, self.int(self.width)), self.int(column))
        return b.gep(self.data["out"], [index])

    def coef(self, arg: Arg, k):
        """``[arg]_k`` for an i64 value k: a load, or for a constant its value at k = 0."""
        if self.varying(arg):
            return self.b.load(self.at(arg.value, k))
        b = self.b
        return b.select(b.icmp_signed("==", k, self.int(0)), self.value0(arg), self.const(0.0))

    def time(self):
        """The time at the start."""
        return self.scalars["t"]

    def real(self, k):
        return self.b.sitofp(k, self.double)

    def sum(self, start, stop, term):
        """``sum_{j=start}^{stop-1} term(j)`` as a loop (0.0 when empty): i64 bounds,
        ``term`` writes the IR of one term for the i64 value j."""
        b, ir = self.b, self.ir
        before = b.block
        header = self.function.append_basic_block("sum")
        body = self.function.append_basic_block("term")
        after = self.function.append_basic_block("summed")
        b.branch(header)
        b.position_at_end(header)
        j = b.phi(self.i64, name="j")
        total = b.phi(self.double, name="acc")
        j.add_incoming(start, before)
        total.add_incoming(ir.Constant(self.double, 0.0), before)
        b.cbranch(b.icmp_signed("<", j, stop), body, after)
        b.position_at_end(body)
        added = b.fadd(total, term(j))
        j.add_incoming(b.add(j, self.int(1)), b.block)
        total.add_incoming(added, b.block)
        b.branch(header)
        b.position_at_end(after)
        return total

    def product_sum(self, a: Arg, c: Arg, k, start, stop, weight=None):
        """``sum_{j=start}^{stop-1} w(j) [a]_j [c]_{k-j}`` with ``weight`` None (w = 1),
        "j" (w = j) or "k-j"."""
        b = self.b

        def term(j):
            back = b.sub(k, j)
            product = b.fmul(self.coef(a, j), self.coef(c, back))
            if weight == "j":
                return b.fmul(self.real(j), product)
            if weight == "k-j":
                return b.fmul(self.real(back), product)
            return product

        return self.sum(start, stop, term)

    # -- the function ----------------------------------------------------------------------

    def write(self) -> None:
        b = self.b
        d, m = self.d, self.m
        out_argument = self.function.args[3]
        rows = b.extract_value(out_argument, [5, 0], name="rows")
        N = b.sub(rows, self.int(1), name="N")
        if self.looped is not None and self.unrolled is None:
            b.call(self.looped, list(self.function.args))
            b.ret(self.ir.Constant(self.result_type, None))
            return
        if self.looped is not None:  # the default order: straight-line code
            straight = self.function.append_basic_block("unrolled")
            other = self.function.append_basic_block("looped")
            b.cbranch(b.icmp_signed("==", N, self.int(self.unrolled)), straight, other)
            b.position_at_end(other)
            b.call(self.looped, list(self.function.args))
            b.ret(self.ir.Constant(self.result_type, None))
            b.position_at_end(straight)
            self.write_straight()
            b.ret(self.ir.Constant(self.result_type, None))
            return
        self.prologue()
        # orders 1 .. N - 1: the state's from the outputs' order k - 1, then the nodes'
        before = b.block
        header = self.function.append_basic_block("order")
        body = self.function.append_basic_block("nodes")
        last = self.function.append_basic_block("last")
        b.branch(header)
        b.position_at_end(header)
        k = b.phi(self.i64, name="k")
        k.add_incoming(self.int(1), before)
        b.cbranch(b.icmp_signed("<", k, N), body, last)
        b.position_at_end(body)
        self.state_row(k)
        for index, node in enumerate(d.nodes):
            if not node.constant:
                b.store(self.recurrence(node, m + index, k), self.at(m + index, k))
        k.add_incoming(b.add(k, self.int(1)), b.block)
        b.branch(header)
        b.position_at_end(last)  # order N: the state's only
        done = self.function.append_basic_block("done")
        final = self.function.append_basic_block("final")
        b.cbranch(b.icmp_signed(">=", N, self.int(1)), final, done)
        b.position_at_end(final)
        self.state_row(N)
        b.branch(done)
        b.position_at_end(done)
        b.ret(self.ir.Constant(self.result_type, None))

    def write_straight(self) -> None:
        """The unrolled form's block (order 0, then ``write_unrolled``), written as text
        by ``_Text`` (llvmlite's builder spent Kepler's 20 ms in Python, this a fifth):
        ``self.straight`` holds its lines, for ``_write`` to put in place of the marker
        comment left in the block."""
        builder, self.b = self.b, _Text()
        constant = self.const
        self.const = self.b.const
        try:
            self.prologue()
            self.write_unrolled(self.unrolled)
        finally:
            self.straight, self.b, self.const = self.b.lines, builder, constant
        builder.comment(_MARKER)

    def prologue(self) -> None:
        """Order 0: the parameters read, the state copied, every node's value (the
        constant nodes' among them, once), all stored in ``out``'s row 0."""
        b = self.b
        d, m = self.d, self.m
        zero = 0
        y = self.data["y"]
        for j in range(len(d.parameters)):  # first: the block dominates every use
            self.value0(Arg("par", j))
        for i in range(m):
            value = self.state_value(y, i)
            self.order0[i] = value
            b.store(value, self.at(i, zero))
        for index, node in enumerate(d.nodes):
            column = m + index
            value = self.value_of(node)
            self.order0[column] = value
            b.store(value, self.at(column, zero))

    # -- the unrolled form: every order's terms written out ---------------------------------

    def write_unrolled(self, N: int) -> None:
        """Orders 1..N with k a number: no loop, no index arithmetic, a constant's terms
        dropped, divisions by a node's order-0 value a product with its reciprocal
        (computed once), the nodes' values kept in registers, the state's stored as
        soon as made."""
        b = self.b
        d, m = self.d, self.m
        self.V: dict[tuple[int, int], object] = {}
        self.inverses: dict[int, object] = {}
        self.weighted: dict[tuple, object] = {}
        for column, value in self.order0.items():
            self.V[column, 0] = value
        zero = self.const(0.0)
        for k in range(1, N + 1):
            for i, output in enumerate(d.outputs):
                # stored at once: a value no later order reads is then dead (against
                # stores at the end: Kepler and Hénon–Heiles compiled 8% faster and ran
                # 10% faster a call)
                value = self.V[i, k] = self.scaled(self.cv(output, k - 1), 1.0 / k)
                b.store(zero if value is None else value, self.at(i, k))
            if k == N:
                break
            for index, node in enumerate(d.nodes):
                if not node.constant:
                    self.V[m + index, k] = self.unrolled_recurrence(node, m + index, k)

    def cv(self, arg: Arg, k: int):
        """``[arg]_k`` (k a number) as an IR value, or None where it is zero."""
        if self.varying(arg):
            return self.V[arg.value, k]
        if k > 0 or (arg.kind == "num" and arg.value == 0.0):
            return None
        return self.value0(arg)

    def inverse(self, arg: Arg, negative: bool = False):
        """1 / (``arg``'s order-0 value), or its negative, computed once."""
        key = (arg.kind, arg.value, negative)
        found = self.inverses.get(key)
        if found is None:
            one = self.const(-1.0 if negative else 1.0)
            found = self.inverses[key] = self.b.fdiv(one, self.value0(arg))
        return found

    def scaled(self, value, factor):
        """``value * factor`` (a number or an IR value); None stays None."""
        if value is None:
            return None
        if isinstance(factor, float):
            if factor == 1.0:
                return value
            factor = self.const(factor)
        return self.b.fmul(value, factor)

    def combined(self, x, y, subtract: bool = False):
        """x + y (x - y), either None for zero."""
        b = self.b
        if y is None:
            return x
        if x is None:
            return b.fneg(y) if subtract else y
        return b.fsub(x, y) if subtract else b.fadd(x, y)

    def total(self, terms):
        """The sum of the IR values among ``terms`` (None: zero), pairwise: a tree of
        depth log2(len) instead of a chain of len additions."""
        values = [term for term in terms if term is not None]
        if not values:
            return None
        while len(values) > 1:
            paired = [self.b.fadd(values[i], values[i + 1]) for i in range(0, len(values) - 1, 2)]
            if len(values) % 2:
                paired.append(values[-1])
            values = paired
        return values[0]

    def products(self, a: Arg, c: Arg, k: int, start: int, stop: int, weight=None):
        """``sum_{j=start}^{stop} w_j [a]_j [c]_{k-j}`` (w = 1, j or k - j), in order."""
        terms = []
        for j in range(start, stop + 1):
            x, y = self.cv(a, j), self.cv(c, k - j)
            if x is None or y is None:
                continue
            if weight == "j":  # j [a]_j, shared by the terms of every order (and by pairs)
                key = (a, j)
                if key not in self.weighted:
                    self.weighted[key] = self.scaled(x, float(j))
                x = self.weighted[key]
            elif weight is not None:
                x = self.scaled(x, float(k - j))
            terms.append((x, y))
        return self.dot(terms)

    def dot(self, pairs):
        """``sum x y`` over the (x, y) of ``pairs``: groups of ``FMA_GROUP`` consecutive
        products, each a product and a chain of fused multiply-adds, summed pairwise."""
        groups = []
        for i in range(0, len(pairs), FMA_GROUP):
            group = pairs[i : i + FMA_GROUP]
            value = self.b.fmul(*group[0])
            for x, y in group[1:]:
                value = self._call("llvm.fma.f64", [x, y, value])
            groups.append(value)
        return self.total(groups)

    def symmetric(self, a: Arg, k: int, start: int, stop: int):
        """``sum_{j=start}^{stop} [a]_j [a]_{k-j}`` with stop = k - start, each pair of
        equal products once (doubled)."""
        half = []
        for j in range(start, (k - 1) // 2 + 1):
            if j >= k - j:
                break
            x, y = self.cv(a, j), self.cv(a, k - j)
            if x is not None and y is not None:
                half.append((x, y))
        result = self.scaled(self.dot(half), 2.0)
        if k % 2 == 0 and start <= k // 2 <= stop:
            x = self.cv(a, k // 2)
            if x is not None:
                result = self.combined(result, self.b.fmul(x, x))
        return result

    def unrolled_recurrence(self, node, column: int, k: int):
        """``[node]_k`` (k a number) as an IR value, or None where it is zero."""
        b = self.b
        op = node.op
        args = node.args
        me = Arg("u", column)
        if op == "time":
            return self.const(1.0) if k == 1 else None
        if op == "sign":
            return None
        a = args[0]
        if op == "neg":
            x = self.cv(a, k)
            return None if x is None else b.fneg(x)
        if op in ("add", "sub"):
            return self.combined(self.cv(a, k), self.cv(args[1], k), op == "sub")
        if op == "mul":
            return self.products(a, args[1], k, 0, k)
        if op == "square":
            return self.symmetric(a, k, 0, k)
        if op == "div":
            c = args[1]
            x, correction = self.cv(a, k), self.products(c, me, k, 1, k)
            if x is None:  # -correction / c_0, the sign in the reciprocal (exact)
                return self.scaled(correction, self.inverse(c, negative=True))
            return self.scaled(self.combined(x, correction, subtract=True), self.inverse(c))
        if op == "pow":
            e = args[1]
            terms = []
            for j in range(k):
                x, p = self.cv(a, k - j), self.cv(me, j)
                if x is None or p is None:
                    continue
                if e.kind == "num":
                    factor = self.const(e.value * (k - j) - j)
                else:
                    factor = b.fsub(b.fmul(self.value0(e), self.const(k - j)), self.const(j))
                terms.append((b.fmul(factor, x), p))
            return self.scaled(self.scaled(self.dot(terms), 1.0 / k), self.inverse(a))
        if op == "sqrt":
            top = self.combined(self.cv(a, k), self.symmetric(me, k, 1, k - 1), subtract=True)
            return self.scaled(self.scaled(top, 0.5), self.inverse(me))
        if op == "exp":
            return self.scaled(self.products(a, me, k, 1, k, "j"), 1.0 / k)
        if op == "log":
            correction = self.scaled(self.products(me, a, k, 1, k - 1, "j"), 1.0 / k)
            top = self.combined(self.cv(a, k), correction, subtract=True)
            return self.scaled(top, self.inverse(a))
        if op in ("sin", "cos", "sinh", "cosh", "tan", "tanh"):
            partner = Arg("u", node.deps[0])
            total = self.scaled(self.products(a, partner, k, 1, k, "j"), 1.0 / k)
            if op == "cos":
                return None if total is None else b.fneg(total)
            if op == "tan":
                return self.combined(self.cv(a, k), total)
            if op == "tanh":
                return self.combined(self.cv(a, k), total, subtract=True)
            return total
        if op in ("asin", "acos", "atan", "atan2"):
            w = Arg("u", node.deps[0])
            if op == "atan2":
                x = args[1]
                g = self.combined(
                    self.products(a, x, k, 1, k, "j"),
                    self.products(x, a, k, 1, k, "j"),
                    subtract=True,
                )
            else:
                g = self.scaled(self.cv(a, k), float(k))
                if op == "acos" and g is not None:
                    g = b.fneg(g)
            correction = self.products(w, me, k, 1, k - 1, "k-j")
            top = self.combined(g, correction, subtract=True)
            return self.scaled(self.scaled(top, 1.0 / k), self.inverse(w))
        if op == "abs":
            a0 = self.value0(a)
            unit = self._call("llvm.copysign.f64", [self.const(1.0), a0])
            is_zero = b.fcmp_ordered("==", a0, self.const(0.0))
            return self.scaled(self.cv(a, k), b.select(is_zero, self.const(0.0), unit))
        raise llvm_kernels.Unsupported(f"no recurrence for the op {op}")

    def state_row(self, k) -> None:
        """``[y_i]_k = [f_i]_{k-1} / k``."""
        b = self.b
        previous = b.sub(k, self.int(1))
        kf = self.real(k)
        for i, output in enumerate(self.d.outputs):
            b.store(b.fdiv(self.coef(output, previous), kf), self.at(i, k))

    def value_of(self, node):
        """A node's value at order 0 (``coefficients.VALUES``)."""
        b = self.b
        op = node.op
        if op == "time":
            return self.time()
        a = [self.value0(arg) for arg in node.args]
        if op == "neg":
            return b.fneg(a[0])
        if op in ("add", "sub", "mul", "div"):
            method = {"add": b.fadd, "sub": b.fsub, "mul": b.fmul, "div": b.fdiv}[op]
            return method(a[0], a[1])
        if op == "square":
            return b.fmul(a[0], a[0])
        if op == "sign":
            unit = self._call("llvm.copysign.f64", [self.const(1.0), a[0]])
            is_zero = b.fcmp_ordered("==", a[0], self.const(0.0))
            return b.select(is_zero, self.const(0.0), unit)
        if op in _INTRINSIC:
            return self._call(_INTRINSIC[op], a)
        if op in _LIBM:
            return self._call(op, a)
        raise llvm_kernels.Unsupported(f"no order-0 value for the op {op}")

    def recurrence(self, node, column: int, k):
        """``[node]_k`` of the node in ``column`` for k >= 1 (``coefficients.RECURRENCES``)."""
        b = self.b
        op = node.op
        args = node.args
        me = Arg("u", column)
        one = self.int(1)
        kp1 = b.add(k, one)
        kf = self.real(k)
        if op == "time":
            return b.select(b.icmp_signed("==", k, one), self.const(1.0), self.const(0.0))
        if op == "sign":
            return self.const(0.0)
        a = args[0]
        if op == "neg":
            return b.fneg(self.coef(a, k))
        if op in ("add", "sub"):
            c = args[1]
            if not self.varying(a):
                value = self.coef(c, k)
                return b.fneg(value) if op == "sub" else value
            if not self.varying(c):
                return self.coef(a, k)
            method = b.fadd if op == "add" else b.fsub
            return method(self.coef(a, k), self.coef(c, k))
        if op == "mul":
            c = args[1]
            if not self.varying(a):
                return b.fmul(self.value0(a), self.coef(c, k))
            if not self.varying(c):
                return b.fmul(self.coef(a, k), self.value0(c))
            return self.product_sum(a, c, k, self.int(0), kp1)
        if op == "square":
            return self.product_sum(a, a, k, self.int(0), kp1)
        if op == "div":
            c = args[1]
            if not self.varying(c):
                return b.fdiv(self.coef(a, k), self.value0(c))
            correction = self.product_sum(c, me, k, one, kp1)
            top = b.fneg(correction) if not self.varying(a) else b.fsub(self.coef(a, k), correction)
            return b.fdiv(top, self.value0(c))
        if op == "pow":
            e = self.value0(args[1])

            def term(j):
                back = b.sub(k, j)
                factor = b.fsub(b.fmul(e, self.real(back)), self.real(j))
                return b.fmul(b.fmul(factor, self.coef(a, back)), self.coef(me, j))

            total = self.sum(self.int(0), k, term)
            return b.fdiv(total, b.fmul(kf, self.value0(a)))
        if op == "sqrt":
            correction = self.product_sum(me, me, k, one, k)
            top = b.fsub(self.coef(a, k), correction)
            return b.fdiv(top, b.fmul(self.const(2.0), self.value0(me)))
        if op == "exp":
            return b.fdiv(self.product_sum(a, me, k, one, kp1, "j"), kf)
        if op == "log":
            correction = b.fdiv(self.product_sum(me, a, k, one, k, "j"), kf)
            return b.fdiv(b.fsub(self.coef(a, k), correction), self.value0(a))
        if op in ("sin", "cos", "sinh", "cosh", "tan", "tanh"):
            partner = Arg("u", node.deps[0])
            total = b.fdiv(self.product_sum(a, partner, k, one, kp1, "j"), kf)
            if op == "cos":
                return b.fneg(total)
            if op == "tan":
                return b.fadd(self.coef(a, k), total)
            if op == "tanh":
                return b.fsub(self.coef(a, k), total)
            return total
        if op in ("asin", "acos", "atan", "atan2"):
            w = Arg("u", node.deps[0])
            if op == "atan2":
                x = args[1]
                g = b.fsub(
                    self.product_sum(a, x, k, one, kp1, "j"),
                    self.product_sum(x, a, k, one, kp1, "j"),
                )
            else:
                g = b.fmul(kf, self.coef(a, k))
                if op == "acos":
                    g = b.fneg(g)
            correction = self.product_sum(w, me, k, one, k, "k-j")
            return b.fdiv(b.fsub(g, correction), b.fmul(kf, self.value0(w)))
        if op == "abs":
            a0 = self.value0(a)
            unit = self._call("llvm.copysign.f64", [self.const(1.0), a0])
            is_zero = b.fcmp_ordered("==", a0, self.const(0.0))
            sign = b.select(is_zero, self.const(0.0), unit)
            return b.fmul(sign, self.coef(a, k))
        raise llvm_kernels.Unsupported(f"no recurrence for the op {op}")


BATCH_NAME = "taylor_batch"
"""The batch function's name (a key of ``systems.codegen.SIGNATURES``)."""


def lanes() -> int:
    """The trajectories of one batch: a vector register's doubles on this CPU (8 with
    AVX-512, 4 with AVX, else 2)."""
    features = llvm_kernels._llvm().get_host_cpu_features()
    if features.get("avx512f"):
        return 8
    return 4 if features.get("avx") else 2


class _BatchWriter(_Writer):
    """``taylor_batch(T, Y, P, out)``: the coefficients of ``B`` trajectories at once,
    every value a vector of B lanes (LLVM's vector type: SIMD instructions), T (B,) their
    times, Y (m, B) their states, out (N + 1, width, B); the same code as
    ``taylor_coefficients`` lane by lane. Functions without a vector form (the libm
    ones) are called lane by lane."""

    def __init__(
        self, module, decomposition: Decomposition, unrolled: int | None, name, looped=None, *, B
    ):
        super().__init__(module, decomposition, unrolled, name, looped)
        ir = self.ir
        self.B = B
        self.scalar = ir.DoubleType()
        self.double = ir.VectorType(self.scalar, B)
        self.vector_pointer = self.double.as_pointer()
        block = self.b.block
        self.b = _AlignedBuilder(block)

    def write_straight(self) -> None:
        self.prologue()
        self.write_unrolled(self.unrolled)

    def splat(self, scalar):
        """The vector of B copies of ``scalar``."""
        ir, b = self.ir, self.b
        undefined = ir.Constant(self.double, ir.Undefined)
        vector = b.insert_element(undefined, scalar, ir.Constant(ir.IntType(32), 0))
        mask = ir.Constant(ir.VectorType(ir.IntType(32), self.B), [0] * self.B)
        return b.shuffle_vector(vector, undefined, mask)

    def vector_at(self, pointer, index):
        """The vector of B doubles from element ``index`` (an i64 value) of ``pointer``."""
        return self.b.bitcast(self.b.gep(pointer, [index]), self.vector_pointer)

    def state_value(self, y, i: int):
        return self.b.load(self.vector_at(y, self.int(i * self.B)), name=f"y{i}")

    def time(self):
        return self.b.load(self.vector_at(self.data["t"], self.int(0)), name="t")

    def at(self, column: int, k):
        b = self.b
        if isinstance(k, int):
            return self.vector_at(self.data["out"], self.int((k * self.width + column) * self.B))
        index = b.add(b.mul(k, self.int(self.width)), self.int(column))
        return self.vector_at(self.data["out"], b.mul(index, self.int(self.B)))

    def value0(self, arg: Arg):
        if arg.kind == "par":
            found = self.parameters.get(arg.value)
            if found is None:
                pointer = self.b.gep(self.data["P"], [self.int(arg.value)])
                scalar = self.b.load(pointer, name=f"P{arg.value}")
                found = self.parameters[arg.value] = self.splat(scalar)
            return found
        return super().value0(arg)

    def real(self, k):
        return self.splat(self.b.sitofp(k, self.scalar))

    def _call(self, name: str, args: list):
        ir, b = self.ir, self.b
        if name.startswith("llvm."):  # an intrinsic: its vector form
            name = f"{name[: -len('f64')]}v{self.B}f64"
            function = self.module.globals.get(name)
            if function is None:
                function_type = ir.FunctionType(self.double, [self.double] * len(args))
                function = ir.Function(self.module, function_type, name=name)
            return b.call(function, args)
        function = self.module.globals.get(name)
        if function is None:
            function_type = ir.FunctionType(self.scalar, [self.scalar] * len(args))
            function = ir.Function(self.module, function_type, name=name)
        result = ir.Constant(self.double, ir.Undefined)
        for lane in range(self.B):
            index = ir.Constant(ir.IntType(32), lane)
            value = b.call(function, [b.extract_element(a, index) for a in args])
            result = b.insert_element(result, value, index)
        return result


class _SweepWriter(_BatchWriter):
    """``taylor_batch``'s code with parameters of each lane's own (a sweep: an orbit
    diagram's values, ``systems.chaos.bifurcation``): ``P`` is (k, B) flattened, lane
    ``l``'s parameter ``j`` at ``P[j B + l]``, read as one vector where the batch splats
    one number. Lane by lane the same operations as ``taylor_coefficients`` at that
    lane's parameters."""

    def value0(self, arg: Arg):
        if arg.kind == "par":
            found = self.parameters.get(arg.value)
            if found is None:
                pointer = self.vector_at(self.data["P"], self.int(arg.value * self.B))
                found = self.parameters[arg.value] = self.b.load(pointer, name=f"P{arg.value}")
            return found
        return super().value0(arg)


_MARKER = "taylor straight-line code"


class _Text:
    """The part of llvmlite's ``IRBuilder`` the unrolled form of ``taylor_coefficients``
    uses, on doubles, writing LLVM IR text directly: an operand is a string (a value
    of this builder, a constant) or an llvmlite value (its reference)."""

    def __init__(self):
        self.lines: list[str] = []
        self.constants: dict[float, str] = {}

    def const(self, value: float) -> str:
        found = self.constants.get(value)
        if found is None:  # as llvmlite writes a double: its bits in hex
            bits = struct.unpack("<Q", struct.pack("<d", value))[0]
            found = self.constants[value] = f"0x{bits:016x}"
        return found

    def _value(self, text: str) -> str:
        name = f"%v{len(self.lines)}"
        self.lines.append(f"  {name} = {text}")
        return name

    @staticmethod
    def _ref(value) -> str:
        return value if isinstance(value, str) else value.get_reference()

    def _binary(self, op: str, x, y) -> str:
        return self._value(f"{op} double {self._ref(x)}, {self._ref(y)}")

    def fadd(self, x, y):
        return self._binary("fadd", x, y)

    def fsub(self, x, y):
        return self._binary("fsub", x, y)

    def fmul(self, x, y):
        return self._binary("fmul", x, y)

    def fdiv(self, x, y):
        return self._binary("fdiv", x, y)

    def fneg(self, x):
        return self._value(f"fneg double {self._ref(x)}")

    def fcmp_ordered(self, op: str, x, y):
        assert op == "=="
        return self._value(f"fcmp oeq double {self._ref(x)}, {self._ref(y)}")

    def select(self, condition, x, y):
        return self._value(f"select i1 {condition}, double {self._ref(x)}, double {self._ref(y)}")

    def gep(self, pointer, indices):
        (index,) = indices
        return self._value(
            f"getelementptr double, double* {self._ref(pointer)}, i64 {self._ref(index)}"
        )

    def load(self, pointer, name=""):
        return self._value(f"load double, double* {self._ref(pointer)}")

    def store(self, value, pointer):
        self.lines.append(f"  store double {self._ref(value)}, double* {self._ref(pointer)}")

    def call(self, function, args):
        operands = ", ".join(f"double {self._ref(a)}" for a in args)
        return self._value(f"call double {function.get_reference()}({operands})")


def _aligned_builder():
    from llvmlite import ir

    class Builder(ir.IRBuilder):
        """Loads and stores aligned to a double (a vector of out need not be aligned to
        its own size)."""

        def load(self, ptr, name="", align=8, typ=None):
            return super().load(ptr, name, align)

        def store(self, value, ptr, align=8):
            return super().store(value, ptr, align)

    return Builder


def _AlignedBuilder(block):
    return _aligned_builder()(block)


def _write(writer, decomposition: Decomposition, name: str, budget: int = UNROLL_BUDGET, **options):
    """The module of the function ``name`` and of its looped form (``writer`` the
    class writing them; ``options`` its own), as LLVM IR text; unrolled at order
    ``UNROLLED`` up to ``budget`` products."""
    from llvmlite import ir

    module = ir.Module(name=f"pe_{name}")
    unrolled = UNROLLED if unrolled_terms(decomposition, UNROLLED) <= budget else None
    looped = writer(module, decomposition, None, name, **options)
    looped.write()
    main = writer(module, decomposition, unrolled, name, looped=looped.function, **options)
    main.write()
    text = str(module)
    if unrolled is None or not hasattr(main, "straight"):
        return text
    before, after = text.split(f"  ; {_MARKER}\n")
    return "".join((before, "\n".join(main.straight), "\n", after))


def write_taylor_batch_ir(decomposition: Decomposition, B: int, budget: int = UNROLL_BUDGET) -> str:
    """The LLVM IR text of ``taylor_batch`` for ``decomposition`` and ``B`` lanes (unrolled
    up to ``budget`` products), with a first comment line giving m, the width of ``out``
    and B."""
    text = _write(_BatchWriter, decomposition, BATCH_NAME, budget, B=B)
    width = decomposition.m + len(decomposition.nodes)
    return f"; taylor m={decomposition.m} width={width} lanes={B}\n{text}"


def write_taylor_sweep_ir(decomposition: Decomposition, B: int) -> str:
    """``write_taylor_batch_ir``'s function (same name and header) with parameters of
    each lane's own (``_SweepWriter``): written only when a sweep asks for it
    (``TaylorKernels.sweep``), never by the default build."""
    text = _write(_SweepWriter, decomposition, BATCH_NAME, UNROLL_BUDGET, B=B)
    width = decomposition.m + len(decomposition.nodes)
    return f"; taylor m={decomposition.m} width={width} lanes={B}\n{text}"


def write_taylor_ir(decomposition: Decomposition) -> str:
    """The LLVM IR text of ``taylor_coefficients`` for ``decomposition``, with a first
    comment line giving m and the width of ``out`` (m + nodes).

    Raises
    ------
    llvm_kernels.Unsupported
        An op without a writer here (none of ``decompose.OPS``).
    """
    text = _write(_Writer, decomposition, NAME)
    width = decomposition.m + len(decomposition.nodes)
    return f"; taylor m={decomposition.m} width={width}\n{text}"


@dataclass(frozen=True)
class TaylorCode:
    """The coefficient function as LLVM IR text (picklable), and the width of its
    ``out``: ``m`` state variables and ``width - m`` nodes."""

    text: str
    m: int
    width: int
    seconds: float = 0.0


def decomposition_of(mechanics) -> taylor_decompose.Decomposition:
    """The Taylor decomposition of ``mechanics``, remembered per scene: every function
    written from it (the scalar coefficients, the batch, the sweep, the double-double
    orders) and the cost the automatic choice counts take the same nodes in every
    process. The same equations decompose into other nodes when their expressions were
    built otherwise: a derivation read back from the disk (unpickled, its sums and
    products rebuilt) gave the double pendulum 50 nodes where the fresh one gave 48, and
    a batch function written from one and run with the other's width read garbage.

    Raises
    ------
    NotDecomposable
        As ``decompose.decompose_mechanics``.
    """
    from systems import derivation_cache

    reason = taylor_decompose.refusal(mechanics)
    if reason:
        raise taylor_decompose.NotDecomposable(reason)
    key = f"taylor decomposition {derivation_cache.scene_key(mechanics.scene)}"
    tag = f"decomposition {derivation_cache.code_hash(taylor_decompose)}"
    return derivation_cache.remembered_value(
        key, tag, lambda: taylor_decompose.decompose_mechanics(mechanics)
    )


def taylor_code(mechanics) -> TaylorCode:
    """Write (or read from the disk cache) the coefficient function of ``mechanics``.

    Raises
    ------
    NotDecomposable
        With the reason (``decompose.refusal``, or the decomposition's own).
    """
    import sys

    import llvmlite

    from systems import derivation_cache

    start = time.perf_counter()
    reason = taylor_decompose.refusal(mechanics)
    if reason:
        raise taylor_decompose.NotDecomposable(reason)
    code = derivation_cache.code_hash(sys.modules[__name__], taylor_decompose, llvm_kernels)
    tag = f"taylor {code} llvmlite {llvmlite.__version__}"

    def write() -> str:
        return write_taylor_ir(decomposition_of(mechanics))

    text = derivation_cache.remembered(mechanics.scene, tag, write)
    found = _HEADER.search(text)
    if found is None:  # remembered text is checked: only a writer's bug gets here
        raise RuntimeError("the Taylor IR lacks its header line")
    m, width = int(found.group(1)), int(found.group(2))
    return TaylorCode(text, m, width, time.perf_counter() - start)


def _kernels(text: str, name: str) -> llvm_kernels.LLVMKernels:
    """The machine code of ``write_taylor_ir``'s (or the batch's) text: the looped form
    optimised (``LOOPED_PASSES``), the unrolled one as written."""
    return llvm_kernels.LLVMKernels(
        text, (name,), host=True, optimise=(name + LOOPED,), passes=LOOPED_PASSES
    )


class TaylorKernels:
    """The coefficient function of one scene as machine code.

    Attributes
    ----------
    function
        The value the drivers take (``fns[0]`` of the taylor family).
    m, width : int
        State variables, and columns of ``out`` (m + nodes).
    seconds : float
        Writing (or reading) the IR and making (or loading) the machine code.
    """

    def __init__(self, code: TaylorCode, mechanics=None):
        start = time.perf_counter()
        self.code = code
        self.mechanics = mechanics
        self._batch = None
        self._sweep = None
        self._double = None
        self.m, self.width = code.m, code.width
        self.kernels = _kernels(code.text, NAME)
        self.function = self.kernels.functions[NAME]
        self.seconds = code.seconds + time.perf_counter() - start

    def batch(self):
        """The batch function ``taylor_batch`` (``lanes()`` trajectories at once), written
        and compiled on first use (its machine code kept on disk like the scalar one's):
        the value the batch ensemble loop takes. Returns (function, lanes)."""
        if self._batch is None:
            B = lanes()
            d = decomposition_of(self.mechanics)
            if d.m + len(d.nodes) != self.width:  # the batch loops allocate self.width
                from systems.cache_integrity import cache_root

                raise RuntimeError(
                    f"the Taylor batch function of {self.mechanics.scene.title!r} has "
                    f"{d.m + len(d.nodes)} columns where its scalar function has "
                    f"{self.width}; clear the cache ({cache_root()})"
                )
            text = write_taylor_batch_ir(d, B)
            kernels = _kernels(text, BATCH_NAME)
            self._batch = (kernels, kernels.functions[BATCH_NAME], B)
        return self._batch[1], self._batch[2]

    def sweep(self):
        """The batch function with parameters of each lane's own (``taylor_batch``'s
        signature, P (k, B) flattened: ``write_taylor_sweep_ir``), written and compiled
        the first time an orbit diagram asks for it (``systems.chaos.bifurcation``), its
        machine code kept on disk like the others'. Returns (function, lanes, width):
        the width of its ``out``, from the scene's one decomposition (``decomposition_of``)
        like the scalar code's."""
        if self._sweep is None:
            B = lanes()
            d = decomposition_of(self.mechanics)
            kernels = _kernels(write_taylor_sweep_ir(d, B), BATCH_NAME)
            width = d.m + len(d.nodes)
            self._sweep = (kernels, kernels.functions[BATCH_NAME], B, width)
        return self._sweep[1:]

    def double(self):
        """The double-double orders 1 and 2 (``systems.taylor.double.DoubleKernels``),
        written and compiled the first time a run asks for them (a tolerance below
        machine epsilon; the machine code kept on disk like the others'), never before."""
        if self._double is None:
            from systems.taylor.double import DoubleKernels

            self._double = DoubleKernels(self.mechanics)
        return self._double

    def coefficients(self, t: float, y: np.ndarray, P: np.ndarray, order: int) -> np.ndarray:
        """``out`` (order + 1, width) of ``taylor_coefficients`` at one state ``y`` (m,)."""
        out = np.zeros((order + 1, self.width))
        y = np.ascontiguousarray(y, dtype=float)
        self.kernels.taylor_coefficients(float(t), y, np.ascontiguousarray(P, dtype=float), out)
        return out


def load_taylor(mechanics) -> TaylorKernels:
    """The coefficient function of ``mechanics`` as machine code.

    Raises
    ------
    NotDecomposable
        With the reason, for a system the family refuses.
    """
    return TaylorKernels(taylor_code(mechanics), mechanics)
