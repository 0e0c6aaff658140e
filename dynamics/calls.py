"""A compiled kernel called through its address, so that the caller does not link it.

numba links every jitted function a function calls into the caller's module and optimises
the whole module again. Called through their addresses, each kernel is compiled once for
its argument types and each caller compiles only its own code: the model-independent
integrator (`dynamics.stepping`) calls each model's derivative, so it is compiled once per
machine, not once per model; the envs' fused step (envs.fused) calls the integrator, the
runtime's kernels and the task's functions, so it no longer re-optimises them once per
task and form (measured here, CPU: the crank-slider's step 2.7 s -> 1.7 s, its LLVM module
12,500 -> 3,900 lines).

`address(kernel, signature)` compiles (or loads) the kernel for exactly `signature` and
gives the address of its machine code; a caller reads it at run time (from an array), so
numba's disk cache of the caller holds no address. `call(address, label, arguments)` calls
it with the tuple `arguments`, whose types must be those `label` (the kernel's name and
signature, or the signature alone for a kernel that returns nothing) names, and gives its
result: a caller whose arguments differ does not compile, rather than calling code
compiled for other types.
"""

from __future__ import annotations

from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

_RETURNS: dict = {}
"""label -> return type of every kernel `address` gave an address of: what `call` types
its result as (a step compiles in the process that gave the addresses it calls)."""


def text(signature) -> str:
    """The text `call` compares the arguments' types with."""
    return ", ".join(str(t) for t in signature)


def label(kernel, signature) -> str:
    """`kernel`'s name and argument types, as a caller's source names the call."""
    fn = getattr(kernel, "py_func", kernel)
    return f"{fn.__module__}.{fn.__qualname__}({text(signature)})"


def address(kernel, signature) -> int:
    """The address of `kernel`'s machine code for the argument types `signature` (numba's
    calling convention), compiled or loaded from numba's cache for them first."""
    signature = tuple(signature)
    kernel.compile(signature)
    result = kernel.overloads[signature]
    _RETURNS[label(kernel, signature)] = result.signature.return_type
    return result.library.get_pointer_to_function(result.fndesc.llvm_func_name)


@intrinsic
def call(typingctx, where, expected, arguments):
    """The result of the kernel at address `where` (int64, from `address`) called with the
    tuple `arguments`; `expected`: its `label`, a string literal, or "(types)" alone for a
    kernel that returns nothing (then no `address` need have been taken in this process)."""
    if not isinstance(where, types.Integer) or not isinstance(arguments, types.BaseTuple):
        return None
    if not isinstance(expected, types.StringLiteral):
        raise TypingError("call: the expected signature must be a string literal")
    name = expected.literal_value
    given = tuple(types.unliteral(t) for t in arguments)
    if not name.endswith(f"({text(given)})"):
        raise TypingError(f"call: arguments ({text(given)}) are not those of {name}")
    returns = types.none if name.startswith("(") else _RETURNS.get(name)
    if returns is None:
        raise TypingError(f"call: no address was taken of {name} (calls.address)")

    def codegen(context, builder, signature, args):
        fnty = context.call_conv.get_function_type(returns, given)
        fn = builder.inttoptr(args[0], fnty.as_pointer())
        values = [
            context.cast(builder, v, t, u)
            for v, t, u in zip(cgutils.unpack_tuple(builder, args[2]), arguments, given)
        ]
        status, value = context.call_conv.call_function(builder, fn, returns, given, values)
        with cgutils.if_unlikely(builder, status.is_error):
            context.call_conv.return_status_propagate(builder, status)
        return value if returns != types.none else context.get_dummy_value()

    return returns(where, expected, arguments), codegen
