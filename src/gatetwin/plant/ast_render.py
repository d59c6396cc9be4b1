"""The C rendering of a module of plain scalar functions, from their Python syntax tree.

:mod:`gatetwin.plant.blocks` is written as ordinary Python (branches, early returns,
loops) so that the reference simulator, the pythonfmu slave (which embeds its source) and
numba (which compiles it as it is) all run it directly. This module translates the same
functions into C for the C FMU, statement by statement:

* an argument annotated ``float`` (or not annotated) and every local is a ``double``, one
  annotated ``int`` an ``int`` (a count: it only bounds loops and indexes arrays), one
  annotated ``list[float]`` an array (``double *``, ``const double *`` where the function
  never writes into it); a function returning a tuple of ``n`` values becomes ``void`` with
  ``n`` output pointers, otherwise it returns ``double``;
* ``for i in range(n)`` becomes ``for (int i = 0; i < n; i++)``: one bound, evaluated once,
  the loop variable never assigned and not used after its loop, so both languages run the
  same passes; array elements are read and written as ``a[i]``, the index built from counts,
  loop variables and integer constants with ``+``, ``-`` and ``*`` (the caller keeps it in
  the array's range: C does not check it, Python wraps a negative one);
* every binary operation is written fully parenthesised in the order the syntax tree gives
  it, so C (compiled with ``-ffp-contract=off``) performs the operations Python performs;
* ``math.f(x)`` for ``f`` one of ``sqrt``, ``floor``, ``ceil``, ``fabs``, ``fmod``, ``exp``,
  ``expm1``, ``log``, ``log1p``, ``sin``, ``cos``, ``pow`` (and ``x ** y`` as ``pow``) becomes
  the C library's ``f(x)``, ``math.ldexp(x, k)`` ``ldexp(x, (int)(k))``: built by the host's
  compiler against the C library Python uses, C and Python agree to the bit; another
  platform's C library may round the inexact ones otherwise in the last bit (no computation
  here magnifies that: the binaries agree within 1e-9 mm);
* ``max`` and ``min`` of two values become ``fmax``/``fmin``; ``math.pi``, ``math.nan`` and
  ``math.inf`` the constants Python holds; a call of another function rendered with it, one
  of numbers returning one, its C rendering.

Anything outside that subset (calls to any other function, attributes, containers, any other
``for``, a count used as a number, a number used as an index) raises ``ValueError`` naming
the construct, so the C rendering can never silently differ.
"""

from __future__ import annotations

import ast
import inspect
import math
import types

__all__ = ["c_module"]

_BINARY = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}
_COMPARE = {ast.Gt: ">", ast.GtE: ">=", ast.Lt: "<", ast.LtE: "<=", ast.Eq: "==",
            ast.NotEq: "!="}  # fmt: skip
#: ``math`` functions rendered as the C library's function of the same name.
_MATH = {"sqrt", "floor", "ceil", "fabs", "fmod", "exp", "expm1", "log", "log1p", "sin", "cos",
         "pow"}  # fmt: skip
_CONSTANTS = {"pi": repr(math.pi), "nan": "NAN", "inf": "INFINITY"}


def _literal(value: object) -> str:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"constant {value!r} is not a number")
    text = repr(float(value))
    return text if "e" in text or "." in text else text + ".0"


def _condition(text: str) -> str:
    """``text`` in the one pair of parentheses an ``if``/``while`` takes (clang warns on a
    comparison in two)."""
    depth = 0
    for i, ch in enumerate(text):
        depth += (ch == "(") - (ch == ")")
        if depth == 0 and i < len(text) - 1:
            return f"({text})"  # not one parenthesised whole
    return text if text.startswith("(") else f"({text})"


def _kind(annotation: ast.expr | None, function: str, name: str) -> str:
    """``"float"``, ``"int"`` or ``"array"`` (``list[float]``) from an argument's annotation."""
    if annotation is None or (isinstance(annotation, ast.Name) and annotation.id == "float"):
        return "float"
    if isinstance(annotation, ast.Name) and annotation.id == "int":
        return "int"
    if (isinstance(annotation, ast.Subscript) and isinstance(annotation.value, ast.Name)
            and annotation.value.id == "list" and isinstance(annotation.slice, ast.Name)
            and annotation.slice.id == "float"):  # fmt: skip
        return "array"
    raise ValueError(f"{function}: argument {name}: {ast.unparse(annotation)} has no C type "
                     "(float, int or list[float])")  # fmt: skip


class _Function:
    """Translation of one function definition."""

    def __init__(self, node: ast.FunctionDef, prefix: str) -> None:
        self.node, self.prefix = node, prefix
        self.args = [a.arg for a in node.args.args]
        kinds = {a.arg: _kind(a.annotation, node.name, a.arg) for a in node.args.args}
        self.counts = {a for a, k in kinds.items() if k == "int"}
        self.arrays = {a for a, k in kinds.items() if k == "array"}
        returns = [n for n in ast.walk(node) if isinstance(n, ast.Return)]
        sizes = {len(r.value.elts) if isinstance(r.value, ast.Tuple) else 1 for r in returns
                 if r.value is not None}  # fmt: skip
        if len(sizes) != 1:
            raise ValueError(f"{node.name}: every return must give the same number of values")
        self.n_out = sizes.pop()
        targets = [t for n in ast.walk(node) if isinstance(n, ast.Assign | ast.AugAssign)
                   for t in (n.targets if isinstance(n, ast.Assign) else [n.target])]  # fmt: skip
        assigned = {t.id for t in targets if isinstance(t, ast.Name)}
        loop_vars = {n.target.id for n in ast.walk(node)
                     if isinstance(n, ast.For) and isinstance(n.target, ast.Name)}  # fmt: skip
        fixed = (self.counts | self.arrays | loop_vars) & assigned
        if fixed:
            raise ValueError(f"{node.name}: assigns to {sorted(fixed)[0]} (a count, an array or "
                             "a loop variable)")  # fmt: skip
        elements = [t.value for t in targets if isinstance(t, ast.Subscript)]
        self.written = {v.id for v in elements if isinstance(v, ast.Name)}
        self.locals = sorted(assigned - set(self.args))
        self.loop_vars: list[str] = []  # the loops being rendered, outermost first
        self.siblings: dict[str, _Function] = {}  # the functions rendered with this one

    def parameter(self, name: str) -> str:
        if name in self.counts:
            return f"int {name}"
        if name in self.arrays:
            return f"{'' if name in self.written else 'const '}double *{name}"
        return f"double {name}"

    def signature(self) -> str:
        params = ", ".join(self.parameter(a) for a in self.args)
        if self.n_out == 1:
            return f"double {self.prefix}{self.node.name}({params})"
        outs = ", ".join(f"double *out{i}" for i in range(self.n_out))
        return f"void {self.prefix}{self.node.name}({params}, {outs})"

    def definition(self) -> str:
        lines = [self.signature(), "{"]
        if self.locals:
            lines.append(f"    double {', '.join(self.locals)};")
        body = self.node.body
        if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
            body = body[1:]  # the docstring
        lines += self.block(body, 1)
        return "\n".join(lines) + "\n}\n"

    def block(self, statements: list[ast.stmt], depth: int) -> list[str]:
        out: list[str] = []
        for s in statements:
            out += self.statement(s, "    " * depth, depth)
        return out

    def statement(self, s: ast.stmt, pad: str, depth: int) -> list[str]:
        if isinstance(s, ast.Assign) and len(s.targets) == 1:
            return [f"{pad}{self.target(s.targets[0])} = {self.expr(s.value)};"]
        if isinstance(s, ast.AugAssign) and type(s.op) in _BINARY:
            target, op = self.target(s.target), _BINARY[type(s.op)]
            return [f"{pad}{target} = ({target} {op} {self.expr(s.value)});"]
        if isinstance(s, ast.Return):
            return self.ret(s, pad)
        if isinstance(s, ast.If):
            lines = [f"{pad}if {_condition(self.expr(s.test))} {{", *self.block(s.body, depth + 1)]
            if s.orelse:
                lines += [f"{pad}}} else {{", *self.block(s.orelse, depth + 1)]
            return [*lines, f"{pad}}}"]
        if isinstance(s, ast.While) and not s.orelse:
            head = f"{pad}while {_condition(self.expr(s.test))} {{"
            return [head, *self.block(s.body, depth + 1), f"{pad}}}"]
        if isinstance(s, ast.For):
            return self.loop(s, pad, depth)
        raise ValueError(f"{self.node.name}: statement {ast.dump(s)[:60]} has no C rendering")

    def target(self, t: ast.expr) -> str:
        """A local (``x``) or an array element (``a[i]``) being assigned."""
        if isinstance(t, ast.Name):
            return t.id
        if isinstance(t, ast.Subscript):
            return self.element(t)
        raise ValueError(f"{self.node.name}: assignment to {ast.dump(t)[:60]} has no C rendering")

    def loop(self, s: ast.For, pad: str, depth: int) -> list[str]:
        """``for i in range(n)``, and no other ``for``."""
        it = s.iter
        counted = (isinstance(it, ast.Call) and isinstance(it.func, ast.Name)
                   and it.func.id == "range" and len(it.args) == 1 and not it.keywords)  # fmt: skip
        if not (counted and isinstance(s.target, ast.Name) and not s.orelse):
            raise ValueError(f"{self.node.name}: loop {ast.dump(s)[:60]} is not "
                             "'for i in range(n)'")  # fmt: skip
        name = s.target.id
        if name in self.args or name in self.locals or name in self.loop_vars:
            raise ValueError(f"{self.node.name}: loop variable {name} is already a name")
        head = f"{pad}for (int {name} = 0; {name} < {self.index(it.args[0])}; {name}++) {{"
        self.loop_vars.append(name)
        try:
            body = self.block(s.body, depth + 1)
        finally:
            self.loop_vars.pop()
        return [head, *body, f"{pad}}}"]

    def index(self, e: ast.expr) -> str:
        """An integer expression: counts, loop variables, integer constants, ``+ - *``."""
        if isinstance(e, ast.Name) and (e.id in self.counts or e.id in self.loop_vars):
            return e.id
        if isinstance(e, ast.Constant) and type(e.value) is int:
            return str(e.value)
        if isinstance(e, ast.BinOp) and type(e.op) in (ast.Add, ast.Sub, ast.Mult):
            return f"({self.index(e.left)} {_BINARY[type(e.op)]} {self.index(e.right)})"
        raise ValueError(f"{self.node.name}: index {ast.dump(e)[:60]} is not a count")

    def element(self, e: ast.Subscript) -> str:
        if not (isinstance(e.value, ast.Name) and e.value.id in self.arrays):
            raise ValueError(f"{self.node.name}: {ast.dump(e.value)[:60]} is not an array "
                             "argument")  # fmt: skip
        return f"{e.value.id}[{self.index(e.slice)}]"

    def ret(self, s: ast.Return, pad: str) -> list[str]:
        if s.value is None:
            raise ValueError(f"{self.node.name}: a bare return has no value")
        if self.n_out == 1:
            return [f"{pad}return {self.expr(s.value)};"]
        elts = s.value.elts  # type: ignore[attr-defined]
        return [*(f"{pad}*out{i} = {self.expr(e)};" for i, e in enumerate(elts)),
                f"{pad}return;"]  # fmt: skip

    def expr(self, e: ast.expr) -> str:  # noqa: C901 - one case per construct
        if isinstance(e, ast.Name):
            if e.id in self.counts or e.id in self.arrays or e.id in self.loop_vars:
                raise ValueError(f"{self.node.name}: {e.id} (a count or an array) used as a "
                                 "number")  # fmt: skip
            if e.id not in self.args and e.id not in self.locals:
                raise ValueError(f"{self.node.name}: unknown name {e.id}")
            return e.id
        if isinstance(e, ast.Subscript):
            return self.element(e)
        if isinstance(e, ast.Constant):
            return _literal(e.value)
        if isinstance(e, ast.BinOp) and isinstance(e.op, ast.Pow):
            return f"pow({self.expr(e.left)}, {self.expr(e.right)})"
        if isinstance(e, ast.BinOp) and type(e.op) in _BINARY:
            return f"({self.expr(e.left)} {_BINARY[type(e.op)]} {self.expr(e.right)})"
        if isinstance(e, ast.UnaryOp) and isinstance(e.op, ast.USub):
            return f"(-{self.expr(e.operand)})"
        if isinstance(e, ast.UnaryOp) and isinstance(e.op, ast.Not):
            return f"(!{self.expr(e.operand)})"
        if isinstance(e, ast.Compare) and len(e.ops) == 1 and type(e.ops[0]) in _COMPARE:
            return (f"({self.expr(e.left)} {_COMPARE[type(e.ops[0])]} "
                    f"{self.expr(e.comparators[0])})")  # fmt: skip
        if isinstance(e, ast.BoolOp):
            op = " && " if isinstance(e.op, ast.And) else " || "
            return "(" + op.join(self.expr(v) for v in e.values) + ")"
        if isinstance(e, ast.IfExp):
            return f"({self.expr(e.test)} ? {self.expr(e.body)} : {self.expr(e.orelse)})"
        if isinstance(e, ast.Attribute) and isinstance(e.value, ast.Name) and \
                e.value.id == "math" and e.attr in _CONSTANTS:  # fmt: skip
            return _CONSTANTS[e.attr]
        if isinstance(e, ast.Call) and not e.keywords:
            return self.call(e)
        raise ValueError(f"{self.node.name}: expression {ast.dump(e)[:60]} has no C rendering")

    def call(self, e: ast.Call) -> str:
        args = ", ".join(self.expr(a) for a in e.args)
        f = e.func
        if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id == "math":
            if f.attr in _MATH:
                return f"{f.attr}({args})"
            if f.attr == "ldexp" and len(e.args) == 2:
                return f"ldexp({self.expr(e.args[0])}, (int)({self.expr(e.args[1])}))"
        if isinstance(f, ast.Name) and f.id in ("max", "min") and len(e.args) == 2:
            return f"f{f.id}({args})"
        callee = self.siblings.get(f.id) if isinstance(f, ast.Name) else None
        if callee is not None and callee.n_out == 1 and not (callee.counts or callee.arrays) \
                and len(e.args) == len(callee.args):  # fmt: skip
            return f"{callee.prefix}{callee.node.name}({args})"
        raise ValueError(f"{self.node.name}: call {ast.dump(f)[:60]} has no C rendering")


def c_module(module: types.ModuleType, names: tuple[str, ...], prefix: str) -> tuple[str, str]:
    """C source and header of the functions ``names`` of ``module`` (prefixed ``prefix``)."""
    tree = ast.parse(inspect.getsource(module))
    defs = {n.name: n for n in tree.body if isinstance(n, ast.FunctionDef)}
    missing = [n for n in names if n not in defs]
    if missing:
        raise ValueError(f"{module.__name__} has no function {missing[0]}")
    functions = [_Function(defs[n], prefix) for n in names]
    for f in functions:
        f.siblings = {g.node.name: g for g in functions}
    stem = module.__name__.rsplit(".", 1)[-1]
    head = f"/* Generated by gatetwin.plant.ast_render from {module.__name__}: do not edit. */\n"
    guard = f"GATETWIN_{stem.upper()}_H"
    header = (head + f"#ifndef {guard}\n#define {guard}\n\n"
              + "\n".join(f.signature() + ";" for f in functions) + "\n\n#endif\n")  # fmt: skip
    own = f'#include "{stem}.h"\n'
    source = (head + f"#include <math.h>\n\n{own}\n"
              + "\n".join(f.definition() for f in functions))  # fmt: skip
    return source, header
