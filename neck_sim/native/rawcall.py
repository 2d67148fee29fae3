"""A numba intrinsic that calls a C function through its raw address: how a compiled kernel calls
``neck_step_batch`` (``controllers.closed_loop`` runs the control periods between events that
way, without returning to Python).

Usage (inside an ``@njit`` / :func:`neck_sim.jit.kernel` function)::

    fatal = call_c(step.address, step.args)     # step: a neck_sim.native.FusedStep
"""

from __future__ import annotations

from numba import types
from numba.extending import intrinsic

__all__ = ["call_c"]


@intrinsic
def call_c(typingctx, address, args):
    """``int f(args...)`` called at ``address`` (an integer): a C function pointer that numba's cache
    can keep (an address baked into the code as a ctypes global would not survive the process).
    ``args`` a tuple of int32 (C int) and int64 (pointers, passed as 64-bit integers)."""
    if not (isinstance(address, types.Integer) and isinstance(args, types.BaseTuple)
            and all(t in (types.int32, types.int64) for t in args.types)):
        return None

    def codegen(context, builder, signature, llargs):
        from llvmlite import ir
        values = [builder.extract_value(llargs[1], i) for i in range(len(args.types))]
        fnty = ir.FunctionType(ir.IntType(32), [v.type for v in values])
        return builder.call(builder.inttoptr(llargs[0], fnty.as_pointer()), values)

    return types.int32(address, args), codegen
