"""The few operations the MPC's arithmetic needs to run on numbers and on casadi symbols.

The discretisation (:mod:`gatetwin.mpc.discrete`), the observer
(:mod:`gatetwin.mpc.observer`) and the condensed QP (:mod:`gatetwin.mpc.qp`) are written
once, on numpy arrays. Given casadi ``SX`` scalars instead of floats (each wrapped in a
:class:`Sym`, held in numpy arrays of ``dtype=object``) the same code builds the expressions that
:mod:`gatetwin.mpc.codegen` turns into C. These helpers are where the two differ: a float
goes through :mod:`math` and numpy exactly as before, a symbol through casadi.

This module holds no MPC arithmetic of its own.
"""

from __future__ import annotations

import math
from typing import Any

import casadi
import numpy as np


class Sym:
    """One casadi ``SX`` scalar that numpy treats as a plain Python object.

    casadi takes over any numpy operation that meets an ``SX`` (an array times a symbol
    becomes an ``SX`` column), which would change the shapes the numpy code relies on; in
    this wrapper a symbol stays one element of an ``object`` array and the arithmetic goes
    element by element, in the order numpy runs it.
    """

    __slots__ = ("sx",)

    def __init__(self, sx: Any) -> None:
        self.sx = sx.sx if isinstance(sx, Sym) else casadi.SX(sx)

    def __repr__(self) -> str:
        return f"Sym({self.sx})"

    def __bool__(self) -> bool:
        raise TypeError("a symbolic value has no truth value; use symbolic.where")

    __hash__ = None  # type: ignore[assignment]


def _raw(x: Any) -> Any:
    return x.sx if isinstance(x, Sym) else x


def _binary(op: Any) -> tuple[Any, Any]:
    def forward(self: Sym, other: Any) -> Any:
        if isinstance(other, np.ndarray):
            return NotImplemented
        return Sym(op(self.sx, _raw(other)))

    def reverse(self: Sym, other: Any) -> Any:
        if isinstance(other, np.ndarray):
            return NotImplemented
        return Sym(op(_raw(other), self.sx))

    return forward, reverse


for _name, _op in {
    "add": lambda a, b: a + b,
    "sub": lambda a, b: a - b,
    "mul": lambda a, b: a * b,
    "truediv": lambda a, b: a / b,
    "pow": lambda a, b: a**b,
}.items():
    _fwd, _rev = _binary(_op)
    setattr(Sym, f"__{_name}__", _fwd)
    setattr(Sym, f"__r{_name}__", _rev)
for _name, _op in {
    "eq": lambda a, b: a == b,
    "ne": lambda a, b: a != b,
    "le": lambda a, b: a <= b,
    "lt": lambda a, b: a < b,
    "ge": lambda a, b: a >= b,
    "gt": lambda a, b: a > b,
}.items():
    setattr(Sym, f"__{_name}__", _binary(_op)[0])
Sym.__neg__ = lambda self: Sym(-self.sx)  # type: ignore[method-assign]


def is_symbolic(*values: Any) -> bool:
    """Whether any of ``values`` is a symbol (:class:`Sym`) or an array holding symbols."""
    for v in values:
        if isinstance(v, Sym):
            return True
        if isinstance(v, np.ndarray) and v.dtype == object:
            return True
    return False


def dtype_of(*values: Any) -> type:
    """``object`` when any value is symbolic (an array of :class:`Sym`), else ``float``."""
    return object if is_symbolic(*values) else float


def zeros(shape: int | tuple[int, ...], *like: Any) -> np.ndarray:
    """Zeros that can hold what ``like`` holds (floats, or symbols)."""
    return np.zeros(shape, dtype=dtype_of(*like))


def asarray(values: Any) -> np.ndarray:
    """A float array, or the object array of symbols it already is."""
    if is_symbolic(values):
        return np.asarray(values, dtype=object)
    return np.asarray(values, dtype=float)


def scalar(value: Any) -> Any:
    """``float(value)``, or the symbol itself."""
    return value if is_symbolic(value) else float(value)


def _unary(fn: Any, numeric: Any) -> Any:
    def apply(x: Any) -> Any:
        return Sym(fn(x.sx)) if isinstance(x, Sym) else numeric(x)

    return apply


exp = _unary(casadi.exp, math.exp)
#: ``math.floor`` (an int), or casadi's ``floor`` (a symbol holding a whole number).
floor_int = _unary(casadi.floor, math.floor)
sqrt = _unary(casadi.sqrt, math.sqrt)
fabs = _unary(casadi.fabs, abs)


def fmax(a: Any, b: Any) -> Any:
    return Sym(casadi.fmax(_raw(a), _raw(b))) if is_symbolic(a, b) else max(a, b)


def clip(x: Any, lo: float, hi: float) -> Any:
    if is_symbolic(x):
        return Sym(casadi.fmin(casadi.fmax(_raw(x), lo), hi))
    return float(np.clip(x, lo, hi))


def where(condition: Any, if_true: Any, if_false: Any) -> Any:
    """``if_true`` where ``condition`` holds (casadi ``if_else`` on symbols)."""
    if is_symbolic(condition, if_true, if_false):
        return Sym(casadi.if_else(_raw(condition), _raw(if_true), _raw(if_false)))
    return if_true if condition else if_false


def solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.linalg.solve``, or casadi's symbolic solve for arrays of symbols."""
    if not is_symbolic(a, b):
        return np.linalg.solve(a, b)
    x = casadi.solve(to_casadi(a), to_casadi(b))
    return from_casadi(x).reshape(np.shape(b))


def to_casadi(values: Any) -> casadi.SX:
    """Floats and symbols (scalar, vector or matrix) as one ``SX`` (a vector as a column)."""
    arr = np.asarray(values, dtype=object)
    if arr.ndim == 0:
        return casadi.SX(_raw(arr.item()))
    if arr.ndim == 1:
        arr = arr[:, None]
    return casadi.vertcat(*[casadi.horzcat(*[casadi.SX(_raw(v)) for v in row]) for row in arr])


def from_casadi(values: casadi.SX) -> np.ndarray:
    """An ``SX`` matrix as a 2-D object array of symbols."""
    out = np.empty(values.shape, dtype=object)
    for i in range(values.shape[0]):
        for j in range(values.shape[1]):
            out[i, j] = Sym(values[i, j])
    return out


def symbols(name: str, n: int) -> tuple[casadi.SX, np.ndarray]:
    """An ``SX`` vector of ``n`` symbols and the same as a 1-D object array."""
    sx = casadi.SX.sym(name, n)
    out = np.empty(n, dtype=object)
    for i in range(n):
        out[i] = Sym(sx[i])
    return sx, out


__all__ = [
    "Sym",
    "asarray",
    "clip",
    "dtype_of",
    "exp",
    "fabs",
    "floor_int",
    "fmax",
    "from_casadi",
    "is_symbolic",
    "scalar",
    "solve",
    "sqrt",
    "symbols",
    "to_casadi",
    "where",
    "zeros",
]
