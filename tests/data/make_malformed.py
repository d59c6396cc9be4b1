"""Write the malformed records of ``tests/data/malformed/`` (one defect per file).

Run from anywhere: ``python tests/data/make_malformed.py``. Every file starts from one
small valid step-test record (60 hold samples at 15 mm, 3 ``open`` samples, 60 hold
samples at 20 mm, gauges 3F and 5H) and breaks it in exactly one way; the file is named
for its defect. The generated files are committed; ``tests/cli/test_cli_malformed.py`` holds
what each refusal must say. Row numbers below are file lines (header = row 1).
"""

from __future__ import annotations

import json
import math
import random
from collections.abc import Callable
from pathlib import Path

HERE = Path(__file__).resolve().parent / "malformed"
HEADER = ["time_s", "opening_mm", "state", "flow_m3h", "level_3F_mm", "level_5H_mm"]
PERIOD_S = 1.2

Rows = list[list[str]]


def _level(t: float, t_step: float | None, offset: float) -> str:
    level = 231.6 + offset + 0.3 * math.sin(7.0 * t)
    if t_step is not None and t > t_step + 4.5:
        level -= 76.3 * (1.0 - math.exp(-(t - t_step - 4.5) / 71.2))
    return f"{level:.1f}"


def segments_record(segments: list[tuple[str, float | None, int]]) -> Rows:
    """Rows for ``(state, opening, n_samples)`` segments; the level follows the first step."""
    rows: Rows = []
    t_step = None
    first_opening = segments[0][1]
    for state, opening, count in segments:
        for _ in range(count):
            t = len(rows) * PERIOD_S
            moved = opening is not None and opening != first_opening
            if t_step is None and (state == "open" or moved):
                t_step = t
            cells = [f"{t:.1f}", "" if opening is None else f"{opening:g}", state, "29.5"]
            cells += [_level(t, t_step, 0.0), _level(t, t_step, 6.4)]
            rows.append(cells)
    return rows


def base_rows() -> Rows:
    """The valid record every malformed file starts from."""
    return segments_record([("hold", 15.0, 60), ("open", None, 3), ("hold", 20.0, 60)])


def to_text(rows: Rows, header: list[str] = HEADER, sep: str = ",") -> str:
    return "\n".join(sep.join(row) for row in [header, *rows]) + "\n"


def set_cell(rows: Rows, row: int, name: str, value: str) -> Rows:
    """Copy of ``rows`` with file row ``row`` (header = 1), column ``name`` set."""
    out = [list(r) for r in rows]
    out[row - 2][HEADER.index(name)] = value
    return out


def drop_columns(rows: Rows, names: list[str]) -> str:
    keep = [j for j, name in enumerate(HEADER) if name not in names]
    return to_text([[r[j] for j in keep] for r in rows], [HEADER[j] for j in keep])


def static_text(flow_cell: str = "26.3", scale: float = 1.0) -> str:
    lines = ["flow_m3h,opening_mm,level_3F_mm,level_3F_sd_mm"]
    for k, (opening, level) in enumerate([(15, 241.0), (20, 161.5), (30, 120.2)]):
        flow = flow_cell if k == 1 else "26.3"
        lines.append(f"{flow},{opening},{level * scale:g},0.4")
    return "\n".join(lines) + "\n"


def _binary_garbage() -> bytes:
    rng = random.Random(0)
    data = bytearray(range(256)) * 4
    rng.shuffle(data)
    return bytes(data)


def _not_utf8() -> bytes:
    text = to_text(set_cell(base_rows(), 4, "flow_m3h", "29.5MU"))
    return text.encode("utf-8").replace(b"29.5MU", b"29.5\xb5")


def _ragged() -> str:
    rows = base_rows()
    rows[25 - 2] = rows[25 - 2][:-1]
    return to_text(rows)


def _blank_line() -> str:
    lines = to_text(base_rows()).split("\n")
    lines.insert(29, "")
    return "\n".join(lines)


def _quoted_newline() -> str:
    lines = to_text(base_rows()).split("\n")
    lines[4] = lines[4].replace(",hold,", ',"hold\n",')
    return "\n".join(lines)


def _all_openings(value: str, rows: Rows | None = None) -> Rows:
    rows = base_rows() if rows is None else rows
    return [[r[0], value if r[2] == "hold" else "", *r[2:]] for r in rows]


def _scaled_levels(rows: Rows, factor: float) -> Rows:
    return [[*r[:4], f"{float(r[4]) * factor:.4f}", f"{float(r[5]) * factor:.4f}"] for r in rows]


def _prbs_short() -> Rows:
    segments: list[tuple[str, float | None, int]] = []
    for opening in (35.0, 45.0, 35.0, 25.0):
        segments += [("hold", opening, 8), ("open", None, 2)]
    return segments_record(segments[:-1])


def _time_backwards() -> Rows:
    return set_cell(base_rows(), 20, "time_s", "20.0")


#: file name -> content (str or bytes) or a function returning it.
CSV_FILES: dict[str, Callable[[], str | bytes]] = {
    "empty.csv": lambda: b"",
    "header_only.csv": lambda: ",".join(HEADER) + "\n",
    "missing_state_column.csv": lambda: drop_columns(base_rows(), ["state"]),
    "missing_level_column.csv": lambda: drop_columns(base_rows(), ["level_3F_mm", "level_5H_mm"]),
    "duplicate_column.csv": lambda: to_text(base_rows(), [*HEADER[:5], "level_3F_mm"]),
    "text_in_level.csv": lambda: to_text(set_cell(base_rows(), 7, "level_3F_mm", "231.6mm")),
    "text_in_time.csv": lambda: to_text(set_cell(base_rows(), 9, "time_s", "00:00:09")),
    "time_backwards.csv": lambda: to_text(_time_backwards()),
    "duplicated_time.csv": lambda: to_text(set_cell(base_rows(), 30, "time_s", "32.4")),
    "unknown_state.csv": lambda: to_text(set_cell(base_rows(), 12, "state", "moving")),
    "empty_state.csv": lambda: to_text(set_cell(base_rows(), 15, "state", "")),
    "all_open.csv": lambda: to_text([[*r[:2], "open", *r[3:]] for r in base_rows()]),
    "semicolon.csv": lambda: to_text(base_rows(), sep=";"),
    "decimal_comma.csv": lambda: to_text([[c.replace(".", ",") for c in r] for r in base_rows()]),
    "binary_garbage.csv": _binary_garbage,
    "not_utf8.csv": _not_utf8,
    "utf16.csv": lambda: to_text(base_rows()).encode("utf-16"),
    "levels_in_metres.csv": lambda: to_text(_scaled_levels(base_rows(), 0.001)),
    "level_out_of_range.csv": lambda: to_text(set_cell(base_rows(), 40, "level_5H_mm", "500000")),
    "nan_literal.csv": lambda: to_text(set_cell(base_rows(), 10, "level_3F_mm", "nan")),
    "inf_literal.csv": lambda: to_text(set_cell(base_rows(), 11, "flow_m3h", "inf")),
    "ragged_row.csv": _ragged,
    "blank_line_inside.csv": _blank_line,
    "quoted_newline.csv": _quoted_newline,
    "negative_flow.csv": lambda: to_text(set_cell(base_rows(), 33, "flow_m3h", "-29.5")),
    "negative_opening.csv": lambda: to_text(set_cell(base_rows(), 8, "opening_mm", "-15")),
    "empty_time.csv": lambda: to_text(set_cell(base_rows(), 16, "time_s", "")),
    "empty_flow.csv": lambda: to_text(
        [
            [*r[: HEADER.index("flow_m3h")], "", *r[HEADER.index("flow_m3h") + 1 :]]
            for r in base_rows()
        ]
    ),  # fmt: skip
    "hold_without_opening.csv": lambda: to_text(
        [[r[0], "" if k >= 63 else r[1], *r[2:]] for k, r in enumerate(base_rows())]
    ),
    "step_without_step.csv": lambda: to_text(_all_openings("15")),
    "too_few_samples_step.csv": lambda: to_text(
        segments_record([("hold", 15.0, 20), ("open", None, 3), ("hold", 20.0, 60)])
    ),
    "prbs_too_short.csv": lambda: to_text(_prbs_short()),
    "bad_sidecar.csv": lambda: to_text(base_rows()),
    "bad_test_word.csv": lambda: to_text(base_rows()),
    "bad_sample_period.csv": lambda: to_text(base_rows()),
    "sidecar_not_object.csv": lambda: to_text(base_rows()),
    "static_text_in_flow.csv": lambda: static_text(flow_cell="approx 26"),
    "static_levels_in_metres.csv": lambda: static_text(scale=0.001),
}

#: sidecar name -> JSON text.
JSON_FILES: dict[str, str] = {
    "step_without_step.json": json.dumps({"condition": "A", "test": "step"}),
    "too_few_samples_step.json": json.dumps({"condition": "A", "test": "step"}),
    "prbs_too_short.json": json.dumps({"condition": "C", "test": "prbs"}),
    "bad_sidecar.json": '{"test": "step",\n "sample_period_s": 1.2,,\n "condition": "A"}',
    "bad_test_word.json": json.dumps({"test": "ramp"}),
    "bad_sample_period.json": json.dumps({"test": "step", "sample_period_s": -1.2}),
    "sidecar_not_object.json": json.dumps(["step", 1.2]),
}


def main() -> None:
    HERE.mkdir(parents=True, exist_ok=True)
    for name, make in CSV_FILES.items():
        content = make()
        data = content.encode("utf-8") if isinstance(content, str) else content
        (HERE / name).write_bytes(data)
    for name, text in JSON_FILES.items():
        (HERE / name).write_text(text + "\n", encoding="utf-8")
    print(f"wrote {len(CSV_FILES)} CSV and {len(JSON_FILES)} JSON files to {HERE}")


if __name__ == "__main__":
    main()
