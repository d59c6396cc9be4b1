"""The harness survives the FMU: crashes, exits, hangs and NaN fail a cell, never the run.

The hostile FMUs are the exported C FMU of the right A/B plant (``test_validate.plant``)
rebuilt from its own ``sources/`` with a patched ``fmi2_glue.c``: the original
``fmi2DoStep`` and ``fmi2GetReal`` become static and are wrapped by versions that, once the
FMU has made more than ``AFTER_STEPS`` steps *and* the discharge input exceeds
``FLOW_ABOVE_M3H``, call ``exit(0)``, call ``abort()``, write through a null pointer, spin
forever, or return NaN from ``fmi2GetReal``. Record B is held near 72.5 m³/h and A near
29.5 m³/h, so each hostile FMU misbehaves on B only and must still pass on A, run after B
in a fresh child process (the right plant fits A at > 90 %, far above the criterion
``fit_percent=70`` used here, see ``test_validate``).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest

from fmu_support import compiler
from gatetwin.records import read_record
from gatetwin.validation import (
    ValidationError,
    communication_grid,
    junit_xml,
    plot_record,
    validate_fmu,
    validate_matrix,
)
from gatetwin.validation.fmu_runner import MAX_FMU_STEPS
from hostile_fmus import ACTIONS, AFTER_STEPS, build_hostile
from test_validate import A, B, export, plant

pytestmark = pytest.mark.skipif(compiler() is None, reason="no C compiler (cc/gcc) on PATH")

SRC = Path(__file__).resolve().parents[2] / "src"
#: Wall-clock limit given to every hostile run, s: the right FMU needs ~0.01 s for A or B.
TIMEOUT_S = 3.0

#: Where B's misbehaving run stops: the step after AFTER_STEPS steps, from record sample
#: AFTER_STEPS (FMU time 10 × 1.2 s on B's grid, which starts at 0 s) to the next.
STOP = rf"at t = {AFTER_STEPS * 1.2:g} s \(record sample {AFTER_STEPS + 1}\)"
#: What the cell on B must say.
CAUSES = {
    "exit": rf"the FMU called exit\(0\) during fmi2DoStep {STOP}",
    "abort": rf"the FMU process died with signal 6 \(SIGABRT\) during fmi2DoStep {STOP}",
    "null_write": rf"the FMU process died with signal 11 \(SIGSEGV\) during fmi2DoStep {STOP}",
    "hang": rf"no result within {TIMEOUT_S:g} s \(the FMU was in fmi2DoStep {STOP}\); its "
    "process was killed",
    # the first NaN is read at the end of that step
    "nan": rf"output level_3F_mm not finite \(nan\) at t = {(AFTER_STEPS + 1) * 1.2:g} s "
    rf"\(record sample {AFTER_STEPS + 1}\)",
}


@pytest.fixture(scope="module")
def fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("hostile")
    good = export(plant(), folder / "right.fmu", "c")
    return {"right": good, **{kind: build_hostile(good, kind, folder) for kind in ACTIONS}}


def _validate_cli(fmu: Path, records: list[Path], out: Path, *extra: str
                  ) -> tuple[subprocess.CompletedProcess[str], float]:  # fmt: skip
    """``gatetwin validate`` in its own process, with a private, empty TMPDIR."""
    tmp = out / "tmp"
    tmp.mkdir(parents=True)
    env = {
        **os.environ,
        "TMPDIR": str(tmp),
        "PYTHONPATH": os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")]),
    }
    command = [sys.executable, "-m", "gatetwin.cli", "validate", str(fmu), *map(str, records),
               "--fail-under", "fit_percent=70", "--json", str(out / "v.json"),
               "--junit", str(out / "v.xml"), *extra]  # fmt: skip
    start = time.perf_counter()
    # the guard only keeps a broken harness from hanging the suite
    run = subprocess.run(command, env=env, capture_output=True, text=True, timeout=300)
    return run, time.perf_counter() - start


@pytest.mark.parametrize("kind", sorted(ACTIONS))
def test_hostile_fmu_fails_its_cell_and_the_report_is_written(
    kind: str, fmus: dict[str, Path], tmp_path: Path
) -> None:
    run, _ = _validate_cli(fmus[kind], [B, A], tmp_path, "--timeout", str(TIMEOUT_S))
    assert run.returncode == 1, run.stderr
    assert run.stdout.rstrip().endswith("FAILED")
    doc = json.loads((tmp_path / "v.json").read_text(encoding="utf-8"))
    on_b, on_a = doc["records"]
    assert (on_b["record"], on_a["record"]) == ("B.csv", "A.csv")
    assert re.fullmatch(CAUSES[kind], on_b["failure_cause"]), on_b["failure_cause"]
    assert on_b["passed"] is False and doc["passed"] is False
    # A runs after the crash, in a fresh child, and passes
    assert on_a["failure_cause"] is None and on_a["passed"], on_a
    assert on_a["metrics"]["fit_percent"] > 90.0
    assert f"B.csv: FMU run failed: {on_b['failure_cause']}" in run.stderr
    case = (
        ET.parse(tmp_path / "v.xml")
        .getroot()
        .find(f"testsuite/testcase[@classname='gatetwin.validate.hostile_{kind}.B']")
    )
    failure = case.find("failure")
    assert failure.get("type") == "FmuRunFailure"
    assert failure.get("message") == on_b["failure_cause"]
    assert list((tmp_path / "tmp").iterdir()) == []  # every temporary folder removed


def test_nan_output_fails_without_any_threshold(fmus: dict[str, Path]) -> None:
    result = validate_fmu(fmus["nan"], [B, A], timeout_s=TIMEOUT_S)
    on_b, on_a = result.records
    assert not on_b.passed and re.fullmatch(CAUSES["nan"], on_b.failure_cause)
    assert on_b.checks == () and on_a.passed and not result.passed
    # the NaN sample is the first after AFTER_STEPS steps; earlier output is the right FMU's
    right = validate_fmu(fmus["right"], [B]).records[0].trace.simulated_mm
    np.testing.assert_array_equal(on_b.trace.simulated_mm[: AFTER_STEPS + 1],
                                  right[: AFTER_STEPS + 1])  # fmt: skip
    assert np.isnan(on_b.trace.simulated_mm[AFTER_STEPS + 1])


def test_a_run_that_gave_nothing_still_renders(fmus: dict[str, Path]) -> None:
    """Every output of a crashed cell renders here, where warnings are errors."""
    result = validate_fmu(fmus["abort"], [B], timeout_s=TIMEOUT_S)
    rec = result.records[0]
    assert np.all(np.isnan(rec.trace.simulated_mm)) and rec.failure_cause
    assert plot_record(result, rec).startswith(b"\x89PNG\r\n\x1a\n")
    assert 'type="FmuRunFailure"' in junit_xml([result])
    doc = json.loads(json.dumps(result.to_dict(), allow_nan=False))
    assert doc["records"][0]["failure_cause"] == rec.failure_cause


def test_matrix_completes_around_hostile_fmus(fmus: dict[str, Path]) -> None:
    """In this very process: isolation keeps the test process alive through them all."""
    order = ["right", "abort", "exit", "null_write", "hang", "nan"]
    cells = validate_matrix([fmus[k] for k in order], [B, A], timeout_s=TIMEOUT_S,
                            thresholds=())  # fmt: skip
    by = {(c["fmu"], c["record"]): c for c in cells}
    assert len(cells) == 2 * len(order)
    assert by["right.fmu", "B.csv"]["passed"] and by["right.fmu", "A.csv"]["passed"]
    for kind in order[1:]:
        bad, good = by[f"hostile_{kind}.fmu", "B.csv"], by[f"hostile_{kind}.fmu", "A.csv"]
        assert re.fullmatch(CAUSES[kind], bad["failure_cause"]), (kind, bad["failure_cause"])
        assert not bad["passed"] and bad["failed_checks"][0].startswith("FMU run failed: ")
        assert good["passed"] and good["failure_cause"] is None, kind


def test_isolated_and_in_process_runs_agree(fmus: dict[str, Path]) -> None:
    isolated = validate_fmu(fmus["right"], [A, B])
    local = validate_fmu(fmus["right"], [A, B], isolate=False)
    for a, b in zip(isolated.records, local.records, strict=True):
        np.testing.assert_array_equal(a.trace.simulated_mm, b.trace.simulated_mm)
        assert a.metrics == b.metrics and a.run_time_s > 0 and b.run_time_s > 0


def _with_gap(tmp_path: Path, gap_s: float) -> Path:
    """A with every time stamp from row 100 on shifted by ``gap_s``."""
    lines = A.read_text(encoding="utf-8").splitlines()
    column = lines[0].split(",").index("time_s")
    for i in range(101, len(lines)):
        cells = lines[i].split(",")
        cells[column] = repr(float(cells[column]) + gap_s)
        lines[i] = ",".join(cells)
    path = tmp_path / f"A_gap_{gap_s:g}.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    (tmp_path / f"{path.stem}.json").write_text(A.with_suffix(".json").read_text("utf-8"),
                                                encoding="utf-8")  # fmt: skip
    return path


def test_a_gap_of_1e9_s_is_refused_before_any_fmu_runs(
    fmus: dict[str, Path], tmp_path: Path
) -> None:
    record = _with_gap(tmp_path, 1e9)
    run, seconds = _validate_cli(fmus["right"], [A, record], tmp_path / "out")
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert re.match(r"gatetwin: error: .*A_gap_1e\+09\.csv: .*(gap|steps)", run.stderr)
    assert not (tmp_path / "out" / "v.json").exists()
    assert not (tmp_path / "out" / "v.xml").exists()
    assert list((tmp_path / "out" / "tmp").iterdir()) == []


def test_grid_limit_is_stated_and_names_the_gap() -> None:
    t = np.array([0.0, 1.2, 2.4, 2.4 + 1e9, 3.6 + 1e9])
    with pytest.raises(ValidationError, match=r"largest gap 1e\+09 s after t = 2.4 s"):
        communication_grid(t, 1.2)
    assert communication_grid(t[:3], 1.2).n_steps == 2
    # the limit itself: exactly MAX_FMU_STEPS steps pass, one more does not
    edge = np.array([0.0, 1.2 * MAX_FMU_STEPS])
    assert communication_grid(edge, 1.2).n_steps == MAX_FMU_STEPS
    with pytest.raises(ValidationError, match=f"more than the {MAX_FMU_STEPS} allowed"):
        communication_grid(np.array([0.0, 1.2 * (MAX_FMU_STEPS + 1)]), 1.2)
    # a gap that would overflow int64 steps is refused, not wrapped around
    with pytest.raises(ValidationError, match="communication steps"):
        communication_grid(np.array([0.0, 1e300]), 1.2)


@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf"])
def test_timeout_must_be_a_positive_number(value: str, fmus: dict[str, Path]) -> None:
    with pytest.raises(ValidationError, match="timeout .* must be a finite number"):
        validate_fmu(fmus["right"], [read_record(A)], timeout_s=float(value))
