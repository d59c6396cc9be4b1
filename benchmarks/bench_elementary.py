"""gatetwin.plant.elementary against the C library: accuracy and cost of each function.

Accuracy: the largest error, in ulp of the exact value (mpmath, 200 bits), of the Python
functions (equal to their C rendering to the bit, tests/test_elementary.py) and of Python's
``math`` (the platform's C library) on the same random arguments. Cost: ns per call of the C
rendering (``elementary.c``, the FMU's flags) and of the C library's function, timed side by
side in one C program compiled in this run (fastest of ``--repeat`` runs of each).

    python benchmarks/bench_elementary.py [--n 20000] [--calls 2000000] [--repeat 5]
"""

from __future__ import annotations

import argparse
import math
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from gatetwin.fmu.c_build import CFLAGS, find_compiler, generated_blocks
from gatetwin.plant import elementary

#: Argument ranges (x; pow also y): the plants' use and beyond.
RANGES = {
    "exp": ((-50.0, 50.0), None),
    "expm1": ((-1.0, 1.0), None),
    "log": ((1e-3, 1e3), None),
    "log1p": ((-0.9, 10.0), None),
    "sin": ((-100.0, 100.0), None),
    "cos": ((-100.0, 100.0), None),
    "pow": ((0.3, 1.0), (0.01, 3.0)),
}

TIMER = r"""#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <time.h>
#include "elementary.h"

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

#define TIME(NAME, CALL)                                                         \
    static double time_##NAME(const double *x, const double *y, long n)        \
    {                                                                            \
        volatile double sink = 0.0;                                              \
        double t0 = now();                                                       \
        (void)y;                                                       \
        for (long i = 0; i < n; i++) { sink += CALL; }                           \
        (void)sink;                                                              \
        return (now() - t0) / n * 1e9;                                           \
    }
"""


def _timer_source(names: tuple[str, ...], n: int, repeat: int) -> str:
    lines = [TIMER]
    for name in names:
        args = "x[i & 1023], y[i & 1023]" if name == "pow" else "x[i & 1023]"
        lines.append(f"TIME(gt_{name}, gt_{name}({args}))")
        lines.append(f"TIME(libm_{name}, {name}({args}))")
    lines.append("int main(void)\n{\n    double x[1024], y[1024];")
    lines.append("    (void)y;")
    for name in names:
        (lo, hi), yr = RANGES[name]
        ylo, yhi = yr or (0.0, 0.0)
        lines.append(
            f"    for (int i = 0; i < 1024; i++) {{ x[i] = {lo!r} + ({hi!r} - {lo!r}) * "
            f"(i + 0.5) / 1024.0; y[i] = {ylo!r} + ({yhi!r} - {ylo!r}) * ((i * 37) % 1024) "
            "/ 1024.0; }"
        )
        lines.append("    {\n        double best_gt = 1e30, best_libm = 1e30;")
        lines.append(f"        for (int r = 0; r < {repeat}; r++) {{")
        lines.append(f"            double a = time_gt_{name}(x, y, {n});")
        lines.append(f"            double b = time_libm_{name}(x, y, {n});")
        lines.append("            if (a < best_gt) best_gt = a;")
        lines.append("            if (b < best_libm) best_libm = b;")
        lines.append("        }")
        lines.append(f'        printf("{name} %.2f %.2f\\n", best_gt, best_libm);')
        lines.append("    }")
    lines.append("    return 0;\n}\n")
    return "\n".join(lines)


def _costs(n: int, repeat: int) -> dict[str, tuple[float, float]]:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name, text in generated_blocks().items():
            (folder / name).write_text(text, encoding="utf-8")
        names = tuple(RANGES)
        (folder / "timer.c").write_text(_timer_source(names, n, repeat), encoding="utf-8")
        flags = [f for f in CFLAGS if f not in ("-fPIC", "-shared", "-fvisibility=hidden")]
        out = folder / "timer"
        subprocess.run([*find_compiler(), *flags, "-o", str(out), "timer.c", "elementary.c",
                        "-lm"], cwd=folder, check=True)  # fmt: skip
        text = subprocess.run([str(out)], capture_output=True, text=True, check=True).stdout
    return {f: (float(a), float(b)) for f, a, b in (line.split() for line in text.splitlines())}


def _accuracy(n: int) -> dict[str, tuple[float, float]]:
    import mpmath

    mpmath.mp.prec = 200
    exact = {"exp": mpmath.exp, "expm1": mpmath.expm1, "log": mpmath.log,
             "log1p": mpmath.log1p, "sin": mpmath.sin, "cos": mpmath.cos}  # fmt: skip
    rng = np.random.default_rng(7)
    out = {}
    for name, ((lo, hi), yr) in RANGES.items():
        xs = rng.uniform(lo, hi, n)
        ys = rng.uniform(*yr, n) if yr else np.zeros(n)
        ours = libm = 0.0
        for x, y in zip(xs.tolist(), ys.tolist(), strict=True):
            if name == "pow":
                ref, a, b = mpmath.power(mpmath.mpf(x), mpmath.mpf(y)), elementary.pow(x, y), x**y
            else:
                ref = exact[name](mpmath.mpf(x))
                a, b = getattr(elementary, name)(x), getattr(math, name)(x)
            ulp = math.ulp(float(ref))
            ours = max(ours, float(abs(mpmath.mpf(a) - ref)) / ulp)
            libm = max(libm, float(abs(mpmath.mpf(b) - ref)) / ulp)
        out[name] = (ours, libm)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=20000, help="random arguments per function")
    ap.add_argument("--calls", type=int, default=2_000_000, help="calls timed per run")
    ap.add_argument("--repeat", type=int, default=5, help="timed runs, the fastest kept")
    args = ap.parse_args()
    accuracy = _accuracy(args.n)
    costs = _costs(args.calls, args.repeat)
    print(f"{'function':9} {'range':>22} {'max ulp: elementary':>20} {'C library':>10} "
          f"{'ns/call: elementary':>20} {'C library':>10} {'ratio':>6}")  # fmt: skip
    for name, ((lo, hi), _) in RANGES.items():
        ours, libm = accuracy[name]
        gt, lib = costs[name]
        print(f"{name:9} {f'[{lo:g}, {hi:g}]':>22} {ours:20.2f} {libm:10.2f} {gt:20.2f} "
              f"{lib:10.2f} {gt / lib:6.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
