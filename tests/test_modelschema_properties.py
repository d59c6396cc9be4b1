"""Property tests: malformed model files, generated, are refused in one line and nothing is
written; whatever the check accepts, the JSON Schema accepts too.

Each example starts from a bundled model file and breaks it one way: a control character,
lone surrogate or non-character in any string or key, an over-long string, nesting past
the limit, a typed field given another type or a value past its bound, a non-finite
number, a required key removed. A fixed small budget runs in the default suite; the
``slow`` variant runs a larger one.
"""

from __future__ import annotations

import contextlib
import io
import json
import tempfile
from pathlib import Path
from typing import Any

import jsonschema
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gatetwin.cli import main
from gatetwin.errors import ModelFileError
from gatetwin.modelfile import read_model_file
from gatetwin.modelschema import MAX_DEPTH, MAX_TEXT_CHARS, check_model_document, model_schema

MODELS = Path(__file__).resolve().parents[1] / "models"
BASES = {name: json.loads((MODELS / f"{name}.json").read_text(encoding="utf-8"))
         for name in ("arx_3F", "fopdt_3F", "physical_3F")}  # fmt: skip
#: Longest refusal line: file, field path, at most 60 quoted characters and the wording.
MAX_LINE_CHARS = 400
#: Stands for a raw JSON token (NaN, 1e400) that json.dumps cannot write.
RAW = "\x00RAW\x00"
BUDGET = settings(
    max_examples=40,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
#: The schema's bound on a physical kernel parameter: a value past it is refused.
KERNEL_MAX = model_schema()["$defs"]["kernel_parameters"]["additionalProperties"]["maximum"]
PAST_KERNEL_MAX = KERNEL_MAX * (1.0 + 1e-9)
#: The schema's bound on an opening, mm (canal gates open by metres): a value past it is refused.
PAST_OPENING_MAX = model_schema()["$defs"]["opening"]["maximum"] + 0.5
BAD_CHARS = [chr(c) for c in range(0x20)] + ["\x7f", "\x85", "\x9f", "\ud800", "\udbff",
                                              "\udc00", "\udfff", "\ufffe", "\uffff"]  # fmt: skip


def _paths(node: Any, path: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    out = [path]
    if isinstance(node, dict):
        for key, value in node.items():
            out += _paths(value, (*path, key))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            out += _paths(value, (*path, i))
    return out


PATHS = {name: _paths(doc)[1:] for name, doc in BASES.items()}


def _get(doc: Any, path: tuple[Any, ...]) -> Any:
    for key in path:
        doc = doc[key]
    return doc


def _put(doc: Any, path: tuple[Any, ...], value: Any) -> Any:
    if not path:
        return value
    _get(doc, path[:-1])[path[-1]] = value
    return doc


DICT_PATHS = {name: [p for p in [(), *PATHS[name]] if isinstance(_get(BASES[name], p), dict)]
              for name in BASES}  # fmt: skip
NUMBER_PATHS = {name: [p for p in PATHS[name]
                       if isinstance(_get(BASES[name], p), float)] for name in BASES}  # fmt: skip


def _copy(name: str) -> Any:
    return json.loads(json.dumps(BASES[name]))


@st.composite
def bad_text(draw) -> tuple[str, Any]:
    name = draw(st.sampled_from(sorted(BASES)))
    path = draw(st.sampled_from(PATHS[name]))
    head = draw(st.text(max_size=20))
    text = head + draw(st.sampled_from(BAD_CHARS)) + draw(st.text(max_size=20))
    return name, _put(_copy(name), path, text)


@st.composite
def bad_key(draw) -> tuple[str, Any]:
    name = draw(st.sampled_from(sorted(BASES)))
    path = draw(st.sampled_from(DICT_PATHS[name]))
    key = draw(st.one_of(
        st.tuples(st.text(max_size=10), st.sampled_from(BAD_CHARS)).map("".join),
        st.integers(MAX_TEXT_CHARS + 1, 3 * MAX_TEXT_CHARS).map(lambda n: "k" * n),
    ))  # fmt: skip
    doc = _copy(name)
    _get(doc, path)[key] = draw(st.integers())
    return name, doc


@st.composite
def long_text(draw) -> tuple[str, Any]:
    name = draw(st.sampled_from(sorted(BASES)))
    path = draw(st.sampled_from(PATHS[name]))
    size = draw(st.integers(MAX_TEXT_CHARS + 1, 4 * MAX_TEXT_CHARS))
    return name, _put(_copy(name), path, "z" * size)


@st.composite
def too_deep(draw) -> tuple[str, Any]:
    name = draw(st.sampled_from(sorted(BASES)))
    path = draw(st.sampled_from(PATHS[name]))
    value: Any = draw(st.sampled_from([0, "x", None, []]))
    for _ in range(MAX_DEPTH + 1 - len(path) + draw(st.integers(0, 200))):
        value = draw(st.sampled_from([[value], {"k": value}]))
    return name, _put(_copy(name), path, value)


@st.composite
def non_finite(draw) -> tuple[str, Any]:
    name = draw(st.sampled_from(sorted(BASES)))
    path = draw(st.sampled_from(NUMBER_PATHS[name]))
    token = draw(st.sampled_from(["NaN", "Infinity", "-Infinity", "1e400", "-2e999"]))
    return name, (_put(_copy(name), path, RAW), token)


def _wrong_for_integer() -> st.SearchStrategy[Any]:
    return st.one_of(
        st.floats(allow_nan=False, allow_infinity=False),  # 2.0 too: not a JSON integer
        st.integers(51, 10**30), st.integers(-10**30, 0), st.booleans(), st.text(max_size=5),
        st.lists(st.integers(1, 3), max_size=3), st.none(),
    )  # fmt: skip


#: (path, strategy of values the field must refuse) for each family.
TYPED: list[tuple[str, tuple[Any, ...], Any]] = [
    ("arx_3F", ("plant", "na"), _wrong_for_integer()),
    ("arx_3F", ("plant", "nb"), _wrong_for_integer()),
    ("arx_3F", ("plant", "nk"), _wrong_for_integer()),
    (
        "arx_3F",
        ("plant", "sample_period_s"),
        st.one_of(st.floats(max_value=0.0, allow_nan=False), st.floats(3600.5, 1e308), st.text()),
    ),
    (
        "fopdt_3F",
        ("plant", "opening_ref_mm"),
        st.one_of(
            st.floats(PAST_OPENING_MAX, 1e308), st.floats(-1e308, -0.5), st.booleans(), st.text()
        ),
    ),
    (
        "fopdt_3F",
        ("plant", "gauge"),
        st.one_of(
            st.text(min_size=33, max_size=60, alphabet="ab1_"),
            st.just(""),
            st.text(min_size=1, max_size=8).filter(lambda t: not t.isascii()),
            st.integers(),
            st.none(),
        ),
    ),
    (
        "fopdt_3F",
        ("plant", "schedule", "gain_mm_per_mm", 0),
        st.one_of(st.floats(1000.5, 1e308), st.floats(-1e308, -1000.5), st.text(), st.none()),
    ),
    (
        "fopdt_3F",
        ("plant", "schedule", "time_constant_s", 2),
        st.one_of(st.floats(max_value=0.0, allow_nan=False), st.floats(86400.5, 1e308)),
    ),
    (
        "physical_3F",
        ("plant", "parameters", "area_m2"),
        st.one_of(
            st.floats(PAST_KERNEL_MAX, 1e308),
            st.floats(-1e308, -PAST_KERNEL_MAX),
            st.text(),
            st.none(),
        ),
    ),
    (
        "fopdt_3F",
        ("provenance",),
        st.one_of(st.integers(), st.text(max_size=5), st.lists(st.integers(), max_size=2)),
    ),
    ("fopdt_3F", ("validity",), st.one_of(st.floats(allow_nan=False), st.text(max_size=5))),
    (
        "physical_3F",
        ("plant", "kind"),
        st.text(max_size=10).filter(lambda t: t not in ("fopdt", "arx", "physical")),
    ),
    ("arx_3F", ("provenance", "records"), st.dictionaries(st.text(max_size=3), st.integers())),
]


@st.composite
def wrong_typed(draw) -> tuple[str, Any]:
    name, path, values = draw(st.sampled_from(TYPED))
    return name, _put(_copy(name), path, draw(values))


REQUIRED = [("name",), ("plant",), ("validity",), ("provenance",), ("schema_version",),
            ("gauge",), ("operating_point",), ("plant", "kind"), ("plant", "schedule"),
            ("plant", "schedule", "flow_m3h"), ("validity", "flow_m3h")]  # fmt: skip


@st.composite
def missing_key(draw) -> tuple[str, Any]:
    name = draw(st.sampled_from(sorted(BASES)))
    path = draw(st.sampled_from(REQUIRED))
    doc = _copy(name)
    del _get(doc, path[:-1])[path[-1]]
    return name, doc


MALFORMED = st.one_of(bad_text(), bad_key(), long_text(), too_deep(), non_finite(),
                      wrong_typed(), missing_key())  # fmt: skip


def _text(doc: Any) -> str:
    if isinstance(doc, tuple):  # (document with a RAW placeholder, raw token)
        body, token = doc
        return json.dumps(body).replace(json.dumps(RAW), token)
    return json.dumps(doc)


def _refused_in_one_line(case: tuple[str, Any]) -> None:
    _, doc = case
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.json"
        path.write_text(_text(doc), encoding="utf-8", errors="surrogatepass")
        out = Path(tmp) / "out" / "model.fmu"
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            code = main(["export", str(path), "--backend", "c", "--out", str(out)])
        lines = err.getvalue().splitlines()
        assert code == 2, err.getvalue()[:300]
        assert len(lines) == 1 and lines[0].startswith(f"gatetwin: error: {path}: "), lines
        assert len(lines[0]) <= MAX_LINE_CHARS, lines[0][:500]
        assert not (Path(tmp) / "out").exists()
        assert sorted(p.name for p in Path(tmp).iterdir()) == ["model.json"]
        with pytest.raises(ModelFileError):
            read_model_file(path)


@BUDGET
@given(MALFORMED)
def test_malformed_model_files_are_refused_in_one_line(case):
    _refused_in_one_line(case)


@pytest.mark.slow
@settings(BUDGET, max_examples=1500)
@given(MALFORMED)
def test_malformed_model_files_are_refused_in_one_line_long_run(case):
    _refused_in_one_line(case)


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-100, 100) | st.floats(-1e4, 1e4)
    | st.text(max_size=6),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=4), inner,
                                                                max_size=3),
    max_leaves=6,
)  # fmt: skip


@BUDGET
@given(st.sampled_from(sorted(BASES)), st.data())
def test_what_the_check_accepts_the_json_schema_accepts(name, data):
    # the check is the schema plus stricter rules: it never lets through what the schema
    # refuses (any value at any place of a valid file)
    doc = _put(_copy(name), data.draw(st.sampled_from(PATHS[name])), data.draw(JSON_VALUES))
    try:
        check_model_document(doc)
    except ModelFileError:
        return
    jsonschema.validate(doc, model_schema())
