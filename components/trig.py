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

The functions are compiled on their own, not inlined by numba into each caller: numba's
inlining of them into every copy of the right-hand sides made a cold compilation a
quarter longer (``rubcosim run`` on an empty cache 49 -> 63 s) for 2 % of a map's time;
LLVM still inlines what it finds worth it.

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
    from numba import types
    from numba.extending import intrinsic

    @intrinsic
    def fma(typingctx, a, b, c):  # pragma: no cover - compiled
        """``a * b + c`` rounded once (LLVM's ``llvm.fma``)."""
        sig = types.float64(types.float64, types.float64, types.float64)

        def codegen(context, builder, signature, args):
            return builder.fma(*args)

        return sig, codegen

    @njit
    def _reduce(x):
        """``(r, tail, q)``: x = q pi/2 + r + tail (mod 2 pi), |r| <= pi/4, q in 0..3."""
        k = (x * _INV_PIO2 + _ROUND) - _ROUND
        r = fma(-k, _PIO2_HI, x)  # exact: k HI is within a factor 2 of x (Sterbenz)
        p = -k * _PIO2_MID
        pe = fma(-k, _PIO2_MID, -p)  # the product's rounding error, exactly
        s = r + p
        b = s - r
        tail = ((r - (s - b)) + (p - b)) + pe  # Knuth's two-sum of r and p, plus pe
        tail = fma(-k, _PIO2_LO, tail)
        head = s + tail
        return head, (s - head) + tail, int(k) & 3

    @njit
    def _kernel_sin(x, y):
        """sin(x + y) for |x| <= pi/4, |y| < ulp(x) (fdlibm's __kernel_sin)."""
        z = x * x
        w = z * z
        r = _S2 + z * (_S3 + z * _S4) + z * w * (_S5 + z * _S6)
        v = z * x
        return x - ((z * (0.5 * y - v * r) - y) - v * _S1)

    @njit
    def _kernel_cos(x, y):
        """cos(x + y) for |x| <= pi/4, |y| < ulp(x) (fdlibm's __kernel_cos)."""
        z = x * x
        w = z * z
        r = z * (_C1 + z * (_C2 + z * _C3)) + w * w * (_C4 + z * (_C5 + z * _C6))
        hz = 0.5 * z
        w = 1.0 - hz
        return w + (((1.0 - w) - hz) + (z * r - x * y))

    @njit
    def cos(x: float) -> float:
        """cos(x) within 1 ulp of libm's."""
        if not abs(x) <= LIMIT:  # also inf and NaN
            return math.cos(x)
        r, y, q = _reduce(x)
        # one kernel: along an integration the quadrant rarely changes between calls
        v = _kernel_sin(r, y) if q & 1 else _kernel_cos(r, y)
        return -v if (q + 1) & 2 else v

    @njit
    def sin(x: float) -> float:
        """sin(x) within 1 ulp of libm's."""
        if not abs(x) <= LIMIT:
            return math.sin(x)
        if abs(x) < TINY:
            return x
        r, y, q = _reduce(x)
        v = _kernel_cos(r, y) if q & 1 else _kernel_sin(r, y)
        return -v if q & 2 else v

    @njit
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
