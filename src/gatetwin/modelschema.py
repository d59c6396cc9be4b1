"""The model-file check: safe JSON parsing, size and character rules, and the JSON Schema.

A model file is refused before anything is built from it when it breaks any of:

* **size and shape** -- at most :data:`MAX_FILE_BYTES` bytes of UTF-8 JSON, objects and
  arrays nested at most :data:`MAX_DEPTH` levels, no key twice in one object, no ``NaN`` or
  ``Infinity`` and no number that overflows to infinity;
* **text** -- every string, object keys included, at most :data:`MAX_TEXT_CHARS`
  characters, without control characters (C0, DEL, C1), lone surrogates or the
  non-characters U+FFFE/U+FFFF (none of them can be carried by XML or a C string);
* **the schema** -- ``data/model_schema.json`` (the repository's ``models/schema.json``):
  types, required keys, ranges (physical bounds of every parameter), patterns (gauge names
  ``[A-Za-z0-9_]{1,32}``), lengths. Integers must be written as JSON integers: ``2.9``,
  ``2.0`` and ``1e6`` are not ARX orders.

The schema is read by a small interpreter of the JSON Schema keywords the file uses
(``type``, ``enum``, ``const``, ``required``, ``properties``, ``patternProperties``,
``additionalProperties``, ``maxProperties``, ``items``, ``minItems``, ``maxItems``,
``minimum``, ``maximum``, ``exclusiveMinimum``, ``exclusiveMaximum``, ``pattern``,
``maxLength``, ``allOf``, ``if``/``then``, local ``$ref``), so the schema a user reads is
the one applied. Every refusal is one :class:`~gatetwin.errors.ModelFileError` line naming
the field path (``plant.na: 1000000 is above the limit 50``) and never quoting more than
:data:`SHOW_CHARS` characters of the bad value.

This module checks; building plants from checked content is :mod:`gatetwin.plant.model`.
"""

from __future__ import annotations

import json
import math
import re
from functools import lru_cache
from importlib import resources
from typing import Any

from gatetwin.errors import ModelFileError

#: Largest model file read, bytes (the bundled ones are ~14 kB).
MAX_FILE_BYTES = 4 * 1024 * 1024
#: Deepest nesting of objects and arrays (the bundled files reach 6).
MAX_DEPTH = 32
#: Longest string or object key, characters.
MAX_TEXT_CHARS = 4096
#: Most characters of a bad value quoted in a message.
SHOW_CHARS = 60
#: Characters no model-file text may hold: C0 controls, DEL, C1 controls, surrogates,
#: U+FFFE and U+FFFF (not XML characters, or not encodable in UTF-8).
_BAD_CHAR = re.compile("[\x00-\x1f\x7f-\x9f\ud800-\udfff\ufffe\uffff]")
_PLAIN_KEY = re.compile(r"[A-Za-z0-9_$]{1,40}")


class _FieldError(Exception):
    """A refusal at ``path`` (a tuple of keys and indices)."""

    def __init__(self, path: tuple[Any, ...], message: str) -> None:
        super().__init__(message)
        self.path = path
        self.message = message


# --------------------------------------------------------------------------- showing


def show(value: Any, limit: int = SHOW_CHARS) -> str:
    """A short, printable rendering of a JSON value for an error message."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "null"
    if isinstance(value, dict):
        return "an object"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, str):
        text = value[:limit].encode("unicode_escape", "backslashreplace").decode("ascii")
        text = "'" + text.replace("'", "\\'")[:limit] + "'"
        return text if len(value) <= limit else f"{text}… ({len(value)} characters)"
    if isinstance(value, int) and abs(value) >= 10**limit:
        return f"an integer of {len(str(abs(value)))} digits"
    text = repr(value)
    return text if len(text) <= limit else text[:limit] + "…"


def format_path(path: tuple[Any, ...], limit: int = 120) -> str:
    """``plant.schedule.flow_m3h[2]``; odd keys quoted and clipped; long paths elided."""
    parts = []
    for item in path:
        if isinstance(item, int):
            parts.append(f"[{item}]")
        elif _PLAIN_KEY.fullmatch(item):
            parts.append(f".{item}" if parts else item)
        else:
            parts.append(f"[{show(item, 20)}]")
    text = "".join(parts) or "(top level)"
    return text if len(text) <= limit else text[: limit // 2] + "…" + text[-limit // 3 :]


def _limit(value: float) -> str:
    if float(value).is_integer() and abs(value) < 1e15:
        return str(int(value))
    return f"{value:g}"


# --------------------------------------------------------------------------- parsing


def _refuse_constant(name: str) -> Any:
    raise _FieldError((), f"{name} is not a number a model file may hold")


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _FieldError((), f"key {show(key)} appears twice in one object")
        out[key] = value
    return out


def parse_model_json(raw: bytes) -> Any:
    """Parse a model file's bytes; :class:`ModelFileError` (without the file name) when the
    bytes are too many, not UTF-8, not JSON or nested too deep."""
    if len(raw) > MAX_FILE_BYTES:
        raise ModelFileError(f"larger than {MAX_FILE_BYTES} bytes; not a model file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ModelFileError(f"not UTF-8 (byte {exc.start}); not a JSON model file") from None
    try:
        return json.loads(text, parse_constant=_refuse_constant, object_pairs_hook=_unique_keys)
    except _FieldError as exc:
        raise ModelFileError(exc.message) from None
    except RecursionError:
        raise ModelFileError(
            f"nested too deep for a model file (at most {MAX_DEPTH} levels)"
        ) from None
    except json.JSONDecodeError as exc:
        raise ModelFileError(
            f"not a JSON model file ({exc.msg}: line {exc.lineno} column {exc.colno})"
        ) from None
    except ValueError as exc:  # e.g. an integer literal of more than 4300 digits
        raise ModelFileError(f"not a JSON model file ({show(str(exc), 80)[1:-1]})") from None


# --------------------------------------------------------------------------- global rules


def text_problem(text: str) -> str:
    """Why ``text`` cannot be model-file text ("" when it can)."""
    if len(text) > MAX_TEXT_CHARS:
        return f"text of {len(text)} characters is longer than the limit {MAX_TEXT_CHARS}"
    bad = _BAD_CHAR.search(text)
    if bad is None:
        return ""
    code = ord(bad.group())
    what = "lone surrogate" if 0xD800 <= code <= 0xDFFF else (
        "non-character" if code >= 0xFFFE else "control character")  # fmt: skip
    return f"{what} U+{code:04X} at character {bad.start()} of {show(text)}"


def _check_node(value: Any, path: tuple[Any, ...]) -> None:
    if isinstance(value, str):
        why = text_problem(value)
        if why:
            raise _FieldError(path, why)
    elif isinstance(value, float) and not math.isfinite(value):
        raise _FieldError(path, f"{show(value)} is not a finite number")


def check_general_rules(content: Any, root: tuple[Any, ...] = ()) -> None:
    """Depth, text and finiteness rules on every value and key (iterative, any depth)."""
    stack: list[tuple[Any, tuple[Any, ...]]] = [(content, root)]
    while stack:
        value, path = stack.pop()
        if isinstance(value, (dict, list)) and len(path) - len(root) >= MAX_DEPTH:
            raise _FieldError(path, f"nested deeper than {MAX_DEPTH} levels")
        if isinstance(value, dict):
            for key, item in reversed(value.items()):
                why = text_problem(key)
                if why:
                    raise _FieldError(path, f"key: {why}")
                stack.append((item, (*path, key)))
        elif isinstance(value, list):
            stack.extend((item, (*path, i)) for i, item in reversed(list(enumerate(value))))
        else:
            _check_node(value, path)


# --------------------------------------------------------------------------- the schema


@lru_cache(maxsize=1)
def model_schema() -> dict[str, Any]:
    """The model-file JSON Schema (``gatetwin/data/model_schema.json``)."""
    text = (resources.files("gatetwin") / "data" / "model_schema.json").read_text("utf-8")
    return json.loads(text)


_TYPE_NAMES = {"object": "an object", "array": "a list", "string": "a string",
               "number": "a number", "integer": "a JSON integer", "boolean": "true or false",
               "null": "null"}  # fmt: skip


def _is_type(value: Any, kind: str) -> bool:
    if kind == "object":
        return isinstance(value, dict)
    if kind == "array":
        return isinstance(value, list)
    if kind == "string":
        return isinstance(value, str)
    if kind == "boolean":
        return isinstance(value, bool)
    if kind == "null":
        return value is None
    if isinstance(value, bool):
        return False
    return isinstance(value, int) or (kind == "number" and isinstance(value, float))


def _resolve(schema: dict[str, Any], root: dict[str, Any]) -> dict[str, Any]:
    while "$ref" in schema:
        ref = schema["$ref"]
        if not ref.startswith("#/"):
            raise ValueError(f"model schema: only local $ref are supported, not {ref}")
        target: Any = root
        for part in ref[2:].split("/"):
            target = target[part]
        schema = {**target, **{k: v for k, v in schema.items() if k != "$ref"}}
    return schema


def _check_type(value: Any, schema: dict[str, Any], path: tuple[Any, ...]) -> None:
    kinds = schema.get("type")
    if kinds is None:
        return
    kinds = [kinds] if isinstance(kinds, str) else kinds
    if any(_is_type(value, k) for k in kinds):
        return
    wanted = " or ".join(_TYPE_NAMES[k] for k in kinds)
    raise _FieldError(path, f"{show(value)} is not {wanted}")


def _check_number(value: Any, schema: dict[str, Any], path: tuple[Any, ...]) -> None:
    if "maximum" in schema and value > schema["maximum"]:
        raise _FieldError(path, f"{show(value)} is above the limit {_limit(schema['maximum'])}")
    if "exclusiveMaximum" in schema and not value < schema["exclusiveMaximum"]:
        raise _FieldError(path, f"{show(value)} must be below {_limit(schema['exclusiveMaximum'])}")
    if "minimum" in schema and value < schema["minimum"]:
        raise _FieldError(path, f"{show(value)} is below the limit {_limit(schema['minimum'])}")
    if "exclusiveMinimum" in schema and not value > schema["exclusiveMinimum"]:
        raise _FieldError(path, f"{show(value)} must be above {_limit(schema['exclusiveMinimum'])}")


def _check_string(value: str, schema: dict[str, Any], path: tuple[Any, ...]) -> None:
    if "maxLength" in schema and len(value) > schema["maxLength"]:
        raise _FieldError(path, f"text of {len(value)} characters is longer than the limit "
                             f"{schema['maxLength']}")  # fmt: skip
    if "pattern" in schema and not re.search(schema["pattern"], value):
        raise _FieldError(path, f"{show(value)} does not match {schema['pattern']}")


def _check_object(value: dict[str, Any], schema: dict[str, Any], path: tuple[Any, ...],
                  root: dict[str, Any]) -> None:  # fmt: skip
    if "maxProperties" in schema and len(value) > schema["maxProperties"]:
        raise _FieldError(path, f"{len(value)} keys, more than the limit {schema['maxProperties']}")
    for key in schema.get("required", ()):
        if key not in value:
            raise _FieldError(path, f"key {key!r} missing")
    properties = schema.get("properties", {})
    patterns = schema.get("patternProperties", {})
    extra = schema.get("additionalProperties", True)
    for key, item in value.items():
        matched = [s for p, s in patterns.items() if re.search(p, key)]
        if key in properties:
            matched.append(properties[key])
        if not matched and extra is False:
            raise _FieldError(path, f"unknown key {show(key)}")
        if not matched and isinstance(extra, dict):
            matched.append(extra)
        for sub in matched:
            _check(item, sub, (*path, key), root)


def _check_array(value: list[Any], schema: dict[str, Any], path: tuple[Any, ...],
                 root: dict[str, Any]) -> None:  # fmt: skip
    if "maxItems" in schema and len(value) > schema["maxItems"]:
        raise _FieldError(path, f"{len(value)} items, more than the limit {schema['maxItems']}")
    if "minItems" in schema and len(value) < schema["minItems"]:
        raise _FieldError(path, f"{len(value)} item(s), fewer than the {schema['minItems']} needed")
    if "items" in schema:
        for i, item in enumerate(value):
            _check(item, schema["items"], (*path, i), root)


def _holds(value: Any, schema: dict[str, Any], root: dict[str, Any]) -> bool:
    try:
        _check(value, schema, (), root)
    except _FieldError:
        return False
    return True


def _check(value: Any, schema: dict[str, Any], path: tuple[Any, ...],
           root: dict[str, Any]) -> None:  # fmt: skip
    schema = _resolve(schema, root)
    _check_type(value, schema, path)
    if "enum" in schema and value not in schema["enum"]:
        choices = ", ".join(map(str, schema["enum"]))
        raise _FieldError(path, f"{show(value)} is not one of {choices}")
    if "const" in schema and value != schema["const"]:
        raise _FieldError(path, f"{show(value)} is not {schema['const']!r}")
    if _is_type(value, "number"):
        _check_number(value, schema, path)
    elif isinstance(value, str):
        _check_string(value, schema, path)
    elif isinstance(value, dict):
        _check_object(value, schema, path, root)
    elif isinstance(value, list):
        _check_array(value, schema, path, root)
    for sub in schema.get("allOf", ()):
        _check(value, sub, path, root)
    if "if" in schema and "then" in schema and _holds(value, schema["if"], root):
        _check(value, schema["then"], path, root)


def _run(content: Any, schema: dict[str, Any], root: tuple[Any, ...]) -> None:
    try:
        check_general_rules(content, root)
        _check(content, schema, root, model_schema())
    except _FieldError as exc:
        raise ModelFileError(f"{format_path(exc.path)}: {exc.message}") from None


def check_model_document(content: Any) -> None:
    """Check a parsed model file against every rule; :class:`ModelFileError` names the
    field path of the first fault (``plant.na: 1000000 is above the limit 50``)."""
    _run(content, model_schema(), ())


def check_plant_section(data: Any) -> None:
    """Check a model file's ``plant`` section alone (paths start at ``plant``)."""
    _run(data, model_schema()["properties"]["plant"], ("plant",))
