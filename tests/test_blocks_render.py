"""The C rendering of the effect blocks (generated from gatetwin.plant.blocks) computes what
the Python functions compute, to the bit, and the renderer refuses what it cannot translate."""

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
    "first_order": [(-100, 400), (-100, 400), (0, 600), (0.5, 200)],
    "seiche_advance": [(-50, 50), (-50, 50), (-60, 60), (0, 60), (2, 40), (1, 200)],
    "seiche_equilibrium": [(-60, 60), (2, 40), (1, 200)],
    "seiche_output": [(-50, 50), (2, 40), (0, 2)],
    "lag_interval": [(-100, 400), (-100, 400), (-100, 100), (0, 60), (0.5, 200), (0.5, 20)],
    "grid_index_at_or_after": [(0, 1e5), (0, 1e3), (0.01, 5)],
    "arx_pole_scaled": [(0.5, 0.999), (5, 120), (5, 120)],
    "arx_gain_rescaled": [(-5, 5), (0.5, 0.999), (0.5, 0.999)],
}


def test_every_rendered_block_is_exercised():
    assert set(RANGES) == set(blocks.RENDERED_C)


@pytest.mark.parametrize("name", blocks.RENDERED_C)
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
