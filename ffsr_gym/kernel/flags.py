"""Flags the compiler does not specialise on: one compiled body per kernel function.

numba compiles a function once per set of argument types, and a constant ``True`` or ``False``
written in compiled code has its own type (a literal). A kernel function called with a literal
flag from one caller and a run-time flag from another was compiled twice, with all it inlines:
the closed loop's step function three times, a decision twice, and each first use of an env
paid for its own copies. :func:`runtime_flag` gives a flag its plain boolean type, so every
caller shares one compiled body (the same machine code for every flag value, the same numbers).
"""

from __future__ import annotations

from numba import types
from numba.extending import intrinsic


@intrinsic
def runtime_flag(typingctx, flag):
    """``flag`` (a boolean, literal or not) as a plain boolean."""
    if not isinstance(flag, (types.Boolean, types.BooleanLiteral)):
        return None  # not a boolean: no implementation

    def codegen(context, builder, signature, args):
        return context.cast(builder, args[0], signature.args[0], signature.return_type)

    return types.boolean(flag), codegen
