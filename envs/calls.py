"""A compiled kernel called through its address, so that the caller does not link it.

numba links every jitted function a function calls into the caller's module and optimises
the whole module again: the fused step (envs.fused) re-optimised the model's integrator at
every compilation, once per task and form. Called through its address, the integrator is
compiled once per model and argument types, and each step compiles only the rest (measured
here: the disk's step 2.1-2.5 s of CPU against 2.9 s, the arm's 1.8-1.9 against 2.1-2.3;
the step runs as fast: the integrator was not inlined into it before either).

`address(kernel, signature)` compiles (or loads) the kernel for exactly `signature` and
gives the address of its machine code; the step reads it from its integer constants at
run time, so numba's disk cache of the step holds no address. `call(address, expected,
arguments)` calls it with the tuple `arguments`, whose types must be `expected` (the
signature's text, written into the step's source): a step whose arguments differ does not
compile, rather than calling code compiled for other types.
"""

from __future__ import annotations

from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic


def text(signature) -> str:
    """The text `call` compares the arguments' types with."""
    return ", ".join(str(t) for t in signature)


def address(kernel, signature) -> int:
    """The address of `kernel`'s machine code for the argument types `signature` (numba's
    calling convention), compiled or loaded from numba's cache for them first."""
    signature = tuple(signature)
    kernel.compile(signature)
    result = kernel.overloads[signature]
    return result.library.get_pointer_to_function(result.fndesc.llvm_func_name)


@intrinsic
def call(typingctx, where, expected, arguments):
    """Call the kernel at address `where` (int64, from `address`) with the tuple
    `arguments` (the kernel returns nothing); `expected`: `text` of its signature."""
    if not isinstance(where, types.Integer) or not isinstance(arguments, types.BaseTuple):
        return None
    if not isinstance(expected, types.StringLiteral):
        raise TypingError("call: the expected signature must be a string literal")
    given = tuple(types.unliteral(t) for t in arguments)
    if text(given) != expected.literal_value:
        raise TypingError(
            f"call: arguments ({text(given)}) are not the kernel's ({expected.literal_value})"
        )

    def codegen(context, builder, signature, args):
        fnty = context.call_conv.get_function_type(types.none, given)
        fn = builder.inttoptr(args[0], fnty.as_pointer())
        values = [
            context.cast(builder, v, t, u)
            for v, t, u in zip(cgutils.unpack_tuple(builder, args[2]), arguments, given)
        ]
        status, _ = context.call_conv.call_function(builder, fn, types.none, given, values)
        with cgutils.if_unlikely(builder, status.is_error):
            context.call_conv.return_status_propagate(builder, status)
        return context.get_dummy_value()

    return types.none(where, expected, arguments), codegen
