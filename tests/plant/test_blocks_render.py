"""The C rendering of the effect blocks (generated from gatetwin.plant.blocks) computes what
the Python functions compute, to the bit (both call this platform's C library for exp, log,
sin, ...), and the renderer refuses what it cannot translate."""

from __future__ import annotations

import ctypes
import math
import subprocess
import types

import numpy as np
import pytest

from gatetwin.fmu.c_build import CFLAGS, find_compiler, generated_blocks
from gatetwin.plant import blocks
from gatetwin.plant.ast_render import c_module
from gatetwin.plant.model import ARX_ORDER_LIMIT


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    folder = tmp_path_factory.mktemp("blocks")
    for name, text in generated_blocks().items():
        (folder / name).write_text(text, encoding="utf-8")
    out = folder / "blocks.so"
    # the FMU's own flags, but with the functions visible to ctypes
    flags = [f for f in CFLAGS if not f.startswith("-fvisibility")]
    subprocess.run([*find_compiler(), *flags, "-o", str(out), "blocks.c", "-lm"],
                   cwd=folder, check=True, capture_output=True)  # fmt: skip
    return ctypes.CDLL(str(out))


def _c_call(lib, name, args, n_out):
    f = getattr(lib, f"gt_{name}")
    f.argtypes = [ctypes.c_double] * len(args) + [ctypes.POINTER(ctypes.c_double)] * (
        n_out if n_out > 1 else 0
    )
    if n_out == 1:
        f.restype = ctypes.c_double
        return (f(*args),)
    outs = [ctypes.c_double() for _ in range(n_out)]
    f.restype = None
    f(*args, *[ctypes.byref(o) for o in outs])
    return tuple(o.value for o in outs)


def _same(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or a == b


#: Argument ranges of each block, as the plants use them (low, high per argument); a random
#: sign where the argument may be negative.
RANGES = {
    "move_toward": [(-80, 80), (-80, 80), (0, 5)],
    "play": [(-80, 80), (-80, 80), (0, 5)],
    "gain_map": [(-60, 60), (-0.05, 0.05)],
    "gain_map_inverse": [(-60, 60), (-0.05, 0.05)],
    "flow_scaled": [(-40, 40), (-0.05, 0.05), (20, 90), (20, 90)],
    "first_order_decay": [(0, 600), (0.5, 200)],
    "relax": [(-100, 400), (-100, 400), (0, 1)],
    "first_order": [(-100, 400), (-100, 400), (0, 600), (0.5, 200)],
    "seiche_advance": [(-50, 50), (-50, 50), (-60, 60), (0, 60), (2, 40), (1, 200)],
    "seiche_equilibrium": [(-60, 60), (2, 40), (1, 200)],
    "seiche_output": [(-50, 50), (2, 40), (0, 2)],
    "lag_interval": [(-100, 400), (-100, 400), (-100, 100), (0, 60), (0.5, 200), (0.5, 20)],
    "grid_index_at_or_after": [(0, 1e5), (0, 1e3), (0.01, 5)],
    "arx_pole_scaled": [(0.5, 0.999), (5, 120), (5, 120)],
    "arx_gain_rescaled": [(-5, 5), (0.5, 0.999), (0.5, 0.999)],
}


#: The blocks over arrays, exercised by their own tests below.
ARRAY_BLOCKS = ("arx_sample", "arx_equilibrium", "arx_envelope_coefficients")


def test_every_rendered_block_is_exercised():
    assert set(RANGES) | set(ARRAY_BLOCKS) == set(blocks.RENDERED_C)
    assert not set(RANGES) & set(ARRAY_BLOCKS)


@pytest.mark.parametrize("name", [n for n in blocks.RENDERED_C if n not in ARRAY_BLOCKS])
def test_c_rendering_equals_python_to_the_bit(library, name):
    f = getattr(blocks, name)
    rng = np.random.default_rng(7)
    for trial in range(2000):
        args = [float(rng.uniform(lo, hi)) for lo, hi in RANGES[name]]
        if trial % 10 == 0 and name in ("gain_map", "gain_map_inverse"):
            args[1] = 0.0  # the linear branch
        if trial % 7 == 0 and name == "lag_interval":
            args[5] = args[4]  # the equal-time-constant branch
        if trial % 5 == 0 and name == "grid_index_at_or_after":
            args[0] = args[1] + round(args[0] / args[2]) * args[2]  # on a grid point
        expected = f(*args)
        expected = expected if isinstance(expected, tuple) else (expected,)
        got = _c_call(library, name, args, len(expected))
        assert all(_same(float(e), g) for e, g in zip(expected, got, strict=True)), (name, args)


def _doubles(values):
    return (ctypes.c_double * len(values))(*values)


def _random_arx(rng):
    """Orders up to the model files' limit, coefficients of either sign and histories of
    levels and openings (mm) as a plant's deviations range."""
    na, nb, nk = (int(rng.integers(1, high)) for high in (ARX_ORDER_LIMIT + 1, 12, 6))
    a = rng.uniform(-1.5, 1.5, na).tolist()
    b = rng.uniform(-3, 3, nb).tolist()
    x_hist = rng.uniform(-200, 200, na).tolist()
    u_hist = rng.uniform(-60, 60, nk + nb - 1).tolist()
    return na, nb, nk, a, b, x_hist, u_hist


def test_arx_sample_in_c_equals_python_to_the_bit(library):
    """Twenty consecutive samples from random states: the output and both histories, shifted
    in place, agree bit for bit."""
    f = library.gt_arx_sample
    f.restype = ctypes.c_double
    rng = np.random.default_rng(11)
    for _ in range(300):
        na, nb, nk, a, b, x_hist, u_hist = _random_arx(rng)
        c_x, c_u, c_a, c_b = _doubles(x_hist), _doubles(u_hist), _doubles(a), _doubles(b)
        for u in rng.uniform(-60, 60, 20).tolist():
            expected = blocks.arx_sample(x_hist, u_hist, a, b, u, na, nb, nk)
            got = f(c_x, c_u, c_a, c_b, ctypes.c_double(u), na, nb, nk)
            assert got == expected, (na, nb, nk)
            assert list(c_x) == x_hist and list(c_u) == u_hist, (na, nb, nk)
        assert u_hist[0] == u and x_hist[0] == expected  # the newest values lead


def test_arx_sample_is_the_difference_equation():
    """Against the equation itself, on whole signals: x(k) = sum a_i x(k-i) + sum b_j
    u(k-nk-j+1). The kernel sums left to right as the direct sum below does, so they agree
    exactly."""
    rng = np.random.default_rng(5)
    for _ in range(50):
        na, nb, nk, a, b, x_hist, u_hist = _random_arx(rng)
        # x(k-1-i) = x_hist[i], u(k-2-m) = u_hist[m], written as whole signals from k = 0 on
        x = x_hist[::-1]
        u_sig = u_hist[::-1]
        for u in rng.uniform(-60, 60, 10).tolist():
            u_sig.append(u)  # u(k-1)
            direct = 0.0
            for i in range(1, na + 1):
                direct += a[i - 1] * x[-i]
            for j in range(1, nb + 1):
                direct += b[j - 1] * u_sig[len(u_sig) - nk - j + 1]
            x.append(blocks.arx_sample(x_hist, u_hist, a, b, u, na, nb, nk))
            assert x[-1] == direct


def test_arx_equilibrium_in_c_equals_python_to_the_bit(library):
    f = library.gt_arx_equilibrium
    f.restype = None
    rng = np.random.default_rng(13)
    for trial in range(2000):
        na, nb, _, a, b, _, _ = _random_arx(rng)
        if trial % 10 == 0:
            na, a = 2, [0.25, 0.75]  # sum(a) is 1: no rest state
        u = float(rng.uniform(-60, 60))
        expected = blocks.arx_equilibrium(a, b, u, na, nb)
        sum_a, x0 = ctypes.c_double(), ctypes.c_double()
        f(_doubles(a), _doubles(b), ctypes.c_double(u), na, nb, ctypes.byref(sum_a),
          ctypes.byref(x0))  # fmt: skip
        assert _same(expected[0], sum_a.value) and _same(expected[1], x0.value), (na, nb)
        if trial % 10 == 0:
            assert expected[0] == 1.0 and math.isnan(expected[1])


def test_arx_envelope_coefficients_in_c_equal_python_to_the_bit(library):
    """Poles and time constants over the ranges of RANGES["arx_pole_scaled"]; the pole scaled
    as that block scales it, every b as arx_gain_rescaled rescales it."""
    f = library.gt_arx_envelope_coefficients
    f.restype = ctypes.c_double
    rng = np.random.default_rng(19)
    for _ in range(500):
        nb = int(rng.integers(1, 12))
        a, b = [float(rng.uniform(0.5, 0.999))], rng.uniform(-5, 5, nb).tolist()
        tau_ref, tau = (float(v) for v in rng.uniform(5, 120, 2))
        a_now, b_now = [0.0], [0.0] * nb
        expected = blocks.arx_envelope_coefficients(a, b, a_now, b_now, nb, tau_ref, tau)
        c_a_now, c_b_now = _doubles([0.0]), _doubles([0.0] * nb)
        got = f(_doubles(a), _doubles(b), c_a_now, c_b_now, nb, ctypes.c_double(tau_ref),
                ctypes.c_double(tau))  # fmt: skip
        assert got == expected == a_now[0] == c_a_now[0], nb
        assert list(c_b_now) == b_now, nb
        assert a_now[0] == blocks.arx_pole_scaled(a[0], tau_ref, tau)
        assert b_now == [blocks.arx_gain_rescaled(bj, a[0], a_now[0]) for bj in b]


def test_arx_equilibrium_is_a_rest_point():
    """A held input from the rest state stays there, to round-off: ``|x - x0|`` within a few
    ulps of the largest term of the sums (float64, 2**-52 relative), times the terms summed."""
    rng = np.random.default_rng(17)
    for _ in range(200):
        na, nb, nk, a, b, _, _ = _random_arx(rng)
        a = (np.asarray(a) * 0.9 / max(1.0, float(np.sum(np.abs(a))))).tolist()  # stable
        u = float(rng.uniform(-60, 60))
        _, x0 = blocks.arx_equilibrium(a, b, u, na, nb)
        x_hist, u_hist = [x0] * na, [u] * (nk + nb - 1)
        scale = max(abs(x0), abs(u)) * (sum(map(abs, a)) + sum(map(abs, b)) + 1.0)
        for _ in range(5):
            x = blocks.arx_sample(x_hist, u_hist, a, b, u, na, nb, nk)
            assert abs(x - x0) <= 8 * (na + nb) * 2.0**-52 * scale


def test_renderer_refuses_what_it_cannot_translate():
    module = types.ModuleType("gatetwin.plant.fake_blocks")
    source = "def f(x):\n    return [x]\n\ndef g(x):\n    return h(x)\n"
    exec(compile(source, "<fake>", "exec"), module.__dict__)  # noqa: S102 - a test module
    import inspect as _inspect

    original = _inspect.getsource
    try:
        _inspect.getsource = lambda m: source  # type: ignore[assignment]
        with pytest.raises(ValueError, match="f: expression"):
            c_module(module, ("f",), "gt_")
        with pytest.raises(ValueError, match="g: call"):
            c_module(module, ("g",), "gt_")
    finally:
        _inspect.getsource = original  # type: ignore[assignment]


#: Loops and arrays outside the subset, each with what the refusal names. A C rendering of any
#: of them would differ from Python (a step or a start C would have to restate, an iterator,
#: a float index, a loop variable changed inside or read after its loop, a count summed as a
#: float, an array rebound) or has no C type.
REFUSED = {
    "def f(a: list[float], n: int) -> float:\n    for i in range(1, n):\n        a[i] = 0.0\n"
    "    return 0.0\n": "f: loop",
    "def f(a: list[float]) -> float:\n    s = 0.0\n    for v in a:\n        s += v\n"
    "    return s\n": "f: loop",
    "def f(a: list[float], x: float) -> float:\n    return a[x]\n": "f: index",
    "def f(a: list[float], n: int) -> float:\n    for i in range(n):\n        i = 0\n"
    "    return 0.0\n": "f: assigns to i",
    "def f(a: list[float], n: int) -> float:\n    for i in range(n):\n        a[i] = 1.0\n"
    "    return a[i]\n": "f: index",
    "def f(n: int) -> float:\n    return n * 0.5\n": "f: n .* used as a number",
    "def f(a: list[float], b: list[float]) -> float:\n    a = b\n    return 0.0\n":
        "f: assigns to a",
    "def f(a: list[float], n: int) -> float:\n    for i in range(n):\n"
    "        for i in range(n):\n            a[i] = 0.0\n    return 0.0\n": "f: loop variable i",
    "def f(a: dict) -> float:\n    return 0.0\n": "f: argument a",
    "def g(x: float) -> tuple[float, float]:\n    return x, x\n\n"
    "def f(x: float) -> float:\n    return g(x)\n": "f: call",
    "def f(a: list[float], n: int) -> float:\n    for i in range(n):\n        a[i] = 0.0\n"
    "    else:\n        return 1.0\n    return 0.0\n": "f: loop",
    # a math function the renderer does not know
    "import math\n\ndef f(x: float) -> float:\n    return math.tanh(x)\n": "f: call",
}  # fmt: skip


def _render(source: str, *names: str) -> str:
    module = types.ModuleType("gatetwin.plant.fake_blocks")
    exec(compile(source, "<fake>", "exec"), module.__dict__)  # noqa: S102 - a test module
    import inspect as _inspect

    original = _inspect.getsource
    try:
        _inspect.getsource = lambda m: source  # type: ignore[assignment]
        return c_module(module, names, "gt_")[0]
    finally:
        _inspect.getsource = original  # type: ignore[assignment]


@pytest.mark.parametrize("source", REFUSED)
def test_renderer_refuses_loops_and_arrays_outside_the_subset(source):
    names = ("g", "f") if source.startswith("def g") else ("f",)  # g rendered along with f
    with pytest.raises(ValueError, match=REFUSED[source]):
        _render(source, *names)


def test_renderer_writes_counted_loops_over_arrays():
    """The accepted form, as C: a bounded loop, an element written, a read-only array const."""
    source = ("def f(a: list[float], b: list[float], n: int) -> float:\n"
              "    s = 0.0\n    for i in range(n - 1):\n        a[i + 1] = b[2 * i]\n"
              "        s += b[i]\n    return s\n")  # fmt: skip
    c = _render(source, "f")
    assert "double gt_f(double *a, const double *b, int n)" in c
    assert "for (int i = 0; i < (n - 1); i++) {" in c
    assert "a[(i + 1)] = b[(2 * i)];" in c


def test_renderer_calls_the_c_librarys_math_functions():
    source = ("import math\n\ndef f(x: float, k: float) -> float:\n"
              "    return math.exp(x) + x ** 1.5 + math.sqrt(x) + math.ldexp(x, k)\n")  # fmt: skip
    c = _render(source, "f")
    assert "return (((exp(x) + pow(x, 1.5)) + sqrt(x)) + ldexp(x, (int)(k)));" in c
