"""Renderings of a kernel module (:mod:`gatetwin.plant.physical_kernel`) beyond plain Python.

A kernel is scalar arithmetic on a few helpers (``fmin``, ``fmax``, ``less``, ``select``,
``sqrt``, ``exp``, ``log``, ``floor``). Each rendering re-binds those helpers and runs the
kernel's own functions, so the arithmetic is never written again:

* :func:`numba_kernel` — the functions compiled by numba (fast simulation for fitting);
* :func:`c_source` — the functions traced into straight-line C (the C FMU's
  ``physical_kernel.c``): every operation becomes one ``const double`` in evaluation order, so
  with ``-ffp-contract=off`` the C result, built by the host's compiler against the C library
  Python uses, equals the Python one to the bit (``exp``, ``log`` and ``sqrt`` are that
  library's in both); another platform's C library may round them otherwise by an ulp.
"""

from __future__ import annotations

import math
import re
import types
from collections.abc import Callable
from functools import cache
from typing import Any

__all__ = [
    "HELPERS",
    "CValue",
    "c_function",
    "c_source",
    "numba_functions",
    "numba_kernel",
]

HELPERS = ("fmin", "fmax", "less", "select", "sqrt", "exp", "log", "floor")


def _rebind(
    module: types.ModuleType,
    helpers: dict[str, Any],
    wrap: Callable[[Callable[..., Any]], Any] | None = None,
) -> types.SimpleNamespace:
    """Copies of the module's functions whose global names resolve to ``helpers`` first."""
    namespace = dict(vars(module))
    namespace.update(helpers)
    out = types.SimpleNamespace()
    names = [n for n, f in vars(module).items()
             if isinstance(f, types.FunctionType) and f.__module__ == module.__name__
             and n not in HELPERS]  # fmt: skip
    for name in names:
        f = vars(module)[name]
        copy = types.FunctionType(f.__code__, namespace, name, f.__defaults__, f.__closure__)
        namespace[name] = wrap(copy) if wrap else copy
    for name in names:
        setattr(out, name, namespace[name])
    return out


@cache
def numba_kernel(module_name: str) -> types.SimpleNamespace:
    """The kernel's functions compiled with numba (``p`` passed as a float64 array)."""
    import importlib
    import math

    from numba import njit

    module = importlib.import_module(module_name)

    def select(condition: bool, a: float, b: float) -> float:
        return a if condition else b

    helpers: dict[str, Any] = {
        "fmin": njit(lambda a, b: a if a < b else b),
        "fmax": njit(lambda a, b: a if a > b else b),
        "less": njit(lambda a, b: a < b),
        "select": njit(select),
        "sqrt": math.sqrt,
        "exp": math.exp,
        "log": math.log,
        "floor": math.floor,
    }
    return _rebind(module, helpers, wrap=lambda f: njit(cache=False)(f))


def numba_functions(module: types.ModuleType) -> types.SimpleNamespace:
    """A module's functions compiled with numba (cached on disk), each calling its siblings'
    compiled copies: how a function that calls other functions of its module (numba cannot
    call plain Python) is compiled as it is written. A function is compiled at its first call,
    so one numba cannot type is harmless until called."""
    from numba import njit

    return _rebind(module, {}, wrap=lambda f: njit(cache=True)(f))


# -- C emitter -----------------------------------------------------------------------------------
class _Trace:
    """The lines of one traced C function."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def emit(self, expression: str) -> CValue:
        name = f"t{len(self.lines)}"
        self.lines.append(f"    const double {name} = {expression};")
        return CValue(name, self)


def _c(value: Any) -> str:
    if isinstance(value, CValue):
        return value.name
    if isinstance(value, bool):
        return "1" if value else "0"
    number = float(value)
    if number != number or number in (float("inf"), float("-inf")):
        raise ValueError(f"a kernel constant must be finite (got {number})")
    text = repr(number)
    return text if "e" in text or "." in text else text + ".0"


class CValue:
    """A traced scalar: arithmetic on it appends C lines to its trace."""

    def __init__(self, name: str, trace: _Trace) -> None:
        self.name, self.trace = name, trace

    def _op(self, other: Any, op: str, reverse: bool = False) -> CValue:
        a, b = (_c(other), self.name) if reverse else (self.name, _c(other))
        return self.trace.emit(f"{a} {op} {b}")

    def __add__(self, o: Any) -> CValue:
        return self._op(o, "+")

    def __radd__(self, o: Any) -> CValue:
        return self._op(o, "+", True)

    def __sub__(self, o: Any) -> CValue:
        return self._op(o, "-")

    def __rsub__(self, o: Any) -> CValue:
        return self._op(o, "-", True)

    def __mul__(self, o: Any) -> CValue:
        return self._op(o, "*")

    def __rmul__(self, o: Any) -> CValue:
        return self._op(o, "*", True)

    def __truediv__(self, o: Any) -> CValue:
        return self._op(o, "/")

    def __rtruediv__(self, o: Any) -> CValue:
        return self._op(o, "/", True)

    def __neg__(self) -> CValue:
        return self.trace.emit(f"-{self.name}")

    def __bool__(self) -> bool:
        raise TypeError("a traced kernel must branch through select(), not if/else")


def _call(fname: str, fold: Callable[..., float]) -> Callable[..., Any]:
    """A C function call, or its value when every argument is a constant (folded by the same
    libm the Python rendering uses)."""

    def f(*args: Any) -> Any:
        if not any(isinstance(a, CValue) for a in args):
            return fold(*args)
        return _trace_of(*args).emit(f"{fname}({', '.join(_c(a) for a in args)})")

    return f


def _trace_of(*args: Any) -> _Trace:
    return next(a.trace for a in args if isinstance(a, CValue))


_C_HELPERS: dict[str, Any] = {
    "fmin": _call("fmin", min),
    "fmax": _call("fmax", max),
    "sqrt": _call("sqrt", math.sqrt),
    "exp": _call("exp", math.exp),
    "log": _call("log", math.log),
    "floor": _call("floor", math.floor),
    "less": lambda a, b: _trace_of(a, b).emit(f"({_c(a)} < {_c(b)}) ? 1.0 : 0.0"),
    "select": lambda c, a, b: _trace_of(c, a, b).emit(f"{_c(c)} != 0.0 ? {_c(a)} : {_c(b)}"),
}


def _live(lines: list[str], uses: list[str]) -> list[str]:
    """The traced ``lines`` that ``uses`` depend on, in order: a value the traced function
    computes but no output uses (one of a pair of slopes when a caller takes the other) is
    left out; the FMUs compile with ``-Wall -Wextra -Werror``, which refuse an unused
    variable."""
    needed = set(re.findall(r"\bt\d+\b", " ".join(uses)))
    kept = []
    for line in reversed(lines):
        name, expression = line.split(" = ", 1)
        if name.split()[-1] in needed:
            kept.append(line)
            needed |= set(re.findall(r"\bt\d+\b", expression))
    return kept[::-1]


def c_function(module: types.ModuleType, name: str, args: tuple[str, ...], n_out: int,
               prefix: str) -> tuple[str, str]:  # fmt: skip
    """C definition and prototype of the kernel function ``name``."""
    trace = _Trace()
    fns = _rebind(module, _C_HELPERS)
    p = [CValue(f"p[{i}]", trace) for i in range(module.N_PARAMETERS)]
    inputs = [CValue(a, trace) for a in args]
    result = getattr(fns, name)(*inputs, p)
    results = result if isinstance(result, tuple) else (result,)
    if len(results) != n_out:
        raise ValueError(f"{name}: {len(results)} outputs, declared {n_out}")
    outs = ", ".join(f"double *out{i}" for i in range(n_out))
    signature = (f"void {prefix}{name}(" + "".join(f"double {a}, " for a in args)
                 + f"const double *p, {outs})")  # fmt: skip
    returns = [f"    *out{i} = {_c(r)};" for i, r in enumerate(results)]
    body = [*_live(trace.lines, returns), *returns]
    return signature + "\n{\n" + "\n".join(body) + "\n}\n", signature + ";"


def c_source(module: types.ModuleType, prefix: str) -> tuple[str, str]:
    """The C file and header of every function in ``module.RENDERED``."""
    stem = module.__name__.rsplit(".", 1)[-1]
    head = (f"/* Generated by gatetwin.plant.kernel_render from {module.__name__}: do not edit. */"
            "\n")  # fmt: skip
    defs, protos = [], []
    for name, args, n_out in module.RENDERED:
        d, proto = c_function(module, name, args, n_out, prefix)
        defs.append(d)
        protos.append(proto)
    guard = f"GATETWIN_{stem.upper()}_H"
    header = (
        head + f"#ifndef {guard}\n#define {guard}\n\n#define {prefix.upper()}N_PARAMETERS "
        f"{module.N_PARAMETERS}\n#define {prefix.upper()}BISECTION_STEPS "
        f"{module.BISECTION_STEPS}\n#define {prefix.upper()}STEADY_MAX_STEPS "
        f"{module.STEADY_MAX_STEPS}\n#define {prefix.upper()}DEPTH_LOW_M "
        f"{_c(module.DEPTH_LOW_M)}\n#define {prefix.upper()}DEPTH_MAX_INDEX "
        f"{module.DEPTH_MAX_INDEX}\n\n" + "\n".join(protos) + "\n\n#endif\n"
    )
    source = (head + f'#include <math.h>\n\n#include "{stem}.h"\n\n'
              + "\n".join(defs))  # fmt: skip
    return source, header
