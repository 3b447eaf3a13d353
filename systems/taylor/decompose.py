"""Hamilton's equations as a sequence of elementary operations: the Taylor decomposition.

A Taylor method needs, at each step, the Taylor coefficients of the solution to a high
order. Automatic differentiation gives them cheaply once every right-hand side is written
as a sequence of *elementary* operations whose Taylor coefficients have a short
recurrence (Jorba & Zou, "A software package for the numerical integration of ODEs by
means of high-order Taylor methods", Experimental Mathematics 14, 2005; heyoka's
``taylor_decompose``, which this module follows)::

    u_0 .. u_{m-1}      the state variables y = (q, p), m = 2n
    u_m, u_{m+1}, ...   nodes: u_k = op(a, b) or f(a); an argument is an earlier node
                        u_i, a number or a parameter read P[j]
    outputs             dy_i/dt as an argument (a node, a number or a parameter)

Common subexpressions are shared (one node per distinct sympy subexpression), numbers
(``pi``, rationals) are folded to floats, and a subexpression free of the state and of
time is a *constant* node: computed once, at order 0, its higher coefficients zero.
Time ``t`` is the node ``time`` ([t]_0 = t0, [t]_1 = 1).

The operations (``OPS``) and the hidden dependencies some carry (``Node.deps``: nodes
whose coefficients of lower order their recurrence reads, appended by the decomposition
as heyoka appends them):

=========  =====================  ==========================================
op         arguments              deps
=========  =====================  ==========================================
time       ()                     ()
neg        (a,)                   ()
add, sub   (a, b)                 ()
mul, div   (a, b)                 ()
square     (a,)                   ()
pow        (a, e), e constant     ()  real power a**e, needs a_0 != 0
sqrt       (a,)                   ()
exp, log   (a,)                   ()
sin, cos   (a,)                   (the cos, resp. sin, of a)
sinh, cosh (a,)                   (the cosh, resp. sinh, of a)
tan, tanh  (a,)                   (the square of the node itself)
asin, acos (a,)                   (sqrt(1 - a**2),)
atan       (a,)                   (1 + a**2,)
atan2      (y, x)                 (x**2 + y**2,)
abs, sign  (a,)                   ()  |a| = sign(a_0) a, analytic where a_0 != 0
=========  =====================  ==========================================

Integer powers are products: ``x**5 = square(square(x)) * x``, ``x**-2 = 1 / square(x)``,
so they hold where x = 0. A quotient by a constant is a product with its reciprocal (a
constant node), as the LLVM kernels compute ``x/m``: a scaling, O(1) an order.
``tanh`` has its own recurrence (1 - tanh^2, as ``tan``).
Anything else raises ``NotDecomposable`` naming the function.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import sympy

OPS = (
    "time neg add sub mul div square pow sqrt exp log sin cos sinh cosh tan tanh "
    "asin acos atan atan2 abs sign"
).split()
"""Every elementary operation a node may be."""


class NotDecomposable(ValueError):
    """A system or expression without a Taylor decomposition, with the reason."""


@dataclass(frozen=True)
class Arg:
    """An argument of a node or an output: ``kind`` "u" (node or state variable index),
    "num" (a float) or "par" (index into the parameters P)."""

    kind: str
    value: int | float

    def __str__(self) -> str:
        if self.kind == "u":
            return f"u_{self.value}"
        if self.kind == "par":
            return f"P[{self.value}]"
        return repr(self.value)


@dataclass(frozen=True)
class Node:
    """One elementary operation ``op(*args)``; ``deps`` are node indices its recurrence
    reads at lower orders; ``constant``: free of the state and of time (coefficients of
    order >= 1 are zero)."""

    op: str
    args: tuple[Arg, ...]
    deps: tuple[int, ...] = ()
    constant: bool = False

    def __str__(self) -> str:
        text = f"{self.op}({', '.join(str(a) for a in self.args)})"
        if self.deps:
            text += f"  [deps {', '.join(f'u_{d}' for d in self.deps)}]"
        return text + ("  [constant]" if self.constant else "")


@dataclass(frozen=True)
class Decomposition:
    """The Taylor decomposition of ``dy/dt = f(y, t, P)``.

    Attributes
    ----------
    variables : tuple of str
        The m state variables' names, u_0 .. u_{m-1}.
    parameters : tuple of str
        The k parameters' names, in the order of P (k,).
    nodes : tuple of Node
        u_m, u_{m+1}, ...: each reads only state variables and earlier nodes (its
        ``deps`` may be later nodes: they are read at lower orders only).
    outputs : tuple of Arg
        dy_i/dt for each state variable, (m,).
    conserved : tuple of int
        The state variables whose dy_i/dt is 0 (p_theta of a central force): constant
        like a parameter, read from the state (a node of them and of constants is a
        constant node).
    """

    variables: tuple[str, ...]
    parameters: tuple[str, ...]
    nodes: tuple[Node, ...]
    outputs: tuple[Arg, ...]
    conserved: tuple[int, ...] = ()

    @property
    def m(self) -> int:
        """The number of state variables."""
        return len(self.variables)

    def counts(self) -> dict[str, int]:
        """How many nodes of each op (constant nodes not counted: they cost no order)."""
        found: dict[str, int] = {}
        for node in self.nodes:
            if not node.constant:
                found[node.op] = found.get(node.op, 0) + 1
        return found

    def __str__(self) -> str:
        lines = [f"u_{i} = {name}" for i, name in enumerate(self.variables)]
        lines += [f"u_{self.m + i} = {node}" for i, node in enumerate(self.nodes)]
        lines += [
            f"d{name}/dt = {arg}" for name, arg in zip(self.variables, self.outputs, strict=True)
        ]
        return "\n".join(lines)


_FUNCTIONS = {
    sympy.sin: "sin",
    sympy.cos: "cos",
    sympy.tan: "tan",
    sympy.exp: "exp",
    sympy.log: "log",
    sympy.sinh: "sinh",
    sympy.cosh: "cosh",
    sympy.tanh: "tanh",
    sympy.asin: "asin",
    sympy.acos: "acos",
    sympy.atan: "atan",
    sympy.atan2: "atan2",
    sympy.Abs: "abs",
    sympy.sign: "sign",
}
_PAIRS = {"sin": "cos", "cos": "sin", "sinh": "cosh", "cosh": "sinh"}


class _Builder:
    def __init__(self, variables, parameters, time, conserved=()):
        self.conserved = frozenset(conserved)
        self.index = {symbol: Arg("u", i) for i, symbol in enumerate(variables)}
        self.index.update({symbol: Arg("par", j) for j, symbol in enumerate(parameters)})
        self.time = time
        self.m = len(variables)
        self.nodes: list[Node] = []
        self.keys: dict[tuple, int] = {}  # (op, args) -> node index: the sharing
        self.memo: dict[sympy.Basic, Arg] = {}

    # -- nodes ----------------------------------------------------------------------------

    def constant(self, arg: Arg) -> bool:
        if arg.kind != "u":
            return True
        if arg.value < self.m:
            return arg.value in self.conserved
        return self.nodes[arg.value - self.m].constant

    def node(self, op: str, *args: Arg, deps: tuple[int, ...] = ()) -> Arg:
        """The node ``op(*args)``, shared with an equal one already made."""
        key = (op, args)
        found = self.keys.get(key)
        if found is not None:
            return Arg("u", found)
        constant = op != "time" and all(self.constant(a) for a in args)
        if constant:
            deps = ()
        index = self.m + len(self.nodes)
        self.nodes.append(Node(op, args, deps, constant))
        self.keys[key] = index
        return Arg("u", index)

    def with_deps(self, arg: Arg, deps: tuple[int, ...]) -> None:
        position = arg.value - self.m
        node = self.nodes[position]
        if not node.constant:
            self.nodes[position] = Node(node.op, node.args, deps, node.constant)

    def pair(self, op: str, a: Arg) -> Arg:
        """sin/cos, sinh/cosh: both nodes, each the other's dependency."""
        mine = self.node(op, a)
        other = self.node(_PAIRS[op], a)
        self.with_deps(mine, (other.value,))
        self.with_deps(other, (mine.value,))
        return mine

    def add(self, a: Arg, b: Arg) -> Arg:
        if a.kind == "num" and a.value == 0.0:
            return b
        if b.kind == "num" and b.value == 0.0:
            return a
        if a.kind == b.kind == "num":
            return Arg("num", a.value + b.value)
        return self.node("add", a, b)

    def sub(self, a: Arg, b: Arg) -> Arg:
        if b.kind == "num" and b.value == 0.0:
            return a
        if a.kind == b.kind == "num":
            return Arg("num", a.value - b.value)
        if a.kind == "num" and a.value == 0.0:
            return self.neg(b)
        return self.node("sub", a, b)

    def neg(self, a: Arg) -> Arg:
        if a.kind == "num":
            return Arg("num", -a.value)
        return self.node("neg", a)

    def mul(self, a: Arg, b: Arg) -> Arg:
        if a.kind == b.kind == "num":
            return Arg("num", a.value * b.value)
        for x, y in ((a, b), (b, a)):
            if x.kind == "num":
                if x.value == 1.0:
                    return y
                if x.value == -1.0:
                    return self.neg(y)
                if x.value == 0.0:
                    return Arg("num", 0.0)
        if a == b:
            return self.node("square", a)
        return self.node("mul", a, b)

    def div(self, a: Arg, b: Arg) -> Arg:
        if b.kind == "num":
            if b.value == 0.0:
                raise NotDecomposable("the equations divide by zero")
            return (
                self.mul(a, Arg("num", 1.0 / b.value))
                if a.kind != "num"
                else Arg("num", a.value / b.value)
            )
        if self.constant(b) and not self.constant(a):  # a * (1/b): a scaling, as the kernels
            return self.mul(a, self.node("div", Arg("num", 1.0), b))
        return self.node("div", a, b)

    def integer_power(self, a: Arg, k: int) -> Arg:
        """a**k by squares and products (k >= 1)."""
        result = None
        square = a
        while k:
            if k & 1:
                result = square if result is None else self.mul(result, square)
            k >>= 1
            if k:
                square = self.mul(square, square)
        return result

    # -- expressions ----------------------------------------------------------------------

    def arg(self, expr: sympy.Basic) -> Arg:
        found = self.memo.get(expr)
        if found is None:
            found = self._arg(expr)
            self.memo[expr] = found
        return found

    def _arg(self, expr: sympy.Basic) -> Arg:
        if expr in self.index:
            return self.index[expr]
        if expr == self.time:
            return self.node("time")
        if expr.is_Symbol:
            raise NotDecomposable(f"the equations contain the unknown symbol {expr}")
        if expr.is_number and not expr.has(sympy.zoo, sympy.nan):
            value = complex(sympy.N(expr, 30))
            if value.imag != 0.0 or not math.isfinite(value.real):
                raise NotDecomposable(f"the equations contain the number {expr}, not a real one")
            return Arg("num", value.real)
        if expr.is_Add:
            return self._sum(expr.args)
        if expr.is_Mul:
            return self._product(expr.args)
        if expr.is_Pow:
            return self._power(*expr.args)
        name = _FUNCTIONS.get(expr.func)
        if name is None:
            raise NotDecomposable(
                f"{expr.func.__name__} has no Taylor recurrence here (in {expr}); the "
                f"decomposition takes {', '.join(sorted(set(_FUNCTIONS.values())))}, "
                "sums, products and powers"
            )
        args = [self.arg(a) for a in expr.args]
        if name in _PAIRS:
            return self.pair(name, args[0])
        if name in ("tan", "tanh"):
            made = self.node(name, args[0])
            if made.value >= self.m and not self.nodes[made.value - self.m].constant:
                self.with_deps(made, (self.node("square", made).value,))
            return made
        if name in ("asin", "acos"):
            a = args[0]
            w = self.node("sqrt", self.sub(Arg("num", 1.0), self.mul(a, a)))
            made = self.node(name, a)
            self.with_deps(made, (w.value,) if w.kind == "u" else ())
            return made
        if name == "atan":
            a = args[0]
            w = self.add(Arg("num", 1.0), self.mul(a, a))
            made = self.node("atan", a)
            self.with_deps(made, (w.value,) if w.kind == "u" else ())
            return made
        if name == "atan2":
            y, x = args
            w = self.add(self.mul(x, x), self.mul(y, y))
            made = self.node("atan2", y, x)
            self.with_deps(made, (w.value,) if w.kind == "u" else ())
            return made
        return self.node(name, *args)

    def _sum(self, terms) -> Arg:
        positive, negative = [], []
        offset = 0.0
        for term in terms:
            if term.is_number:
                offset += self.arg(term).value
                continue
            coefficient, rest = term.as_coeff_Mul()
            if coefficient.is_Number and coefficient.is_negative:
                negative.append(self.arg(-coefficient * rest))
            else:
                positive.append(self.arg(term))
        total = None
        for a in positive:
            total = a if total is None else self.add(total, a)
        for a in negative:
            total = self.neg(a) if total is None else self.sub(total, a)
        if total is None:
            return Arg("num", offset)
        return self.add(total, Arg("num", offset))

    def _product(self, factors) -> Arg:
        numerator, denominator = [], []
        coefficient = 1.0
        for factor in factors:
            if factor.is_number:
                coefficient *= self.arg(factor).value
                continue
            base, exponent = factor.as_base_exp()
            if exponent.is_Number and exponent.is_negative:
                denominator.append(self.arg(base) if exponent == -1 else self.arg(base**-exponent))
            else:
                numerator.append(self.arg(factor))
        top = None  # the coefficient last, so that x*y is shared by 2*x*y and x*y
        for a in numerator:
            top = a if top is None else self.mul(top, a)
        if top is None or self.constant(top):
            varying = [a for a in denominator if not self.constant(a)]
            if varying:  # a constant over a varying product: see _reciprocal
                return self._reciprocal(top, coefficient, denominator, varying)
        bottom = None
        for a in denominator:
            bottom = a if bottom is None else self.mul(bottom, a)
        if bottom is not None:
            top = self.div(Arg("num", 1.0) if top is None else top, bottom)
        return Arg("num", coefficient) if top is None else self.mul(top, Arg("num", coefficient))

    def _reciprocal(self, top, coefficient: float, denominator, varying) -> Arg:
        """``coefficient top / prod(denominator)`` with ``top`` constant (None: 1) and
        ``varying`` the denominator's varying factors: the constant ``coefficient top /
        (the constant factors)`` times the node ``1 / prod(varying)``. The quotient
        costs what ``div(top, bottom)`` did (k products an order), and every constant
        over the same varying product (k / r**2 and p_theta / (m r**2) in polar Kepler,
        p_theta conserved) shares the one reciprocal: a scaling each."""
        constant = Arg("num", coefficient)
        if top is not None:
            constant = self.mul(top, constant)
        for a in denominator:
            if self.constant(a):
                constant = self.div(constant, a)
        bottom = None
        for a in varying:
            bottom = a if bottom is None else self.mul(bottom, a)
        return self.mul(self.div(Arg("num", 1.0), bottom), constant)

    def _power(self, base, exponent) -> Arg:
        if base == sympy.E:
            return self.node("exp", self.arg(exponent))
        if exponent.is_Integer or (exponent.is_Float and float(exponent).is_integer()):
            k = int(exponent)
            if k == 0:
                return Arg("num", 1.0)
            if abs(k) > 64:
                a = self.arg(base)
                return self.node("pow", a, Arg("num", float(k)))
            powered = self.integer_power(self.arg(base), abs(k))
            return powered if k > 0 else self.div(Arg("num", 1.0), powered)
        if exponent == sympy.Rational(1, 2):
            return self.node("sqrt", self.arg(base))
        if exponent == sympy.Rational(-1, 2):
            return self.div(Arg("num", 1.0), self.node("sqrt", self.arg(base)))
        e = self.arg(exponent)
        a = self.arg(base)
        if self.constant(e):
            return self.node("pow", a, e)
        # a**e with e varying: exp(e log a)
        return self.node("exp", self.mul(e, self.node("log", a)))


def decompose(
    exprs: Sequence[sympy.Expr],
    variables: Sequence[sympy.Symbol],
    parameters: Sequence[sympy.Symbol] = (),
    time: sympy.Symbol | None = None,
    *,
    conserve: bool = False,
) -> Decomposition:
    """The Taylor decomposition of ``dy_i/dt = exprs[i]``.

    Parameters
    ----------
    exprs : sequence of sympy expressions, (m,)
        The right-hand sides, in ``variables``, ``parameters`` and ``time``.
    variables : sequence of sympy Symbols, (m,)
        The state y.
    parameters : sequence of sympy Symbols, (k,)
        Read at run time from P (k,).
    time : sympy Symbol, optional
    conserve : bool
        Treat a variable whose right-hand side is 0 as a constant (``conserved``): for
        the ODE alone, not for series of the variables given otherwise.

    Returns
    -------
    Decomposition

    Raises
    ------
    NotDecomposable
        For a function without a recurrence (named), an unknown symbol or a number
        that is not real.
    """
    from systems.expressions import as_expr

    if len(exprs) != len(variables):
        raise ValueError(f"{len(exprs)} right-hand sides for {len(variables)} variables")
    exprs = [as_expr(e) for e in exprs]
    conserved = tuple(i for i, e in enumerate(exprs) if conserve and e == 0)
    builder = _Builder(tuple(variables), tuple(parameters), time, conserved)
    outputs = tuple(builder.arg(e) for e in exprs)
    return Decomposition(
        tuple(str(v) for v in variables),
        tuple(str(p) for p in parameters),
        tuple(builder.nodes),
        outputs,
        conserved,
    )


def refusal(mechanics) -> str | None:
    """None when Hamilton's equations of ``mechanics`` can be decomposed, else why not."""
    from systems import constraints

    if constraints.constrained(mechanics.scene):
        return (
            "the scene has [constraints]: the projected motion's multipliers, contacts "
            "and impacts are not a system of ODEs a Taylor series can follow"
        )
    if mechanics.matrix_form is not None:
        return (
            "the system is in matrix form (more than four coupled coordinates): its "
            "velocities solve M(q) qdot = p - a at every evaluation, a linear solve the "
            "decomposition does not take yet"
        )
    return None


def decompose_mechanics(mechanics) -> Decomposition:
    """The Taylor decomposition of Hamilton's equations of ``mechanics`` (effects
    included), state (q, p), parameters in the scene's order, time ``mechanics.t``.

    Raises
    ------
    NotDecomposable
        With ``refusal``'s reason, or the decomposition's own.
    """
    reason = refusal(mechanics)
    if reason:
        raise NotDecomposable(reason)
    scene = mechanics.scene
    parameters = [mechanics.params[name] for name, _ in scene.parameters]
    return decompose(
        mechanics.hamilton_equations,
        (*mechanics.q, *mechanics.p),
        parameters,
        mechanics.t,
        conserve=True,
    )
