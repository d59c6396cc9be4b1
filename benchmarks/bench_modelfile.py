"""Cost of checking a model file when it is read (prints; never asserts).

For every bundled model file, side by side in one run: parsing the JSON and building the
plant without any check (``json.loads`` + ``plant_from_dict`` minus its section check),
the check alone (:func:`gatetwin.modelschema.check_model_document`), and the whole
:func:`gatetwin.modelfile.read_model_file`; then the ratio of the whole read to the bare
parse-and-build.

Run: ``python benchmarks/bench_modelfile.py``. Times are the best of a few repeats
(``time.perf_counter``).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any
from unittest import mock

from gatetwin.modelfile import read_model_file
from gatetwin.modelschema import check_model_document
from gatetwin.plant.model import plant_from_dict

MODELS = Path(__file__).resolve().parents[1] / "models"


def best_of(func: Callable[[], Any], repeats: int = 30) -> float:
    """Smallest wall time of ``repeats`` calls, s."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        func()
        best = min(best, time.perf_counter() - start)
    return best


def bare_read(path: Path) -> Any:
    """Parse and build (called with the section check switched off)."""
    return plant_from_dict(json.loads(path.read_bytes())["plant"])


def main() -> None:
    print(f"{'model file':<18} {'bare read (ms)':>15} {'check (ms)':>11} "
          f"{'read_model_file (ms)':>21} {'ratio':>6}")  # fmt: skip
    for path in sorted(MODELS.glob("*.json")):
        if path.name == "schema.json":
            continue
        doc = json.loads(path.read_bytes())
        with mock.patch("gatetwin.modelschema.check_plant_section"):
            bare = best_of(lambda p=path: bare_read(p))
        check = best_of(lambda d=doc: check_model_document(d))
        full = best_of(lambda p=path: read_model_file(p))
        print(f"{path.name:<18} {bare * 1e3:>15.3f} {check * 1e3:>11.3f} "
              f"{full * 1e3:>21.3f} {full / bare:>5.1f}×")  # fmt: skip


if __name__ == "__main__":
    main()
