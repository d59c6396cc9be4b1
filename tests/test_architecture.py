"""The package's import graph: no circles, and the libraries never reach up into the
``gatetwin run`` orchestration or the command line.

Every ``import`` counts, at module level or inside a function (a lazy import is still a
dependency); imports under ``if TYPE_CHECKING:`` (annotations only) do not.
"""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "gatetwin"
#: Subpackages that are libraries: they may not import the orchestrator or the CLI.
LIBRARIES = ("identification", "fmu", "validation", "mpc", "diagnosis", "plant", "records",
             "flume", "fleet", "ssp")  # fmt: skip
#: The orchestration of ``gatetwin run`` and the command line.
TOP_LAYERS = ("gatetwin.run", "gatetwin.cli")


def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(tree: ast.AST) -> list[ast.Import | ast.ImportFrom]:
    found: list[ast.Import | ast.ImportFrom] = []

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _is_type_checking(node):
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.Import | ast.ImportFrom):
            found.append(node)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    return found


def _targets(name: str, path: Path, node: ast.Import | ast.ImportFrom,
             modules: dict[str, Path]) -> set[str]:  # fmt: skip
    if isinstance(node, ast.Import):
        names = [a.name for a in node.names]
    else:
        if node.level:
            base = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
            base = base[: len(base) - (node.level - 1)]
            module = ".".join([*base, *([node.module] if node.module else [])])
        else:
            module = node.module or ""
        names = [f"{module}.{a.name}" if f"{module}.{a.name}" in modules else module
                 for a in node.names]  # fmt: skip
    out = set()
    for target in names:
        while target not in modules and "." in target:
            target = target.rsplit(".", 1)[0]
        if target in modules and target != name:
            out.add(target)
    return out


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    modules = _modules()
    return {name: set().union(*[_targets(name, path, node, modules)
                                for node in _imports(ast.parse(path.read_text("utf-8")))])
            for name, path in modules.items()}  # fmt: skip


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module."""
    names = sorted(graph)
    position = {n: i for i, n in enumerate(names)}
    edges = [(position[a], position[b]) for a in names for b in graph[a] if b in position]
    rows, cols = zip(*edges, strict=True) if edges else ((), ())
    matrix = csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(names), len(names)))
    _, label = connected_components(matrix, directed=True, connection="strong")
    groups: dict[int, list[str]] = {}
    for name, lab in zip(names, label, strict=True):
        groups.setdefault(int(lab), []).append(name)
    return sorted(g for g in groups.values() if len(g) > 1)


def test_the_walker_sees_a_planted_circle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_circles(graph):
    assert _cycles(graph) == []


def test_libraries_do_not_import_the_orchestrator_or_the_cli(graph):
    bad = sorted(f"{m} imports {t}" for m, deps in graph.items() for t in deps
                 if any(m.startswith(f"gatetwin.{lib}") for lib in LIBRARIES)
                 and any(t == top or t.startswith(top + ".") for top in TOP_LAYERS))  # fmt: skip
    assert not bad, "\n".join(bad)


# --- the C FMU's translation units --------------------------------------------------------------
TEMPLATES = PACKAGE.parents[1] / "fmu_templates"
_DEFINITION = re.compile(r"^(?!static\b)[A-Za-z_][\w \t\*]*?\b([A-Za-z_]\w*)\s*\([^;]*$", re.M)
_CALL = re.compile(r"\b([A-Za-z_]\w*)\s*\(")


#: The components of the FMUs other than the plant's (controllers, the observer).
COMPONENTS = ("controller_", "observer")


def _c_units(component: str | None = None) -> dict[str, str]:
    """The plant FMU's translation units, or another FMU's (the glue, its core and the
    component ``<component>.c``, e.g. ``controller_mpc``): each is its own program."""
    from gatetwin.fmu.c_build import generated_blocks, generated_kernel

    units = {p.name: p.read_text("utf-8") for p in TEMPLATES.glob("*.c")}
    if component is not None:
        return {k: v for k, v in units.items()
                if k in ("fmi2_glue.c", "glue_core.c", f"{component}.c")}  # fmt: skip
    units = {k: v for k, v in units.items() if not k.startswith(COMPONENTS)}
    units.update({k: v for k, v in {**generated_blocks(), **generated_kernel()}.items()
                  if k.endswith(".c")})  # fmt: skip
    return units


def _c_graph(units: dict[str, str]) -> dict[str, set[str]]:
    """Which translation unit calls a function another one defines (externally visible)."""
    owner = {name: unit for unit, text in units.items() for name in _DEFINITION.findall(text)}
    return {unit: {owner[c] for c in _CALL.findall(text) if owner.get(c, unit) != unit}
            for unit, text in units.items()}  # fmt: skip


def test_the_c_walker_finds_definitions_and_calls():
    units = {
        "a.c": "int f(int x)\n{\n    return g(x);\n}\n",
        "b.c": "static int h(void);\nint g(int x)\n{\n    return f(x);\n}\n",
    }
    assert _c_graph(units) == {"a.c": {"b.c"}, "b.c": {"a.c"}}
    assert _cycles(_c_graph(units)) == [["a.c", "b.c"]]


def test_no_call_circles_between_c_translation_units():
    graph = _c_graph(_c_units())
    assert "component.c" in graph["effects.c"]  # the walker sees the real calls
    assert _cycles(graph) == []
    components = [p.stem for p in TEMPLATES.glob("*.c") if p.name.startswith(COMPONENTS)]
    assert {"controller_mpc", "observer"} <= set(components)
    for name in components:
        graph = _c_graph(_c_units(name))
        assert "glue_core.c" in graph["fmi2_glue.c"]  # the glue calls its core,
        assert f"{name}.c" in graph["glue_core.c"]  # which calls the component
        assert _cycles(graph) == []


def test_the_command_line_is_built_without_python_control():
    """Every gatetwin command builds the whole parser first: it must not import
    python-control (2.6 s with scipy.signal), which no command's help needs."""
    code = ("import sys; from gatetwin.cli import build_parser; build_parser(); "
            "print([m for m in ('control', 'scipy.signal') if m in sys.modules])")  # fmt: skip
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=60, check=True)  # fmt: skip
    assert run.stdout.strip() == "[]"
