"""The FMU validation harness: right models pass, wrong ones fail, bad input is refused.

Test plants are FOPDT models of gauge 3F scheduled on Q, anchored on the bundled A record
(step 15 -> 20 mm at Q = 29.5 m³/h): the level at the reference opening is the record's
pre-step mean plus K times the opening change, so the right model starts where the record
starts.

Threshold used throughout: ``fit_percent >= 85`` and ``rmse_mm <= 4``. Why this is a fair
bar for a *linear* model of a *nonlinear* gate on A: after the step the gauge noise alone
has an SD of about 2.4 mm (the reference study's Table 2, 3#F post SD 2.42 mm), so even a
perfect model's free-run RMSE is about 2 mm and its NRMSE fit is capped near
100 (1 - 2 / 31) ≈ 94 % (31 mm is the SD of the measured level over the record). The step
drops the level by 77 mm, a third of the depth; the gate law makes the level's sensitivity
to the opening vary over that range, so one gain and one time constant cost a few more
per cent. 85 % and 4 mm leave that margin, while a sign error or a dead time of a minute
drops the fit to 65 % or below.
"""

from __future__ import annotations

import json
import re
import shutil
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest

from fmu_support import with_zip_bomb
from gatetwin.cli import main
from gatetwin.fmu import export_fmu
from gatetwin.plant import ArxPlant, FopdtPlant, Schedule, simulate
from gatetwin.records import read_record, record_from_arrays
from gatetwin.validation import (
    Threshold,
    ValidationError,
    communication_grid,
    free_run_metrics,
    matrix_markdown,
    parse_thresholds,
    validate_fmu,
    validate_matrix,
)

RECORDS = Path(__file__).resolve().parents[2] / "src" / "gatetwin" / "data" / "records"
MALFORMED = Path(__file__).resolve().parents[1] / "data" / "malformed"
A, B = RECORDS / "A.csv", RECORDS / "B.csv"
THRESHOLDS = (Threshold("fit_percent", 85.0), Threshold("rmse_mm", 4.0))
CLI_THRESHOLDS = ["--fail-under", "fit_percent=85", "--fail-over", "rmse_mm=4"]
GAIN_A, GAIN_B = -15.4, -10.6
OPENING_REF_MM = 20.0


def has_compiler() -> bool:
    return bool(shutil.which("cc") or shutil.which("gcc"))


#: The backend most tests use: the native C FMU when a compiler is there.
BACKEND = "c" if has_compiler() else "python"


def _pre_step_mean(path: Path) -> tuple[float, float]:
    """3F mean over the 40 hold samples before the first step, and the opening there."""
    record = read_record(path)
    step = record.steps[0]
    level = record.levels_mm["3F"][step.before.stop - 40 : step.before.stop]
    return float(np.mean(level)), step.before.opening_mm


def plant(gain_a: float = GAIN_A, dead_time_a_s: float = 2.0) -> FopdtPlant:
    """FOPDT 3F plant matching A's operating point (and B's, at the upper knot)."""
    (h_a, e_a), (h_b, e_b) = _pre_step_mean(A), _pre_step_mean(B)
    return FopdtPlant(
        "3F",
        OPENING_REF_MM,
        Schedule(
            (29.5, 72.5),
            {
                "gain_mm_per_mm": (gain_a, GAIN_B),
                "time_constant_s": (71.0, 42.0),
                "dead_time_s": (dead_time_a_s, 2.5),
                "level_ref_mm": (
                    h_a + GAIN_A * (OPENING_REF_MM - e_a),
                    h_b + GAIN_B * (OPENING_REF_MM - e_b),
                ),
            },
        ),
    )


def export(p: FopdtPlant | ArxPlant, path: Path, backend: str = BACKEND) -> Path:
    return export_fmu(p, path, backend=backend, model_name="gate_3F", provenance={"test": 1})


@pytest.fixture(scope="module")
def fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("fmus")
    built = {
        "right": export(plant(), folder / "right.fmu"),
        "flipped": export(plant(gain_a=-GAIN_A), folder / "gain_sign_flipped.fmu"),
        "late": export(plant(dead_time_a_s=60.0), folder / "dead_time_60s.fmu"),
        "doubled": export(plant(dead_time_a_s=4.0), folder / "dead_time_doubled.fmu"),
        "right_python": export(plant(), folder / "right_python.fmu", "python"),
    }
    if has_compiler():
        built["right_c"] = built["right"]
    return built


# --------------------------------------------------------------------------- the library


def test_right_fmu_passes_and_wrong_fmus_fail_on_a(fmus: dict[str, Path]) -> None:
    right = validate_fmu(fmus["right"], [A], thresholds=THRESHOLDS)
    assert right.passed and right.static_findings == ()
    metrics = right.records[0].metrics
    assert metrics.fit_percent > 90.0 and metrics.rmse_mm < 2.5 and metrics.r2 > 0.99
    assert abs(metrics.bias_mm) < 1.0
    for name in ("flipped", "late"):
        wrong = validate_fmu(fmus[name], [A], thresholds=THRESHOLDS)
        assert not wrong.passed, name
        checks = {c.threshold.metric: c for c in wrong.records[0].checks}
        assert checks["fit_percent"].failed and checks["rmse_mm"].failed, name
        assert wrong.records[0].metrics.fit_percent < 70.0, name


def test_step_comparison_sees_a_doubled_dead_time_the_fit_cannot(fmus: dict[str, Path]) -> None:
    """2 s -> 4 s of dead time hides in the noise of the fit (both ≈ 94 %), but the FOPDT
    fits of the two responses differ by more than three samples (3.6 s) only for it."""
    timing = (*THRESHOLDS, Threshold("dead_time_abs_diff_s", 3.6))
    right = validate_fmu(fmus["right"], [A], thresholds=timing).records[0]
    doubled = validate_fmu(fmus["doubled"], [A], thresholds=timing).records[0]
    assert right.passed
    assert [c.threshold.metric for c in doubled.checks if c.failed] == ["dead_time_abs_diff_s"]
    step = right.steps[0].to_dict()
    assert step["measured"]["gain_mm_per_mm"] == pytest.approx(GAIN_A, abs=0.5)
    assert abs(step["difference"]["gain_mm_per_mm"]) < 0.5
    assert abs(step["difference"]["time_constant_s"]) < 10.0


def test_metrics_are_known_truths() -> None:
    y = np.array([1.0, 2.0, np.nan, 4.0, 5.0])
    perfect = free_run_metrics(y, y)
    assert (perfect.fit_percent, perfect.r2, perfect.rmse_mm, perfect.n) == (100.0, 1.0, 0.0, 4)
    shifted = free_run_metrics(y, y + 0.5)
    assert shifted.bias_mm == pytest.approx(0.5) and shifted.max_abs_error_mm == pytest.approx(0.5)
    assert shifted.mae_mm == pytest.approx(0.5) and shifted.rmse_mm == pytest.approx(0.5)
    mean = free_run_metrics(y, np.full(5, 3.0))
    assert mean.fit_percent == pytest.approx(0.0) and mean.r2 == pytest.approx(0.0)
    blown_up = free_run_metrics(y, np.full(5, np.inf))
    assert (
        blown_up.fit_percent == -np.inf
        and not Threshold("fit_percent", 0).check({"fit_percent": blown_up.fit_percent}).status
        == "passed"
    )


def test_grid_ignores_jitter_and_steps_across_gaps() -> None:
    t = np.array([0.0, 1.203, 2.398, 3.61, 7.2, 8.4])  # 3.61 -> 7.2 s is a 3-sample gap
    grid = communication_grid(t, 1.2)
    assert grid.steps.tolist() == [1, 1, 1, 3, 1] and grid.n_steps == 7 and grid.gaps == 1
    assert grid.index.tolist() == [0, 1, 2, 3, 6, 7]


def test_fmu_across_a_logging_gap_equals_the_reference_on_the_grid(
    fmus: dict[str, Path],
) -> None:
    full = read_record(A)
    keep = np.ones(full.n_samples, bool)
    keep[300:305] = False  # a 5-sample logging gap during the transient
    cut = record_from_arrays(
        full.time_s[keep], full.opening_mm[keep], full.hold[keep], full.flow_m3h[keep],
        {"3F": full.levels_mm["3F"][keep]}, sample_period_s=1.2, test="step", path="A_gap.csv",
    )  # fmt: skip
    result = validate_fmu(fmus["right"], [cut]).records[0]
    assert result.n_fmu_steps == full.n_samples - 1
    # reference: the Python plant on the nominal grid, inputs held through the gap
    grid = communication_grid(cut.time_s, 1.2)
    index = grid.index
    held = np.searchsorted(index, np.arange(index[-1] + 1), side="right") - 1
    t_grid = cut.time_s[0] + 1.2 * np.arange(index[-1] + 1)
    with pytest.warns(RuntimeWarning, match="outside the schedule"):  # A dips to 29.4 m³/h
        expected = simulate(plant(), t_grid, result.trace.opening_mm[held], cut.flow_m3h[held])
    with np.errstate(invalid="ignore"):
        assert np.max(np.abs(result.trace.simulated_mm - expected[index])) <= 1e-9


def test_a_gate_move_inside_a_logging_gap_is_counted_and_warned(
    fmus: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A's step falls inside ten unlogged samples (a free record then: a step test must log
    its step): the result counts the move the logger missed (A read whole has none), the
    JSON says so, and the command warns in one line."""
    step = read_record(A).steps[0].before.stop  # the first sample of the move
    lines = A.read_text(encoding="utf-8").splitlines(keepends=True)
    gap = tmp_path / "A.csv"  # the header is line 0: sample k is line k + 1
    gap.write_text("".join(lines[: step - 3] + lines[step + 7 :]), encoding="utf-8")
    sidecar = json.loads(A.with_suffix(".json").read_text(encoding="utf-8"))
    gap.with_suffix(".json").write_text(json.dumps({**sidecar, "test": "free"}), encoding="utf-8")
    assert read_record(A).unobserved_steps == 0 and read_record(gap).unobserved_steps == 1
    result = validate_fmu(fmus["right"], [gap]).records[0]
    assert result.unobserved_steps == 1 and result.to_dict()["unobserved_steps"] == 1
    capsys.readouterr()
    assert main(["validate", str(fmus["right"]), str(gap), "--json", str(tmp_path / "v.json")]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if "logging gaps" in line]
    assert warned == ["gatetwin: warning: A.csv: the gate moved inside logging gaps (1 opening "
                      "change(s)); the FMU holds the last logged opening through them, and the "
                      "metrics include the settling after them"]  # fmt: skip


def test_both_backends_give_the_same_metrics(fmus: dict[str, Path]) -> None:
    if "right_c" not in fmus:
        pytest.skip("no C compiler (cc/gcc) on PATH")
    c = validate_fmu(fmus["right_c"], [A], thresholds=THRESHOLDS)
    py = validate_fmu(fmus["right_python"], [A], thresholds=THRESHOLDS)
    assert c.passed and py.passed
    diff = c.records[0].trace.simulated_mm - py.records[0].trace.simulated_mm
    assert np.max(np.abs(diff)) <= 1e-9
    mc, mp = c.records[0].flat_metrics(), py.records[0].flat_metrics()
    assert mc.keys() == mp.keys()
    for key in mc:
        assert mc[key] == pytest.approx(mp[key], rel=1e-9, abs=1e-9), key


def test_matrix_two_fmus_by_two_records(fmus: dict[str, Path]) -> None:
    cells = validate_matrix([fmus["right"], fmus["flipped"]], [A, B], thresholds=THRESHOLDS)
    assert [(c["fmu"], c["record"]) for c in cells] == [
        ("right.fmu", "A.csv"), ("right.fmu", "B.csv"),
        ("gain_sign_flipped.fmu", "A.csv"), ("gain_sign_flipped.fmu", "B.csv"),
    ]  # fmt: skip
    by = {(c["fmu"], c["record"]): c for c in cells}
    assert by["right.fmu", "A.csv"]["passed"] and not by["gain_sign_flipped.fmu", "A.csv"]["passed"]
    assert by["gain_sign_flipped.fmu", "A.csv"]["failed_checks"] == ["fit_percent >= 85",
                                                                     "rmse_mm <= 4"]  # fmt: skip
    # the right model is anchored on B too, at the upper knot
    assert by["right.fmu", "B.csv"]["passed"] and by["right.fmu", "B.csv"]["fit_percent"] > 85
    for cell in cells:
        assert {"fmu", "record", "fit_percent", "r2", "rmse_mm", "passed"} <= cell.keys()
    json.dumps({"matrix": cells}, allow_nan=False)
    table = matrix_markdown(cells).splitlines()
    assert len(table) == 2 + 4 and table[0].startswith("| FMU | record |")
    assert all(line.count("|") == table[0].count("|") for line in table[2:4])


def test_thresholds_refuse_the_wrong_side_and_bad_text() -> None:
    under, over = parse_thresholds(["fit_percent=85"], ["rmse_mm=4"])
    assert (under.fails_when, over.fails_when) == ("below", "above")
    cases = {
        ("rmse_mm=4", ""): "rmse_mm is an error metric .* use --fail-over rmse_mm=4",
        ("", "fit_percent=85"): "use --fail-under fit_percent=85",
        ("fit=85", ""): "unknown metric 'fit'",
        ("fit_percent", ""): "expected METRIC=VALUE",
        ("fit_percent=high", ""): "'high' is not a number",
        ("fit_percent=nan", ""): "not finite",
    }
    for (u, o), message in cases.items():
        with pytest.raises(ValidationError, match=message):
            parse_thresholds([u] if u else [], [o] if o else [])


def test_step_metric_on_a_prbs_record_is_not_applicable(fmus: dict[str, Path]) -> None:
    result = validate_fmu(fmus["right"], [RECORDS / "C.csv"],
                          thresholds=[Threshold("dead_time_abs_diff_s", 1.0)])  # fmt: skip
    check = result.records[0].checks[0]
    assert check.status == "not_applicable" and result.records[0].steps == ()


# --------------------------------------------------------------------------- the command


def _outputs(tmp_path: Path) -> tuple[list[str], Path, Path, Path]:
    out = tmp_path / "out"
    json_path, junit_path, plots = out / "v.json", out / "v.xml", out / "plots"
    args = ["--json", str(json_path), "--junit", str(junit_path), "--plots", str(plots)]
    return args, json_path, junit_path, plots


def test_cli_pass_writes_json_junit_and_plots(
    fmus: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args, json_path, junit_path, plots = _outputs(tmp_path)
    assert main(["validate", str(fmus["right"]), str(A), str(B), *CLI_THRESHOLDS, *args]) == 0
    assert "passed" in capsys.readouterr().out
    doc = json.loads(json_path.read_text(encoding="utf-8"))
    assert doc["passed"] and doc["static_validation"] == {
        "tool": "fmpy.validation.validate_fmu", "findings": [], "passed": True}  # fmt: skip
    rec = doc["records"][0]
    assert rec["record"] == "A.csv" and rec["passed"] and rec["gauge"] == "3F"
    assert rec["metrics"]["fit_percent"] > 85 and len(rec["step_comparison"]) == 1
    assert [t["metric"] for t in rec["thresholds"]] == ["fit_percent", "rmse_mm"]
    assert rec["whiteness"]["n"] == 751 and 0 <= rec["whiteness"]["ljung_box_p"] <= 1
    # the test FMUs state no validity envelope: unknown, never inside
    assert rec["inside_validity"] is None and doc["fmu"]["validity"] is None
    floor = rec["noise_floor"]
    assert 0 < floor["sigma_mm"] < 5 and 0 < floor["fit_percent"] < 100
    fit = rec["metrics"]["fit_percent"]
    assert rec["fit_vs_floor"] == pytest.approx(fit - floor["fit_percent"])
    suites = ET.parse(junit_path).getroot()
    assert suites.tag == "testsuites" and len(suites.findall("testsuite")) == 1
    cases = suites.findall("testsuite/testcase")
    assert len(cases) == 1 + 2 * 3 and suites.get("failures") == "0"
    pngs = sorted(p.name for p in plots.iterdir())
    assert pngs == ["right__A_3F.png", "right__B_3F.png"]
    assert (plots / pngs[0]).read_bytes().startswith(b"\x89PNG\r\n\x1a\n")


def test_cli_leaves_a_folders_static_table_out_and_refuses_it_alone(
    fmus: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``records/*.csv`` holds the static rating table, which is no time series: named on
    stderr and left out; given alone, one error line, exit 2 and no output."""
    static = RECORDS / "static.csv"
    args, json_path, *_ = _outputs(tmp_path)
    assert main(["validate", str(fmus["right"]), str(static), str(A), *args]) == 0
    err = capsys.readouterr().err
    assert f"gatetwin: note: {static} is a static rating table, not a time series" in err
    assert [r["record"] for r in json.loads(json_path.read_text())["records"]] == ["A.csv"]
    other = tmp_path / "other"
    code = main(["validate", str(fmus["right"]), str(static), "--json", str(other / "v.json")])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and err[-1] == (f"gatetwin: error: no time series to validate: {static} "
                                     "is a static rating table")  # fmt: skip
    assert not other.exists()


def test_cli_threshold_failure_exits_1_with_junit_failures(
    fmus: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args, json_path, junit_path, _ = _outputs(tmp_path)
    assert main(["validate", str(fmus["flipped"]), str(A), *CLI_THRESHOLDS, *args]) == 1
    assert "FAILED" in capsys.readouterr().out
    assert json.loads(json_path.read_text(encoding="utf-8"))["passed"] is False
    suite = ET.parse(junit_path).getroot().find("testsuite")
    failures = suite.findall("testcase/failure")
    assert suite.get("failures") == "2" and len(failures) == 2
    assert failures[0].get("message").startswith("fit_percent = -")


def test_cli_static_findings_fail_with_exit_1(
    fmus: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = _rewrite(fmus["right"], tmp_path / "undefined_unit.fmu", lambda name, data: (
        data.replace(b'<Real unit="mm" />', b'<Real unit="furlong" />')
        if name == "modelDescription.xml" else data))  # fmt: skip
    args, json_path, junit_path, _ = _outputs(tmp_path)
    assert main(["validate", str(bad), str(A), *args]) == 1
    assert 'unit "furlong"' in capsys.readouterr().out
    doc = json.loads(json_path.read_text(encoding="utf-8"))
    assert doc["records"][0]["passed"] and not doc["static_validation"]["passed"]
    failure = ET.parse(junit_path).getroot().find("testsuite/testcase/failure")
    assert failure is not None and "furlong" in failure.get("message")


def _rewrite(src: Path, dst: Path, change) -> Path:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for name in zin.namelist():
            data = change(name, zin.read(name))
            if data is not None:
                zout.writestr(name, data)
    return dst


def _no_header_record(tmp_path: Path) -> Path:
    lines = A.read_text(encoding="utf-8").splitlines()
    header = lines[0].split(",")
    drop = header.index("level_3F_mm")
    path = tmp_path / "A_without_3F.csv"
    path.write_text("\n".join(",".join(c for i, c in enumerate(line.split(",")) if i != drop)
                              for line in lines) + "\n", encoding="utf-8")  # fmt: skip
    return path


def _arx_1s(tmp_path: Path) -> Path:
    arx = ArxPlant("3F", 20.0, 1.0, 1, 1, 1, Schedule((29.5,), {
        "a1": (0.98,), "b1": (-0.3,), "level_ref_mm": (154.0,)}))  # fmt: skip
    return export(arx, tmp_path / "arx_1s.fmu", "python")


BAD_INPUTS = {
    "random_bytes": r"random.fmu: not an FMU \(not a readable zip archive",
    "zip_without_md": r"not an FMU \(the archive has no modelDescription.xml\)",
    "no_binary": r"no binary for this platform \(expected binaries/",
    "refused_step": r"fmi2DoStep returned status 2 \(discard\) at FMU time 0 s, record sample 1; "
    r"FMU log: communication step 1.2 s is not a whole multiple",
    "bad_record": r"time_backwards.csv: row \d+: column 'time_s'",
    "no_gauge": r"A_without_3F.csv: no column level_3F_mm",
    "wrong_side": r"rmse_mm is an error metric \(lower is better\); use --fail-over rmse_mm=4",
    "other_gauge": r"no output level_5H_mm \(its level outputs: level_3F_mm\)",
    "zip_bomb": r"bomb.fmu: its members unpack to \d+ bytes, more than the limit",
}


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_cli_bad_input_is_one_line_exit_2_and_writes_nothing(
    case: str, fmus: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fmu, record, extra = fmus["right"], A, []
    if case == "random_bytes":
        fmu = tmp_path / "random.fmu"
        fmu.write_bytes(np.random.default_rng(1).bytes(4096))
    elif case == "zip_without_md":
        fmu = _rewrite(fmus["right"], tmp_path / "no_md.fmu",
                       lambda n, d: None if n == "modelDescription.xml" else d)  # fmt: skip
    elif case == "no_binary":
        fmu = _rewrite(fmus["right"], tmp_path / "no_bin.fmu",
                       lambda n, d: None if n.startswith("binaries/linux") else d)  # fmt: skip
    elif case == "refused_step":
        fmu = _arx_1s(tmp_path)
    elif case == "bad_record":
        record = MALFORMED / "time_backwards.csv"
    elif case == "no_gauge":
        record = _no_header_record(tmp_path)
    elif case == "wrong_side":
        extra = ["--fail-under", "rmse_mm=4"]
    elif case == "other_gauge":
        extra = ["--gauge", "5H"]
    elif case == "zip_bomb":
        fmu = with_zip_bomb(fmus["right"], tmp_path / "bomb.fmu")
    args, *_ = _outputs(tmp_path)
    assert main(["validate", str(fmu), str(record), *extra, *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("gatetwin: error: "), err
    assert re.search(BAD_INPUTS[case], err), err
    assert not (tmp_path / "out").exists()


def test_record_path_or_record_object_give_the_same_result(fmus: dict[str, Path]) -> None:
    by_path = validate_fmu(fmus["right"], [A]).records[0]
    by_object = validate_fmu(fmus["right"], [read_record(A)]).records[0]
    assert by_path.metrics == by_object.metrics
