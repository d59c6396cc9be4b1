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

The schema is applied by ``jsonschema`` (draft 2020-12), so the schema a user reads is the
one applied; the checks before it (size, depth, text, finiteness, duplicate keys) are what
JSON Schema cannot say or what must hold before any of it runs. Every refusal is one
:class:`~gatetwin.errors.ModelFileError` line naming
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

__all__ = [
    "MAX_DEPTH",
    "MAX_FILE_BYTES",
    "MAX_TEXT_CHARS",
    "SHOW_CHARS",
    "check_general_rules",
    "check_model_document",
    "check_plant_section",
    "format_path",
    "model_schema",
    "parse_model_json",
    "show",
    "text_problem",
]

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


@lru_cache(maxsize=2)
def _validator(section: str = "") -> Any:
    """The validator (jsonschema, draft 2020-12) of the whole schema, or of one top-level
    ``section`` (its definitions kept for its ``$ref``), with one change: an integer is a
    JSON integer (``2.0`` is a number, not an ARX order; JSON Schema would accept it)."""
    from jsonschema import Draft202012Validator, validators

    schema = model_schema()
    if section:
        schema = {"$defs": {**schema["$defs"], "section": schema["properties"][section]},
                  "$ref": "#/$defs/section"}  # fmt: skip
    strict = Draft202012Validator.TYPE_CHECKER.redefine("integer",
                                                        lambda _, v: type(v) is int)  # fmt: skip
    return validators.extend(Draft202012Validator, type_checker=strict)(schema)


def _unknown_key(value: dict[str, Any], schema: dict[str, Any]) -> str:
    """The first key of ``value`` that neither ``properties`` nor ``patternProperties`` of
    ``schema`` admits."""
    patterns = schema.get("patternProperties", {})
    return next(k for k in value if k not in schema.get("properties", {})
                and not any(re.search(p, k) for p in patterns))  # fmt: skip


def _type_message(value: Any, limit: Any, _: Any) -> str:
    kinds = [limit] if isinstance(limit, str) else limit
    return f"{show(value)} is not {' or '.join(_TYPE_NAMES[k] for k in kinds)}"


#: The line of each JSON Schema keyword the schema uses: (value, the keyword's value, error).
_MESSAGES: dict[str, Any] = {
    "type": _type_message,
    "maximum": lambda v, lim, _: f"{show(v)} is above the limit {_limit(lim)}",
    "minimum": lambda v, lim, _: f"{show(v)} is below the limit {_limit(lim)}",
    "exclusiveMaximum": lambda v, lim, _: f"{show(v)} must be below {_limit(lim)}",
    "exclusiveMinimum": lambda v, lim, _: f"{show(v)} must be above {_limit(lim)}",
    "maxLength": lambda v, lim, _: f"text of {len(v)} characters is longer than the limit {lim}",
    "pattern": lambda v, lim, _: f"{show(v)} does not match {lim}",
    "enum": lambda v, lim, _: f"{show(v)} is not one of {', '.join(map(str, lim))}",
    "const": lambda v, lim, _: f"{show(v)} is not {lim!r}",
    "required": lambda v, lim, _: f"key {next(k for k in lim if k not in v)!r} missing",
    "additionalProperties": lambda v, _, e: f"unknown key {show(_unknown_key(v, e.schema))}",
    "maxProperties": lambda v, lim, _: f"{len(v)} keys, more than the limit {lim}",
    "maxItems": lambda v, lim, _: f"{len(v)} items, more than the limit {lim}",
    "minItems": lambda v, lim, _: f"{len(v)} item(s), fewer than the {lim} needed",
}


def _message(error: Any) -> str:
    """One short line for a jsonschema error, quoting no more of the value than :func:`show`."""
    if error.validator in _MESSAGES:
        return _MESSAGES[error.validator](error.instance, error.validator_value, error)
    return show(error.message, 2 * SHOW_CHARS)[1:-1]  # a keyword the schema does not use yet


def _run(content: Any, section: str, root: tuple[Any, ...]) -> None:
    try:
        check_general_rules(content, root)
    except _FieldError as exc:
        raise ModelFileError(f"{format_path(exc.path)}: {exc.message}") from None
    error = next(_validator(section).iter_errors(content), None)
    if error is not None:
        path = (*root, *error.absolute_path)
        raise ModelFileError(f"{format_path(path)}: {_message(error)}")


def check_model_document(content: Any) -> None:
    """Check a parsed model file against every rule; :class:`ModelFileError` names the
    field path of the first fault (``plant.na: 1000000 is above the limit 50``)."""
    _run(content, "", ())


def check_plant_section(data: Any) -> None:
    """Check a model file's ``plant`` section alone (paths start at ``plant``)."""
    _run(data, "plant", ("plant",))
