"""Elementary functions that give the same bits on every platform, for the C FMU.

The C library's ``exp``, ``expm1``, ``log``, ``log1p``, ``sin``, ``cos`` and ``pow`` are
accurate to about an ulp, but not the same ulp everywhere: glibc picks an FMA variant on CPUs
that have one, Windows' C runtime has its own implementations, and results differ in the last
bit for a tenth of ``exp``'s arguments. A plant simulated over thousands of samples carries
those bits into its level (1e-10 mm between a Linux and a Windows build of the same FMU).

The functions below use only IEEE 754's basic operations (``+ - * /``, each correctly rounded
on every conforming platform), ``floor``, ``fmod`` and ``ldexp`` (exact), so with
``-ffp-contract=off`` they compute the same bits wherever the FMU runs. They are written once
here, in the subset :mod:`gatetwin.plant.ast_render` translates, and rendered into the C FMU's
``elementary.c``; the C renderings of :mod:`gatetwin.plant.blocks` and
:mod:`gatetwin.plant.physical_kernel` call them in place of the C library's. The Python
reference, numba and the pythonfmu slave keep the platform's ``math`` (fast; these run in pure
Python at microseconds a call): the two agree to a few ulp a call, well within the renderings'
tolerance. ``tests/test_elementary.py`` holds this module equal to its C rendering to the bit,
the C rendering built for other platforms equal to the host's to the bit, and the accuracy
below against 200-bit arithmetic (which a wrong constant would fail).

Method (textbook, no tables): argument reduction by a constant split in a high part with
trailing zero bits (so ``k * HI`` is exact) and a low part; a Taylor polynomial on the reduced
range, evaluated by Horner's rule, with enough terms that truncation is below a tenth of an
ulp; scaling by ``ldexp``. Accuracy over the arguments the plants use and far beyond (the
tests' ranges): ``exp``, ``log``, ``sin``, ``cos`` within 2 ulp of the exact value;
``expm1`` and ``log1p`` within 4; ``pow`` (``exp(y log x)``, positive ``x`` only) within
``2 + 2.5 |y log x|`` ulp (the plants raise a pole near 1 to a power near 1: ``|y log x|``
below 0.1). Standard library only, no gatetwin imports.
"""

from __future__ import annotations

import math

__all__ = [
    "RENDERED_C",
    "REPLACED",
    "cos",
    "exp",
    "expm1",
    "log",
    "log1p",
    "math_calls",
    "pow",
    "sin",
]

#: The ``math`` functions these replace in the C renderings (``pow`` also for ``**``).
REPLACED = ("exp", "expm1", "log", "log1p", "sin", "cos", "pow")
#: The functions rendered into ``elementary.c`` (prefix ``gt_``).
RENDERED_C = (*REPLACED, "_sin_reduced", "_cos_reduced", "_quadrant_value")


def math_calls(prefix: str) -> dict[str, str]:
    """``math`` name -> C name of its replacement (for ``ast_render.c_module``)."""
    return {name: prefix + name for name in REPLACED}


def exp(x: float) -> float:
    """``e**x``: ``x = k ln2 + r`` with ``|r| <= ln2 / 2``, degree-13 Taylor in ``r``."""
    if x != x:
        return x
    if x > 709.782712893384:  # ln(DBL_MAX)
        return math.inf
    if x < -745.1332191019412:  # ln of half the smallest subnormal
        return 0.0
    k = math.floor(x * 1.4426950408889634 + 0.5)  # 1 / ln2
    # ln2 = 0.6931471803691238 (32 significant bits, k * it exact) + 1.9082149292705877e-10
    r = (x - k * 0.6931471803691238) - k * 1.9082149292705877e-10
    # Horner's rule on 1 / n!, n = 13 down to 0
    p = 1.6059043836821613e-10
    p = 2.08767569878681e-09 + r * p
    p = 2.505210838544172e-08 + r * p
    p = 2.755731922398589e-07 + r * p
    p = 2.7557319223985893e-06 + r * p
    p = 2.48015873015873e-05 + r * p
    p = 0.0001984126984126984 + r * p
    p = 0.001388888888888889 + r * p
    p = 0.008333333333333333 + r * p
    p = 0.041666666666666664 + r * p
    p = 0.16666666666666666 + r * p
    p = 0.5 + r * p
    p = 1.0 + r * p
    p = 1.0 + r * p
    return math.ldexp(p, k)


def expm1(x: float) -> float:
    """``e**x - 1``: degree-16 Taylor for ``|x| <= 0.5`` (no cancellation), else
    :func:`exp` minus one (cancellation costs under two bits there)."""
    if x != x:
        return x
    if x > 0.5 or x < -0.5:
        return exp(x) - 1.0
    # Horner's rule on 1 / n!, n = 16 down to 1
    p = 4.779477332387385e-14
    p = 7.647163731819816e-13 + x * p
    p = 1.1470745597729725e-11 + x * p
    p = 1.6059043836821613e-10 + x * p
    p = 2.08767569878681e-09 + x * p
    p = 2.505210838544172e-08 + x * p
    p = 2.755731922398589e-07 + x * p
    p = 2.7557319223985893e-06 + x * p
    p = 2.48015873015873e-05 + x * p
    p = 0.0001984126984126984 + x * p
    p = 0.001388888888888889 + x * p
    p = 0.008333333333333333 + x * p
    p = 0.041666666666666664 + x * p
    p = 0.16666666666666666 + x * p
    p = 0.5 + x * p
    p = 1.0 + x * p
    return x * p


def log(x: float) -> float:
    """Natural logarithm: ``x = m 2**e`` with ``m`` in ``[sqrt(1/2), sqrt(2))`` (scaled by
    exact powers of two), ``ln m = 2 atanh(s)``, ``s = (m - 1) / (m + 1)``, series to
    ``s**23``."""
    if x != x:
        return x
    if x < 0.0:
        return math.nan
    if x == 0.0:
        return -math.inf
    if x > 1.7976931348623157e308:
        return x
    m = x
    e = 0.0
    while m >= 1.8446744073709552e19:  # 2**64
        m = m * 5.421010862427522e-20
        e = e + 64.0
    while m < 5.421010862427522e-20:  # 2**-64
        m = m * 1.8446744073709552e19
        e = e - 64.0
    while m >= 1.4142135623730951:
        m = m * 0.5
        e = e + 1.0
    while m < 0.7071067811865476:
        m = m * 2.0
        e = e - 1.0
    f = m - 1.0  # exact (Sterbenz)
    s = f / (2.0 + f)
    z = s * s
    # Horner's rule on 2 / (2k + 1), k = 11 down to 1
    series = 0.08695652173913043
    series = 0.09523809523809523 + z * series
    series = 0.10526315789473684 + z * series
    series = 0.11764705882352941 + z * series
    series = 0.13333333333333333 + z * series
    series = 0.15384615384615385 + z * series
    series = 0.18181818181818182 + z * series
    series = 0.2222222222222222 + z * series
    series = 0.2857142857142857 + z * series
    series = 0.4 + z * series
    series = 0.6666666666666666 + z * series
    series = z * series
    return e * 0.6931471803691238 + (e * 1.9082149292705877e-10 + (2.0 * s + s * series))


def log1p(x: float) -> float:
    """``ln(1 + x)``: ``log(u) * x / (u - 1)`` with ``u = 1 + x`` rounded, which cancels the
    rounding of ``u`` to first order."""
    if x != x:
        return x
    if x < -1.0:
        return math.nan
    if x == -1.0:
        return -math.inf
    if x > 1.0e15:
        return log(x) + log(1.0 + 1.0 / x)
    u = 1.0 + x
    if u == 1.0:
        return x
    return log(u) * (x / (u - 1.0))


def _sin_reduced(r: float) -> float:
    """Taylor series of sine to ``r**17``, ``|r| <= pi / 4``."""
    z = r * r
    # Horner's rule on (-1)**k / (2k + 1)!, k = 8 down to 1
    p = 2.8114572543455206e-15
    p = -7.647163731819816e-13 + z * p
    p = 1.6059043836821613e-10 + z * p
    p = -2.505210838544172e-08 + z * p
    p = 2.7557319223985893e-06 + z * p
    p = -0.0001984126984126984 + z * p
    p = 0.008333333333333333 + z * p
    p = -0.16666666666666666 + z * p
    return r + r * (z * p)


def _cos_reduced(r: float) -> float:
    """Taylor series of cosine to ``r**16``, ``|r| <= pi / 4``."""
    z = r * r
    # Horner's rule on (-1)**k / (2k)!, k = 8 down to 2
    p = 4.779477332387385e-14
    p = -1.1470745597729725e-11 + z * p
    p = 2.08767569878681e-09 + z * p
    p = -2.755731922398589e-07 + z * p
    p = 2.48015873015873e-05 + z * p
    p = -0.001388888888888889 + z * p
    p = 0.041666666666666664 + z * p
    return 1.0 + z * (-0.5 + z * p)


def _quadrant_value(x: float, cosine: float) -> float:
    """``sin(x + cosine * pi / 2)``: ``x = n pi/2 + r``, ``pi / 2`` split in two 33-bit parts
    (``n *`` each exact for ``|n| < 2**20``) and a rest; the quadrant picks the series."""
    if x != x or x - x != 0.0:  # NaN or an infinity
        return math.nan
    if x > 1.6e6 or x < -1.6e6:  # beyond the exact reduction: the remainder (exact) by 2 pi
        x = math.fmod(x, 6.283185307179586)
    n = math.floor(x * 0.6366197723675814 + 0.5)  # 2 / pi
    r = ((x - n * 1.5707963267341256) - n * 6.077100506303966e-11) - n * 2.0222662487959506e-21
    q = n + cosine - 4.0 * math.floor((n + cosine) * 0.25)
    if q == 0.0:
        return _sin_reduced(r)
    if q == 1.0:
        return _cos_reduced(r)
    if q == 2.0:
        return -_sin_reduced(r)
    return -_cos_reduced(r)


def sin(x: float) -> float:
    """Sine; accurate for ``|x|`` below 1.6e6 (the plants' phases are far smaller), beyond
    that of the argument's remainder by the double nearest ``2 pi``: the same bits
    everywhere, in ``[-1, 1]``, but not the true phase."""
    return _quadrant_value(x, 0.0)


def cos(x: float) -> float:
    """Cosine, as :func:`sin` a quarter period on."""
    return _quadrant_value(x, 1.0)


def pow(x: float, y: float) -> float:
    """``x**y`` for positive ``x`` as ``exp(y log x)`` (``1`` for ``y == 0``, ``0`` for
    ``x == 0 < y``, NaN for a negative ``x``)."""
    if y == 0.0:
        return 1.0
    if x != x or y != y:
        return math.nan
    if x == 0.0:
        return 0.0 if y > 0.0 else math.inf
    if x < 0.0:
        return math.nan
    return exp(y * log(x))
