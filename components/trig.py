"""Cosine and sine of a forcing phase, at about twice libm's speed, within 1 ulp of it.

A forced oscillator or an unbalanced rotor evaluates ``cos(w t)`` at every
right-hand side; libm's ``cos`` (glibc's ``__cos_fma``) was a quarter of the
time of a one-period map of Feng & Yang's oscillator.  Here the phase is
reduced by pi/2 in double-double arithmetic (Cody and Waite with a fused
multiply-add: ``x - k pi/2`` to about 2**-100 relative to ``x``, so that a
phase next to a zero of cos keeps all its digits), then fdlibm's kernels
(FreeBSD ``k_cos.c`` and ``k_sin.c``, degree 14 and 13 on [-pi/4, pi/4], with
the reduction's tail) give the result.  Measured against libm over
[-1e6, 1e6] and next to the multiples of pi/2: at most 1 ulp apart, equal for
97 % of arguments (``tests/test_trig.py``).  Beyond ``LIMIT`` in magnitude, and
for inf and NaN, libm's own functions are used.

Without numba (the kernels bundled in an FMU run as plain Python) these are
``math.cos`` and ``math.sin``: an FMU and the reference then differ by at most
an ulp in the forcing, far below any tolerance.
"""

from __future__ import annotations

import math

from .jit import USE_NUMBA, njit

LIMIT = 1.0e6  # |x| up to here: k = round(x 2 / pi) < 2**20, the reduction's range
TINY = 2.0**-27  # below: sin x = x and cos x = 1, correctly rounded (and sin(-0) = -0)
_INV_PIO2 = 0.6366197723675814  # 2 / pi
# pi/2 = HI + MID + LO to about 2**-160 (each the double nearest the rest)
_PIO2_HI = 1.5707963267948966
_PIO2_MID = 6.123233995736766e-17
_PIO2_LO = -1.4973849048591698e-33
_ROUND = 6755399441055744.0  # 1.5 * 2**52: adding and subtracting it rounds to an integer
# fdlibm's minimax coefficients (FreeBSD msun k_sin.c, k_cos.c)
_S1 = -1.66666666666666324348e-01
_S2 = 8.33333333332248946124e-03
_S3 = -1.98412698298579493134e-04
_S4 = 2.75573137070700676789e-06
_S5 = -2.50507602534068634195e-08
_S6 = 1.58969099521155010221e-10
_C1 = 4.16666666666666019037e-02
_C2 = -1.38888888888741095749e-03
_C3 = 2.48015872894767294178e-05
_C4 = -2.75573143513906633035e-07
_C5 = 2.08757232129817482790e-09
_C6 = -1.13596475577881948265e-11

if USE_NUMBA:
    from llvmlite import ir
    from numba import types
    from numba.extending import intrinsic

    @intrinsic
    def fma(typingctx, a, b, c):  # pragma: no cover - compiled
        """``a * b + c`` rounded once (LLVM's ``llvm.fma``)."""
        sig = types.float64(types.float64, types.float64, types.float64)

        def codegen(context, builder, signature, args):
            return builder.fma(*args)

        return sig, codegen

    # The reduction and the kernels are written as LLVM instructions (numba intrinsics):
    # they go into every caller as they are, like an inlined function, without numba
    # typing them again at each of the many copies of the right-hand sides (inlining
    # them through numba made a cold compilation a quarter longer; calling them
    # instead cost 3 % of a map).  The operations, and their order, are those of the
    # formulas in the docstrings: the results are the same, bit for bit
    # (tests/test_trig.py checks them against a plain numba version).
    _F64 = ir.DoubleType()

    def _const(v: float) -> ir.Constant:
        return ir.Constant(_F64, v)

    @intrinsic
    def _reduce(typingctx, x):  # pragma: no cover - compiled
        """``(r, tail, q)``: x = q pi/2 + r + tail (mod 2 pi), |r| <= pi/4, q in 0..3:
        k = (x 2/pi + ROUND) - ROUND; r = fma(-k, HI, x) (exact, Sterbenz);
        p = -k MID; pe = fma(-k, MID, -p) (p's rounding error); Knuth's two-sum of r and
        p, plus pe, plus fma(-k, LO, .) makes the tail; q = int(k) & 3."""
        sig = types.Tuple((types.float64, types.float64, types.int64))(types.float64)

        def codegen(context, b, signature, args):
            (x,) = args
            k = b.fsub(b.fadd(b.fmul(x, _const(_INV_PIO2)), _const(_ROUND)), _const(_ROUND))
            nk = b.fneg(k)
            r = b.fma(nk, _const(_PIO2_HI), x)
            p = b.fmul(nk, _const(_PIO2_MID))
            pe = b.fma(nk, _const(_PIO2_MID), b.fneg(p))
            s = b.fadd(r, p)
            bb = b.fsub(s, r)
            tail = b.fadd(b.fadd(b.fsub(r, b.fsub(s, bb)), b.fsub(p, bb)), pe)
            tail = b.fma(nk, _const(_PIO2_LO), tail)
            head = b.fadd(s, tail)
            low = b.fadd(b.fsub(s, head), tail)
            q = b.and_(b.fptosi(k, ir.IntType(64)), ir.Constant(ir.IntType(64), 3))
            return context.make_tuple(b, signature.return_type, [head, low, q])

        return sig, codegen

    @intrinsic
    def _kernel_sin(typingctx, x, y):  # pragma: no cover - compiled
        """sin(x + y) for |x| <= pi/4, |y| < ulp(x) (fdlibm's __kernel_sin):
        z = x x; w = z z; r = S2 + z (S3 + z S4) + z w (S5 + z S6); v = z x;
        x - ((z (0.5 y - v r) - y) - v S1)."""
        sig = types.float64(types.float64, types.float64)

        def codegen(context, b, signature, args):
            x, y = args
            add, sub, mul = b.fadd, b.fsub, b.fmul
            z = mul(x, x)
            w = mul(z, z)
            r = add(
                add(_const(_S2), mul(z, add(_const(_S3), mul(z, _const(_S4))))),
                mul(mul(z, w), add(_const(_S5), mul(z, _const(_S6)))),
            )
            v = mul(z, x)
            inner = sub(mul(z, sub(mul(_const(0.5), y), mul(v, r))), y)
            return sub(x, sub(inner, mul(v, _const(_S1))))

        return sig, codegen

    @intrinsic
    def _kernel_cos(typingctx, x, y):  # pragma: no cover - compiled
        """cos(x + y) for |x| <= pi/4, |y| < ulp(x) (fdlibm's __kernel_cos):
        z = x x; w = z z; r = z (C1 + z (C2 + z C3)) + w w (C4 + z (C5 + z C6));
        hz = 0.5 z; u = 1 - hz; u + (((1 - u) - hz) + (z r - x y))."""
        sig = types.float64(types.float64, types.float64)

        def codegen(context, b, signature, args):
            x, y = args
            add, sub, mul = b.fadd, b.fsub, b.fmul
            z = mul(x, x)
            w = mul(z, z)
            r = add(
                mul(z, add(_const(_C1), mul(z, add(_const(_C2), mul(z, _const(_C3)))))),
                mul(mul(w, w), add(_const(_C4), mul(z, add(_const(_C5), mul(z, _const(_C6)))))),
            )
            hz = mul(_const(0.5), z)
            u = sub(_const(1.0), hz)
            return add(u, add(sub(sub(_const(1.0), u), hz), sub(mul(z, r), mul(x, y))))

        return sig, codegen

    @njit(inline="always")
    def cos(x: float) -> float:
        """cos(x) within 1 ulp of libm's."""
        if not abs(x) <= LIMIT:  # also inf and NaN
            return math.cos(x)
        r, y, q = _reduce(x)
        # one kernel: along an integration the quadrant rarely changes between calls
        v = _kernel_sin(r, y) if q & 1 else _kernel_cos(r, y)
        return -v if (q + 1) & 2 else v

    @njit(inline="always")
    def sin(x: float) -> float:
        """sin(x) within 1 ulp of libm's."""
        if not abs(x) <= LIMIT:
            return math.sin(x)
        if abs(x) < TINY:
            return x
        r, y, q = _reduce(x)
        v = _kernel_cos(r, y) if q & 1 else _kernel_sin(r, y)
        return -v if q & 2 else v

    @njit(inline="always")
    def cos_sin(x: float) -> tuple[float, float]:
        """(cos(x), sin(x)), each within 1 ulp of libm's, from one reduction."""
        if not abs(x) <= LIMIT:
            return math.cos(x), math.sin(x)
        if abs(x) < TINY:
            return 1.0, x
        r, y, q = _reduce(x)
        s = _kernel_sin(r, y)
        c = _kernel_cos(r, y)
        if q & 1:
            s, c = c, s
        return (-c if (q + 1) & 2 else c), (-s if q & 2 else s)

else:
    cos = math.cos
    sin = math.sin

    def cos_sin(x: float) -> tuple[float, float]:
        return math.cos(x), math.sin(x)
