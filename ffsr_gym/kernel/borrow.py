"""Borrowed arrays: the kernel's time loop without reference counting.

numba reference-counts every array it copies into a variable, slices or passes to a function:
each count is an atomic add on the array's header, and it also counts every member of a tuple
passed along (the model tuple has 20 arrays, the workspace about 50). Inside the closed loop
those atomics were over half of a planner step (a 20 s ``paper`` rollout: 14.5 us per step, 6.7
without; the same numbers bit for bit), and in the batched kernel they made the threads fight
over the shared model arrays' headers.

:func:`borrowed` returns the same array (or tuple of arrays) without its owner record, so numba
skips the counting. The contract, kept by every caller in this package: the owner stays alive
for as long as the borrowed value is used (the owner is an argument of the function that
borrows, so its caller holds it), and a borrowed array is never returned, stored or boxed.
"""

from __future__ import annotations

from numba import types
from numba.core import cgutils
from numba.extending import intrinsic


def _borrow_array(context, builder, array_type, value):
    owned = context.make_array(array_type)(context, builder, value=value)
    view = context.make_array(array_type)(context, builder)
    view.meminfo = cgutils.get_null_value(view.meminfo.type)
    view.parent = cgutils.get_null_value(view.parent.type)
    view.nitems, view.itemsize, view.data = owned.nitems, owned.itemsize, owned.data
    view.shape, view.strides = owned.shape, owned.strides
    return view._getvalue()


@intrinsic
def borrowed(typingctx, value):
    """``value`` (an array, or a tuple or named tuple of arrays) without reference counting."""
    members = value.types if isinstance(value, types.BaseTuple) else (value,)
    if not all(isinstance(member, types.Array) for member in members):
        return None  # not an array or a tuple of arrays: no implementation

    def codegen(context, builder, signature, args):
        value_type, (value_in,) = signature.args[0], args
        if not isinstance(value_type, types.BaseTuple):
            return _borrow_array(context, builder, value_type, value_in)
        out = value_in
        for i, member in enumerate(value_type.types):
            item = builder.extract_value(value_in, i)
            out = builder.insert_value(out, _borrow_array(context, builder, member, item), i)
        return out

    return value(value), codegen
