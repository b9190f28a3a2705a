"""One cell of the fast engine, compiled: its state (:data:`STATE`), the
closed-form advance over silent steps (:func:`advanced`) and the bound that
lets a cell be parked (:func:`safe`), and the processor's cycle counter
that the loops read per phase of a step when told to (:data:`PHASES`)."""

from __future__ import annotations

import os

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

#: one cell's state (32 bytes, one half cache line): ``spike`` holds the step
#: of its last spike (plus one) in its low bits (:data:`SPIKE_STEP`) and
#: whether the cell is active in its sign bit (:data:`ACTIVE`)
STATE = np.dtype([("v", "f8"), ("e", "f8"), ("i", "f8"), ("last", "i4"), ("spike", "i4")], align=True)
SPIKE_STEP = 0x7FFFFFFF
ACTIVE = -0x80000000
#: array indices are converted to this unsigned type in the hot loops: numba
#: then skips its negative-index handling, which otherwise doubles their cost
U = np.uint64
#: a 64-bit word of ones (the marks of cells that received input are bits)
FULL = np.uint64(0xFFFFFFFFFFFFFFFF)
#: whether the loops add up the processor's cycle counter per phase of a step
#: (:data:`.deliver.PHASE_NAMES`), set by ``SNN_FG_ENGINE_PHASES=1`` before the
#: engine is imported (``experiments/bench/phases.py``). numba compiles the flag
#: in as a constant: off, the counting is compiled away; the cached code is
#: dropped when it changes (:func:`.compiled.drop_stale_caches`)
PHASES = os.environ.get("SNN_FG_ENGINE_PHASES", "") == "1"


@intrinsic
def prefetch(typingctx, arr, idx):
    """Ask the CPU to bring ``arr[idx]`` into cache, to be written (LLVM's
    ``prefetch`` intrinsic: a hint, with no effect on any result)."""

    def codegen(context, builder, signature, args):
        aty = signature.args[0]
        ary = context.make_array(aty)(context, builder, args[0])
        ptr = cgutils.get_item_pointer2(
            context,
            builder,
            data=ary.data,
            shape=cgutils.unpack_tuple(builder, ary.shape),
            strides=cgutils.unpack_tuple(builder, ary.strides),
            layout=aty.layout,
            inds=[args[1]],
            wraparound=False,
            boundscheck=False,
        )
        i8p, i32 = ir.IntType(8).as_pointer(), ir.IntType(32)
        # (the name without its pointer-type suffix: LLVM renames it to its own
        # version's, p0i8 before opaque pointers and p0 after)
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32]), "llvm.prefetch"
        )
        # (address, 1: for writing, 3: keep in every cache level, 1: data)
        builder.call(fn, [builder.bitcast(ptr, i8p), ir.Constant(i32, 1), ir.Constant(i32, 3), ir.Constant(i32, 1)])
        return context.get_dummy_value()

    return types.void(arr, idx), codegen


@intrinsic
def borrowed(typingctx, arr):
    """``arr`` as a view that does not count references to its memory.

    numba counts the references to an array's memory with atomic operations,
    each time the array is passed to a function: in the engine's loops, two
    per array per call, a few percent of a run's time, and with two threads
    the counter's cache line travels between the cores. A borrowed view
    skips them (numba checks for its missing counter); it must not outlive
    ``arr``, which its caller holds."""
    if not isinstance(arr, types.Array):
        return None

    def codegen(context, builder, signature, args):
        aryty = signature.args[0]
        src = context.make_array(aryty)(context, builder, args[0])
        dst = context.make_array(aryty)(context, builder)
        for field in ("data", "shape", "strides", "itemsize", "nitems"):
            setattr(dst, field, getattr(src, field))
        dst.meminfo = cgutils.get_null_value(dst.meminfo.type)
        dst.parent = cgutils.get_null_value(dst.parent.type)
        return dst._getvalue()

    return arr(arr), codegen


@intrinsic
def trailing_zeros(typingctx, x):
    """The number of trailing zero bits of the ``uint64`` ``x`` (LLVM's
    ``cttz``: one instruction; 64 for 0)."""

    def codegen(context, builder, signature, args):
        i64, i1 = ir.IntType(64), ir.IntType(1)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(i64, [i64, i1]), "llvm.cttz.i64")
        return builder.call(fn, [args[0], ir.Constant(i1, 0)])

    return types.uint64(types.uint64), codegen


@intrinsic
def ones(typingctx, x):
    """The number of one bits of the ``uint64`` ``x`` (LLVM's ``ctpop``)."""

    def codegen(context, builder, signature, args):
        i64 = ir.IntType(64)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(i64, [i64]), "llvm.ctpop.i64")
        return builder.call(fn, [args[0]])

    return types.int64(types.uint64), codegen


@njit(cache=True, inline="always")
def low_bits(n):
    """A ``uint64`` with its ``n`` lowest bits set (``0 <= n <= 64``)."""
    return FULL >> U(64 - n) if n > 0 else U(0)


@njit(cache=True, inline="always")
def divide(x, d, inverse):
    """``(x // d, x % d)`` for ``0 <= x < 2**40`` and ``d >= 1``, by
    multiplying with ``inverse = 1 / d`` (a division takes tens of cycles)."""
    q = np.int64(x * inverse)
    r = x - q * d
    if r < 0:
        q -= 1
        r += d
    elif r >= d:
        q += 1
        r -= d
    return q, r


@njit(cache=True, inline="always")
def advanced(v, e, i, v_rest, adv_row, k):
    """``(v, I_exc, I_inh)`` after ``k`` silent steps (``adv_row``: the
    advance tables of the cell's neuron type)."""
    kmax = adv_row.shape[1] - 1
    while k > 0:
        s = k if k <= kmax else kmax
        v = v_rest + ((adv_row[0, s] * (v - v_rest) + e * adv_row[3, s]) - i * adv_row[4, s])
        e = e * adv_row[1, s]
        i = i * adv_row[2, s]
        k -= s
    return v, e, i


@njit(cache=True, inline="always")
def safe(v, e, i, v_rest, tight, peak, gap):
    """Whether a cell in this state cannot reach threshold without new input
    (``v_rest``, ``tight``, ``peak``, ``gap``: its neuron type's, see
    :mod:`.neurons`; scalars, so that calling it costs no reference counting).

    With ``u = v - v_rest`` and no input, ``u_k = d_m^k u + e P_e(k) - i
    P_i(k)``, where ``0 <= P_e(k) <= min(1 - d_m^k, peak)``. If the
    inhibitory current decays no faster than the excitatory one
    (``TIGHT``), ``P_i >= P_e`` and ``i >= 0`` let the inhibition be
    subtracted: ``u_k <= d_m^k u + x P_e(k)`` with ``x = max(e - i, 0)``,
    which is at most ``max(u, x)`` and at most ``max(u, 0) + peak x``.
    Otherwise ``u_k <= max(u, e^+ + i^-)``.
    """
    u = v - v_rest
    if tight and i >= 0:
        x = max(e - i, 0.0)
        return (max(u, x) <= gap) | (max(u, 0.0) + peak * x <= gap)  # (the min of the two bounds, no branch)
    return max(u, max(e, 0.0) + max(-i, 0.0)) <= gap


@intrinsic
def cycles(typingctx):
    """The processor's cycle counter (LLVM's ``readcyclecounter``: ``rdtsc``
    on x86-64, which ticks at a constant rate whatever the core's clock;
    other processors may not let a program read it, so the phases are
    counted on x86-64 only)."""

    def codegen(context, builder, signature, args):
        i64 = ir.IntType(64)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(i64, []), "llvm.readcyclecounter")
        return builder.call(fn, [])

    return types.int64(), codegen
