"""Every module of gatetwin names what it offers in ``__all__``, and offers what it defines.

Each module is imported and its ``__all__`` checked against its namespace: every listed name
exists, and every public function or class the module defines is listed (a new public
definition without an export fails here). A module that cannot be imported without an
optional extra, and a ``__main__`` module (importing it runs the command), is checked from
its source instead: the same two rules on its top-level statements.
"""

from __future__ import annotations

import ast
import functools
import importlib
import pkgutil
import sys
from pathlib import Path
from typing import NamedTuple

import pytest

import gatetwin

PACKAGE_DIR = Path(gatetwin.__file__).resolve().parent
#: Import names of the optional extras (pyproject.toml's optional dependencies) a module may
#: need; without them installed, the module is checked from its source.
OPTIONAL_IMPORTS = frozenset({"dask", "distributed", "pandas", "pyswmm", "ziglang"})


def _is_missing_extra(exc: BaseException | None) -> bool:
    """Whether ``exc`` is the import of an optional extra that is not installed."""
    return (
        isinstance(exc, ModuleNotFoundError) and (exc.name or "").split(".")[0] in OPTIONAL_IMPORTS
    )


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE_DIR).with_suffix("").parts
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(("gatetwin", *parts))


def walk() -> tuple[set[str], dict[str, BaseException | None]]:
    """Every module name pkgutil.walk_packages finds under gatetwin (importing the packages),
    and the packages it could not import, with the exception."""
    failed: dict[str, BaseException | None] = {}

    def onerror(name: str) -> None:
        failed[name] = sys.exc_info()[1]

    walked = {gatetwin.__name__}
    walked.update(m.name for m in pkgutil.walk_packages(gatetwin.__path__, "gatetwin.", onerror))
    return walked, failed


#: Every module's file, by module name; :func:`test_every_module_is_walked` checks that these
#: are the modules pkgutil.walk_packages finds.
MODULES = sorted(_module_name(p) for p in PACKAGE_DIR.rglob("*.py"))


def _source_path(name: str) -> Path:
    parts = name.split(".")[1:]
    folder = PACKAGE_DIR.joinpath(*parts)
    if (folder / "__init__.py").is_file():
        return folder / "__init__.py"
    return folder.with_suffix(".py")


# -- the source check (modules not imported) ------------------------------------------------


def _top_level(statements: list[ast.stmt]) -> list[ast.stmt]:
    """Top-level statements, with those inside top-level ``if``/``try``/``with`` blocks."""
    out: list[ast.stmt] = []
    for s in statements:
        out.append(s)
        if isinstance(s, ast.If):
            out += _top_level(s.body) + _top_level(s.orelse)
        elif isinstance(s, ast.Try):
            out += _top_level(s.body) + _top_level(s.orelse) + _top_level(s.finalbody)
            for handler in s.handlers:
                out += _top_level(handler.body)
        elif isinstance(s, ast.With):
            out += _top_level(s.body)
    return out


def _target_names(node: ast.expr) -> list[str]:
    if isinstance(node, ast.Name):
        return [node.id]
    if isinstance(node, ast.Tuple | ast.List):
        return [n for element in node.elts for n in _target_names(element)]
    if isinstance(node, ast.Starred):
        return _target_names(node.value)
    return []


def source_names(
    source: str, name: str = "<source>"
) -> tuple[list[str] | None, set[str], set[str]]:
    """From the source of module ``name``: its ``__all__`` (None without one), every name it
    binds at top level, and its public top-level functions and classes."""
    exported: list[str] | None = None
    bound: set[str] = set()
    definitions: set[str] = set()
    for s in _top_level(ast.parse(source).body):
        if isinstance(s, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            bound.add(s.name)
            if not s.name.startswith("_"):
                definitions.add(s.name)
        elif isinstance(s, ast.Import | ast.ImportFrom):
            for alias in s.names:
                bound.add(alias.asname or alias.name.split(".")[0])
        elif isinstance(s, ast.Assign | ast.AnnAssign | ast.AugAssign):
            targets = s.targets if isinstance(s, ast.Assign) else [s.target]
            names = [n for t in targets for n in _target_names(t)]
            bound.update(names)
            if "__all__" in names and s.value is not None:
                try:
                    exported = list(ast.literal_eval(s.value))
                except ValueError:
                    raise AssertionError(f"{name}.__all__ is not a literal list of names") from None
    return exported, bound, definitions


class Facts(NamedTuple):
    """What a module exports and defines."""

    #: Its ``__all__``, None without one.
    exported: list[str] | None
    #: Names in ``__all__`` the module does not define.
    undefined: list[str]
    #: Its public functions and classes.
    definitions: set[str]


def _from_source(name: str) -> Facts:
    source = _source_path(name).read_text(encoding="utf-8")
    exported, bound, definitions = source_names(source, name)
    return Facts(exported, [n for n in exported or [] if n not in bound], definitions)


@functools.cache
def facts(name: str) -> Facts:
    """The module's facts, from the imported module or, where it cannot be imported (see the
    docstring), from its source."""
    if name.rsplit(".", 1)[-1] == "__main__":
        return _from_source(name)
    try:
        module = importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if not _is_missing_extra(exc):
            raise
        return _from_source(name)
    exported = getattr(module, "__all__", None)
    exported = None if exported is None else list(exported)
    definitions = {
        n
        for n, value in vars(module).items()
        if not n.startswith("_")
        and callable(value)
        and getattr(value, "__module__", None) == module.__name__
    }
    undefined = [n for n in exported or [] if not hasattr(module, n)]
    return Facts(exported, undefined, definitions)


# -- the tests --------------------------------------------------------------------------------


def test_every_module_is_walked() -> None:
    walked, failures = walk()
    unexpected = {n: repr(e) for n, e in failures.items() if not _is_missing_extra(e)}
    assert not unexpected, f"packages that could not be imported: {unexpected}"
    # a package that needs a missing extra hides its modules from the walk
    unwalked = sorted(
        n for n in set(MODULES) - walked if not any(n.startswith(f"{p}.") for p in failures)
    )
    assert not unwalked, f"modules not found by pkgutil.walk_packages: {unwalked}"
    not_on_disk = sorted(walked - set(MODULES))
    assert not not_on_disk, f"modules without a .py file under {PACKAGE_DIR}: {not_on_disk}"
    assert len(MODULES) > 100, f"only {len(MODULES)} modules found under {PACKAGE_DIR}"


@pytest.mark.parametrize("name", MODULES)
def test_module_declares_all(name: str) -> None:
    exported = facts(name).exported
    assert exported is not None, f"{name} has no __all__"
    duplicates = sorted({n for n in exported if exported.count(n) > 1})
    assert not duplicates, f"{name}.__all__ lists {duplicates} more than once"


@pytest.mark.parametrize("name", MODULES)
def test_exported_names_exist(name: str) -> None:
    undefined = facts(name).undefined
    assert not undefined, f"{name}.__all__ lists names the module does not define: {undefined}"


@pytest.mark.parametrize("name", MODULES)
def test_public_definitions_are_exported(name: str) -> None:
    found = facts(name)
    unlisted = sorted(found.definitions - set(found.exported or []))
    assert not unlisted, f"{name} defines public {unlisted} but its __all__ omits them"


def test_source_check_finds_what_is_missing() -> None:
    source = (
        "import os\n"
        "from pathlib import Path as P\n"
        '__all__ = ["LIMIT", "listed", "ghost"]\n'
        "LIMIT = 1\n"
        "def listed(): pass\n"
        "def unlisted(): pass\n"
        "def _private(): pass\n"
        "class Hidden: pass\n"
        "if os.name:\n"
        "    def conditional(): pass\n"
    )
    exported, bound, definitions = source_names(source)
    assert exported == ["LIMIT", "listed", "ghost"]
    assert [n for n in exported if n not in bound] == ["ghost"]
    assert {"os", "P", "LIMIT", "_private"} <= bound
    assert sorted(definitions - set(exported)) == ["Hidden", "conditional", "unlisted"]
    assert source_names("x = 1\n")[0] is None
