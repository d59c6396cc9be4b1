"""gatetwin.plant.elementary: accurate (against 200-bit arithmetic), equal to its C rendering
to the bit, and the same bits on every platform the FMU is built for (the C rendering built
for 64-bit ARM Linux and run under qemu, and for Windows and run under wine, prints what the
host's build prints)."""

from __future__ import annotations

import ctypes
import math
import os
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

from gatetwin.fmu.c_build import CFLAGS, KERNEL_PREFIX, find_compiler, generated_blocks
from gatetwin.fmu.platforms import zig_available, zig_cc
from gatetwin.plant import elementary

TESTS = Path(__file__).resolve().parent
WINE = shutil.which("wine") or shutil.which("wine64")


def _arguments() -> dict[str, list[tuple[float, float]]]:
    """Each function's arguments, ``(x, y)`` (``y`` read by ``pow`` only): random over the
    ranges the plants use and well beyond, and the special values."""
    rng = np.random.default_rng(29)

    def u(lo: float, hi: float, n: int = 1500) -> list[float]:
        return rng.uniform(lo, hi, n).tolist()

    def logu(lo: float, hi: float, n: int = 1500) -> list[float]:
        return (10.0 ** rng.uniform(lo, hi, n)).tolist()

    special = [math.nan, math.inf, -math.inf, 0.0, -0.0, 1.0, -1.0, 5e-324, 1e-300, 1e300]
    xs = {
        "exp": u(-50, 50) + u(-745, 709.7) + u(-1e-8, 1e-8, 300) + [709.78, -745.2, -745.1],
        "expm1": u(-1, 1) + u(-40, 40) + u(-1e-8, 1e-8, 300),
        "log": logu(-300, 300) + u(0.5, 2) + [2.2250738585072014e-308, 1e-320],
        "log1p": u(-0.999, 10) + logu(-20, 0) + [-v for v in logu(-20, -0.001)] + [1e16, 1e300],
        "sin": u(-100, 100) + u(-1e5, 1e5) + u(-1e-8, 1e-8, 300),
        "cos": u(-100, 100) + u(-1e5, 1e5) + u(-1e-8, 1e-8, 300),
    }
    out = {name: [(x, 0.0) for x in values + special] for name, values in xs.items()}
    # pow: poles near 1 raised to ratios of time constants (the plants' use), and wider
    out["pow"] = (list(zip(u(0.3, 1), u(0.01, 100), strict=True))
                  + list(zip(logu(-3, 3), u(-5, 5), strict=True))
                  + [(x, y) for x in special for y in (0.0, 0.5, 2.0, -1.5, math.nan)])  # fmt: skip
    return out


ARGUMENTS = _arguments()


def _reference(name: str, x: float, y: float):
    import mpmath

    x_, y_ = mpmath.mpf(x), mpmath.mpf(y)
    return {"exp": mpmath.exp, "expm1": mpmath.expm1, "log": mpmath.log, "log1p": mpmath.log1p,
            "sin": mpmath.sin, "cos": mpmath.cos}[name](x_) if name != "pow" else \
        mpmath.power(x_, y_)  # fmt: skip


def _bound_ulp(name: str, x: float, y: float) -> float:
    """The module's stated accuracy (its docstring), in ulp of the exact value."""
    if name == "pow":
        return 2.0 + 2.5 * abs(y * math.log(x))
    return 4.0 if name in ("expm1", "log1p") else 2.0


@pytest.mark.parametrize("name", elementary.REPLACED)
def test_every_function_is_within_its_stated_ulps_of_the_exact_value(name):
    mpmath = pytest.importorskip("mpmath")
    mpmath.mp.prec = 200
    f = getattr(elementary, name)
    checked = 0
    for x, y in ARGUMENTS[name]:
        finite = math.isfinite(x) and math.isfinite(y)
        in_domain = x > {"pow": 0.0, "log": 0.0, "log1p": -1.0}.get(name, -math.inf)
        if not (finite and in_domain):
            continue
        if name in ("sin", "cos") and abs(x) > 1.6e6:
            assert -1.0 <= f(x) <= 1.0  # the stated range of accuracy ends here
            continue
        exact = _reference(name, x, y)
        nearest = float(exact)
        if nearest == 0.0 or not math.isfinite(nearest) or abs(nearest) < 2.2250738585072014e-308:
            continue  # under- and overflow: below
        error = abs(mpmath.mpf(f(x, y) if name == "pow" else f(x)) - exact) / math.ulp(nearest)
        assert error <= _bound_ulp(name, x, y), (name, x, y, float(error))
        checked += 1
    assert checked > 1000


def _same(a: float, b: float) -> bool:
    return struct.pack("<d", a) == struct.pack("<d", b) or (math.isnan(a) and math.isnan(b))


#: What the C library returns where Python's math raises (a pole, outside the domain, overflow).
C_WHERE_PYTHON_RAISES = {
    "log": lambda x: -math.inf if x == 0.0 else math.nan,
    "log1p": lambda x: -math.inf if x == -1.0 else math.nan,
    "exp": lambda x: math.inf,
    "expm1": lambda x: math.inf,
    "sin": lambda x: math.nan,
    "cos": lambda x: math.nan,
}


@pytest.mark.parametrize("name", elementary.REPLACED)
def test_special_values_follow_the_c_library(name):
    """NaN in, NaN out; the C library's results at infinities, zeros and the ends of the
    range (pow: for the positive bases the plants raise, and NaN for a negative one)."""
    f = getattr(elementary, name)
    for x, y in ARGUMENTS[name]:
        if math.isfinite(x) and x != 0.0 and not (name == "exp" and abs(x) > 709):
            continue
        if name == "pow":
            if x < 0.0 or (x == 0.0 and y < 0.0) or (x == 1.0 and math.isnan(y)):
                continue  # Python raises or C returns 1; the plants raise positive poles
            expected = math.nan if math.isnan(x) and y != 0.0 else x**y
            assert _same(f(x, y), expected), (x, y)
            continue
        try:
            expected = getattr(math, name)(x)
        except (ValueError, OverflowError):  # Python raises where C returns NaN or infinity
            expected = C_WHERE_PYTHON_RAISES[name](x)
        if name == "exp" and 0.0 < expected < 2.2250738585072014e-308:
            # a subnormal result keeps fewer bits than the ulp or two exp may be off by
            assert abs(f(x) - expected) <= 2**-52 * 2.2250738585072014e-308, x
            continue
        assert _same(f(x), expected) or (x == 0.0 and f(x) == expected), (name, x)


def _lines() -> str:
    def bits(v: float) -> str:
        return struct.pack(">d", v).hex()

    return "".join(f"{name} {bits(x)} {bits(y)}\n" for name, args in ARGUMENTS.items()
                   for x, y in args)  # fmt: skip


def _python_bits() -> list[str]:
    out = []
    for name, args in ARGUMENTS.items():
        f = getattr(elementary, name)
        for x, y in args:
            out.append(struct.pack(">d", f(x, y) if name == "pow" else f(x)).hex())
    return out


@pytest.fixture(scope="module")
def sources(tmp_path_factory):
    folder = tmp_path_factory.mktemp("elementary")
    for name, text in generated_blocks().items():
        (folder / name).write_text(text, encoding="utf-8")
    return folder


def _driver(sources: Path, cc: list[str], out: Path) -> Path:
    flags = [f for f in CFLAGS if f not in ("-fPIC", "-shared", "-fvisibility=hidden")]
    subprocess.run([*cc, *flags, "-I", str(sources), "-o", str(out),
                    str(TESTS / "elementary_driver.c"), str(sources / "elementary.c"), "-lm"],
                   check=True, capture_output=True)  # fmt: skip
    return out


def _run(command: list[str]) -> list[str]:
    done = subprocess.run(command, input=_lines(), capture_output=True, text=True, timeout=600,
                          env={**os.environ, "WINEDEBUG": "-all"})  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout.split()


def test_the_c_rendering_gives_the_python_bits(sources, tmp_path):
    try:
        cc = find_compiler()
    except Exception:
        pytest.skip("no C compiler on this machine")
    lib = tmp_path / "elementary.so"
    flags = [f for f in CFLAGS if not f.startswith("-fvisibility")]
    subprocess.run([*cc, *flags, "-o", str(lib), str(sources / "elementary.c"), "-lm"],
                   check=True, capture_output=True)  # fmt: skip
    c = ctypes.CDLL(str(lib))
    for name, args in ARGUMENTS.items():
        f = getattr(c, KERNEL_PREFIX + name)
        f.restype = ctypes.c_double
        f.argtypes = [ctypes.c_double] * (2 if name == "pow" else 1)
        python = getattr(elementary, name)
        for x, y in args:
            got = f(x, y) if name == "pow" else f(x)
            assert _same(got, python(x, y) if name == "pow" else python(x)), (name, x, y)
    # and the driver the foreign builds below are compared with prints those bits
    assert _run([str(_driver(sources, cc, tmp_path / "driver"))]) == _python_bits()


#: Zig target and what runs the driver built for it.
FOREIGN = {
    "aarch64-linux": ("aarch64-linux-gnu.2.17", ["qemu-aarch64", "-L", "/usr/aarch64-linux-gnu"]),
    "x86_64-windows": ("x86_64-windows-gnu", [WINE]),
}


@pytest.mark.skipif(not zig_available(), reason="ziglang (gatetwin[cross]) absent")
@pytest.mark.parametrize("platform", list(FOREIGN))
def test_foreign_builds_give_the_same_bits(sources, tmp_path, platform):
    target, runner = FOREIGN[platform]
    if runner[0] is None or shutil.which(runner[0]) is None:
        pytest.skip(f"{platform}: {'wine' if 'windows' in platform else 'qemu-user'} absent")
    if "linux" in platform and not Path(runner[-1]).is_dir():
        pytest.skip("the arm64 C library (libc6-arm64-cross) absent")
    suffix = ".exe" if "windows" in platform else ""
    driver = _driver(sources, zig_cc(target), tmp_path / f"driver{suffix}")
    assert _run([*runner, str(driver)]) == _python_bits()
