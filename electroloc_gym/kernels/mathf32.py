"""Float32 ``exp``/``log`` and fixed-order sums: the only transcendental and reduction steps of the filter.

Why these exist (docs/design.md, "Results that do not depend on the CPU"): numpy's SIMD ``exp``, ``log``
and ``pow`` differ between CPUs, and between the SIMD body and the scalar tail of one array, in the
last bit; ``np.sum`` adds in an order that depends on the array's length and layout. These are
branch-free polynomials (Cephes' ``expf``/``logf``) and sums in a fixed order, made only of
additions, multiplications and comparisons, each correctly rounded by IEEE 754: a vectorised loop
and a scalar one give the same bits, on every CPU. numba compiles without ``fastmath``, so LLVM
neither reassociates nor fuses ``a*b + c`` into an FMA.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit
from numba.core import types
from numba.extending import intrinsic

__all__ = ["JIT", "exp32", "log32", "exp_f32", "log_f32", "sum8", "row_sums"]

#: Options of every kernel: cached on disk (compiled once per machine), no GIL, numpy's error model.
JIT = {"cache": True, "nogil": True, "error_model": "numpy"}

_F32_HALF = np.float32(0.5)


@intrinsic
def _pow2(typingctx, n):  # pragma: no cover - compiled
    """2**n as float32 for a float32 integer value n in [−126, 127] (built from the exponent bits)."""
    if n != types.float32:
        return None

    def codegen(context, builder, signature, args):
        i32 = ir.IntType(32)
        e = builder.add(builder.fptosi(args[0], i32), ir.Constant(i32, 127))
        return builder.bitcast(builder.shl(e, ir.Constant(i32, 23)), ir.FloatType())

    return types.float32(types.float32), codegen


@intrinsic
def _frexp32(typingctx, x):  # pragma: no cover - compiled
    """(f, e), both float32, with x = f·2**e and f in [0.5, 1), for a normal float32 x > 0 (bit fields)."""
    if x != types.float32:
        return None
    sig = types.UniTuple(types.float32, 2)(types.float32)

    def codegen(context, builder, signature, args):
        i32 = ir.IntType(32)
        bits = builder.bitcast(args[0], i32)
        f = builder.or_(builder.and_(bits, ir.Constant(i32, 0x007FFFFF)), ir.Constant(i32, 0x3F000000))
        e = builder.and_(builder.lshr(bits, ir.Constant(i32, 23)), ir.Constant(i32, 0xFF))
        return context.make_tuple(
            builder,
            signature.return_type,
            (builder.bitcast(f, ir.FloatType()), builder.sitofp(builder.sub(e, ir.Constant(i32, 126)), ir.FloatType())),
        )

    return sig, codegen


_F = np.float32
_ONE = _F(1.0)
_ZERO = _F(0.0)
_INF = _F(np.inf)
_NAN = _F(np.nan)
_LN2_HI = _F(0.693359375)  # ln 2 = _LN2_HI + _LN2_LO (Cody–Waite)
_LN2_LO = _F(-2.12194440e-4)
_LOG2E = _F(1.44269504088896341)
_EXP_MAX = _F(88.72283)  # exp(x) overflows above
_EXP_MIN = _F(-103.972084)  # exp(x) < 2**−150 below: 0
_E0, _E1, _E2, _E3, _E4, _E5 = (
    _F(1.9875691500e-4),
    _F(1.3981999507e-3),
    _F(8.3334519073e-3),
    _F(4.1665795894e-2),
    _F(1.6666665459e-1),
    _F(5.0000001201e-1),
)
_SQRT_HALF = _F(0.707106781186547524)
_L0, _L1, _L2, _L3, _L4, _L5, _L6, _L7, _L8 = (
    _F(7.0376836292e-2),
    _F(-1.1514610310e-1),
    _F(1.1676998740e-1),
    _F(-1.2420140846e-1),
    _F(1.4249322787e-1),
    _F(-1.6668057665e-1),
    _F(2.0000714765e-1),
    _F(-2.4999993993e-1),
    _F(3.3333331174e-1),
)
_F32_MIN_NORMAL = _F(1.17549435e-38)
_TWO23 = _F(8388608.0)
_TWENTY3 = _F(23.0)


@njit(inline="always")
def exp32(x):  # pragma: no cover - compiled
    """The exponential of a float32, within 1 ulp; exact 1 at 0, 0 below −103.97, inf above 88.72, NaN for NaN.

    Cephes' ``expf``: x = n·ln 2 + r (|r| ≤ ½ ln 2, Cody–Waite), a degree-6 polynomial in r, times
    2**n applied as two exactly representable factors (so the subnormal range rounds once). Branch
    free, so loops over it vectorise.
    """
    xc = x if x > _EXP_MIN else _EXP_MIN
    xc = xc if xc < _EXP_MAX else _EXP_MAX
    n = np.floor(_LOG2E * xc + _F32_HALF)
    r = (xc - n * _LN2_HI) - n * _LN2_LO
    p = (((((_E0 * r + _E1) * r + _E2) * r + _E3) * r + _E4) * r + _E5) * (r * r) + r + _ONE
    n1 = np.floor(n * _F32_HALF)
    y = (p * _pow2(n1)) * _pow2(n - n1)  # pyright: ignore[reportCallIssue]  # numba's @intrinsic supplies typingctx
    y = y if x > _EXP_MIN else _ZERO
    y = y if x < _EXP_MAX else _INF
    return y if x == x else x


@njit(inline="always")
def log32(x):  # pragma: no cover - compiled
    """Natural log of a float32, within 1 ulp; −inf at 0, NaN below 0 or for NaN, inf at inf.

    Cephes' ``logf``: x = f·2**e with f in [√½, √2), a degree-9 polynomial in f − 1, plus e·ln 2
    (Cody–Waite). Subnormals are scaled by 2**23 first. Branch free, so loops over it vectorise.
    """
    small = x < _F32_MIN_NORMAL
    xs = x * _TWO23 if small else x
    f, e = _frexp32(xs)  # pyright: ignore[reportCallIssue]  # numba's @intrinsic supplies typingctx
    e = e - (_TWENTY3 if small else _ZERO)
    low = f < _SQRT_HALF
    e = e - _ONE if low else e
    f = (f + f - _ONE) if low else (f - _ONE)
    z = f * f
    y = ((((((((_L0 * f + _L1) * f + _L2) * f + _L3) * f + _L4) * f + _L5) * f + _L6) * f + _L7) * f + _L8) * f * z
    y = y + _LN2_LO * e
    y = y - _F32_HALF * z
    r = (f + y) + _LN2_HI * e
    r = r if x > _ZERO else (-_INF if x == _ZERO else _NAN)
    return r if x < _INF else x


@njit(**JIT)
def exp_f32(x, out):  # pragma: no cover - compiled
    """``out[i] = exp32(x[i])`` over 1-D float32 arrays (in place works, but only a separate ``out`` vectorises)."""
    for i in range(x.shape[0]):
        out[i] = exp32(x[i])


@njit(**JIT)
def log_f32(x, out):  # pragma: no cover - compiled
    """``out[i] = log32(x[i])`` over 1-D float32 arrays (in place works, but only a separate ``out`` vectorises)."""
    for i in range(x.shape[0]):
        out[i] = log32(x[i])


@njit(inline="always")
def sum8(x):  # pragma: no cover - compiled
    """Sum of a 1-D float64 array in a fixed order: eight interleaved partial sums, combined pairwise,
    then the remainder — the same bits on every machine, and ~4× faster than one running sum.
    """
    m = x.shape[0]
    m8 = m - m % 8
    a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = 0.0
    for i in range(0, m8, 8):
        a0 += x[i]
        a1 += x[i + 1]
        a2 += x[i + 2]
        a3 += x[i + 3]
        a4 += x[i + 4]
        a5 += x[i + 5]
        a6 += x[i + 6]
        a7 += x[i + 7]
    s = ((a0 + a1) + (a2 + a3)) + ((a4 + a5) + (a6 + a7))
    for i in range(m8, m):
        s += x[i]
    return s


@njit(**JIT)
def row_sums(w, out):  # pragma: no cover - compiled
    """``out[e] = sum8(w[e])`` for a (k, M) float64 array: the weights' normalising sums."""
    for e in range(w.shape[0]):
        out[e] = sum8(w[e])
