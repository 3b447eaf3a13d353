"""A scene's functions of the state over many rows at once, four rows to a SIMD vector.

``compiled.hamiltonian(t, Y)`` over the 10 000 rows of ``run``'s output called the
scalar function once a row through the drivers' loop: 34 ns a row for the double
pendulum, nearly all of it three cosines of C's math library. Written again here over
vectors of four rows (LLVM's ``<4 x double>``), with glibc's vector math library
(libmvec: ``_ZGVdN4v_cos`` and its siblings, AVX2) for the functions, the same rows
cost about 5 ns.

The vector functions are accurate to 4 units in the last place where C's are to one,
so a row's value may differ from the scalar function's in its last bits. A function
with a node this writer lacks (a velocity solve of a system in matrix form, a function
libmvec does not have), a CPU without AVX2 and FMA, or a C library without libmvec:
``Unsupported``, and the caller keeps the scalar loop.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools

from systems import llvm_kernels
from systems.llvm_kernels import FunctionSpec, Unsupported

LANES = 4
"""Rows in one vector (AVX2's four doubles: glibc's 8-wide AVX-512 cosine measured
slower here, 1.7 against 1.05 ns a value)."""

VECTOR = {
    "llvm.sin.f64": "_ZGVdN4v_sin",
    "llvm.cos.f64": "_ZGVdN4v_cos",
    "llvm.log.f64": "_ZGVdN4v_log",
    "llvm.exp.f64": "_ZGVdN4v_exp",
    "llvm.pow.f64": "_ZGVdN4vv_pow",
    "llvm.sqrt.f64": "llvm.sqrt.v4f64",
    "llvm.fabs.f64": "llvm.fabs.v4f64",
    "llvm.copysign.f64": "llvm.copysign.v4f64",
    **{name: f"_ZGVdN4v_{name}" for name in llvm_kernels.LIBM if name != "atan2"},
    "atan2": "_ZGVdN4vv_atan2",
}
"""The scalar functions ``llvm_kernels`` calls, by the vector function called instead
(libmvec's AVX2 variants, or LLVM's own intrinsics where they are one instruction)."""


@functools.cache
def _libmvec() -> ctypes.CDLL | None:
    """glibc's vector math library, loaded into the process for LLVM's code (None where
    this CPU lacks AVX2 and FMA or the C library has no libmvec)."""
    llvm = llvm_kernels._llvm()
    features = llvm.get_host_cpu_features()
    if not (features.get("avx2") and features.get("fma")):
        return None
    path = ctypes.util.find_library("mvec")
    if path is None:
        return None
    try:
        library = ctypes.CDLL(path)
    except OSError:
        return None
    llvm.load_library_permanently(path)
    return library


class _RowsWriter(llvm_kernels._Writer):
    """``llvm_kernels._Writer`` over vectors of ``LANES`` rows: ``void name(double *t,
    double *Y, double *P, double *out, i64 groups, i64 width)``, row r of ``Y`` at
    ``Y + r width``, the rows' results at ``out + r`` (a function returning a scalar) or
    ``out + r k + i`` (one giving ``k`` values), for ``groups`` groups of ``LANES``
    rows."""

    def __init__(self, module, spec: FunctionSpec, rename: dict, symbol: str):
        from llvmlite import ir

        if spec.solve is not None or spec.pre is not None:
            raise Unsupported("a velocity solve is not written over rows")
        if spec.targets is not None or tuple(spec.arguments[:3]) != ("t", "y", "P"):
            raise Unsupported(f"{spec.name} does not take (t, y, P)")
        self.ir = ir
        self.module = module
        self.spec = spec
        self.rename = rename
        self.double = ir.DoubleType()
        self.vector = ir.VectorType(self.double, LANES)
        pointer = self.double.as_pointer()
        i64 = ir.IntType(64)
        function_type = ir.FunctionType(ir.VoidType(), [pointer] * 4 + [i64, i64])
        self.function = ir.Function(module, function_type, name=symbol)
        for argument, name in zip(
            self.function.args, ("t", "Y", "P", "out", "groups", "width"), strict=True
        ):
            argument.name = name
            if name in ("t", "Y", "P", "out"):
                argument.add_attribute("noalias")
        self.names: dict[str, object] = {}
        self.memo: dict = {}

    def const(self, value: float):
        return self.ir.Constant(self.vector, [self.ir.Constant(self.double, float(value))] * LANES)

    def _call(self, name: str, args: list):
        vector = VECTOR.get(name)
        if vector is None:
            raise Unsupported(f"no vector function for {name}")
        if not vector.startswith("llvm.") and not hasattr(_libmvec(), vector):
            raise Unsupported(f"this C library has no {vector}")
        function = self.module.globals.get(vector)
        if function is None:
            function_type = self.ir.FunctionType(self.vector, [self.vector] * len(args))
            function = self.ir.Function(self.module, function_type, name=vector)
        return self.b.call(function, args)

    def write(self) -> None:
        ir = self.ir
        i64 = ir.IntType(64)
        t, Y, P, out, groups, width = self.function.args
        entry = self.function.append_basic_block("entry")
        loop = self.function.append_basic_block("loop")
        done = self.function.append_basic_block("done")
        b = self.b = ir.IRBuilder(entry)
        b.cbranch(b.icmp_signed(">", groups, ir.Constant(i64, 0)), loop, done)
        b.position_at_end(loop)
        group = b.phi(i64, name="group")
        row = b.mul(group, ir.Constant(i64, LANES), name="row")
        rows = [b.add(row, ir.Constant(i64, j)) for j in range(LANES)]
        starts = [b.gep(Y, [b.mul(r, width)]) for r in rows]
        vector_pointer = self.vector.as_pointer()
        for symbol, argument, index in self.spec.bindings:
            if argument == "t" and index is None:
                value = b.load(b.bitcast(b.gep(t, [row]), vector_pointer), align=8)
            elif argument == "y":
                value = ir.Constant(self.vector, ir.Undefined)
                for j, start in enumerate(starts):
                    element = b.load(b.gep(start, [ir.Constant(i64, index)]))
                    value = b.insert_element(value, element, ir.Constant(ir.IntType(32), j))
            elif argument == "P":
                scalar = b.load(b.gep(P, [ir.Constant(i64, index)]))
                value = ir.Constant(self.vector, ir.Undefined)
                for j in range(LANES):
                    value = b.insert_element(value, scalar, ir.Constant(ir.IntType(32), j))
            else:
                raise Unsupported(f"a binding to {argument}[{index}] is not written over rows")
            self.names[symbol] = value
        results = self._phase(self.spec.exprs, None)
        if self.spec.returns:
            b.store(results[0], b.bitcast(b.gep(out, [row]), vector_pointer), align=8)
        else:
            k = ir.Constant(i64, len(results))
            ends = [b.gep(out, [b.mul(r, k)]) for r in rows]
            for i, value in enumerate(results):
                for j, end in enumerate(ends):
                    element = b.extract_element(value, ir.Constant(ir.IntType(32), j))
                    b.store(element, b.gep(end, [ir.Constant(i64, i)]))
        following = b.add(group, ir.Constant(i64, 1))
        group.add_incoming(ir.Constant(i64, 0), entry)
        group.add_incoming(following, loop)
        b.cbranch(b.icmp_signed("<", following, groups), loop, done)
        b.position_at_end(done)
        b.ret_void()


def symbol(name: str) -> str:
    """The name of ``name``'s function over rows in the written module."""
    return f"{name}_rows"


def write_ir(specs: list[FunctionSpec], rename: dict) -> str:
    """The IR text of ``specs``' functions over rows (``symbol(name)`` each).

    Raises
    ------
    Unsupported
        As ``llvm_kernels.write_ir``, and where vectors of rows cannot be written (the
        module docstring says when).
    """
    if llvm_kernels.symengine is None:
        raise Unsupported("symengine is not installed")
    if _libmvec() is None:
        raise Unsupported("no libmvec, or a CPU without AVX2 and FMA")
    from llvmlite import ir

    module = ir.Module(name="pe_rows")
    for spec in specs:
        _RowsWriter(module, spec, rename, symbol(spec.name)).write()
    return str(module)


class Rows:
    """Machine code of ``write_ir``'s text: ``rows(name, t, Y, P, out)`` calls function
    ``name`` over every row (``t`` (N,), ``Y`` (N, m) and ``out`` (N,) or (N, k), all
    C-contiguous float64, ``N`` a multiple of ``LANES``)."""

    def __init__(self, text: str, names: list[str]):
        if _libmvec() is None:  # a text from the disk: the library is loaded here
            raise Unsupported("no libmvec, or a CPU without AVX2 and FMA")
        # host=True: the vector functions are AVX2's, this CPU's
        kernels = llvm_kernels.LLVMKernels(text, (), host=True)
        prototype = ctypes.CFUNCTYPE(None, *[ctypes.c_void_p] * 4, ctypes.c_int64, ctypes.c_int64)
        self._kernels = kernels  # owns the machine code
        self.names = frozenset(names)
        self.lanes = LANES
        self._functions = {name: prototype(kernels.address(symbol(name))) for name in names}

    def __call__(self, name: str, t, Y, P, out) -> None:
        groups, remainder = divmod(len(Y), LANES)
        if remainder:
            raise ValueError(f"rows come in groups of {LANES}, not {len(Y)}")
        self._functions[name](
            t.ctypes.data, Y.ctypes.data, P.ctypes.data, out.ctypes.data, groups, Y.shape[1]
        )
