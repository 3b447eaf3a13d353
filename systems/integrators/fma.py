"""``fma(x, y, z)``: x y + z with one rounding (LLVM's ``llvm.fma.f64``) for the
generated drivers (``systems.codegen.template_source`` imports it into their module):
numba has no fused multiply-add to ask for by name, and contraction (``fastmath``'s
``contract``) is a permission, not a promise. The exact error of a product, ``fma(x, y,
-(x y))``, is what double-double arithmetic is made of (``kernels._taylor_first``)."""

from numba import types
from numba.extending import intrinsic


@intrinsic
def fma(typingctx, x, y, z):
    """x y + z rounded once (float64)."""
    signature = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, sig, args):
        from llvmlite import ir
        from numba.core import cgutils

        double = ir.DoubleType()
        function_type = ir.FunctionType(double, [double, double, double])
        function = cgutils.get_or_insert_function(builder.module, function_type, "llvm.fma.f64")
        return builder.call(function, args)

    return signature, codegen
