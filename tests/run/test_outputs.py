"""Where gatetwin writes and what it reads from archives: read-only destinations, the
ownership of ``gatetwin run --out``, stale work folders of killed runs, FMU zip members."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from gatetwin._io import write_json_atomic
from gatetwin.cli import main
from gatetwin.errors import OutputError, PipelineError, ValidationError
from gatetwin.run.outdir import MARKER, RUN_PID_FILE, clean_stale_work
from gatetwin.run.pipeline import STAGES, PipelineContext, PipelineStage, run_pipeline
from gatetwin.validation import inspect_fmu

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT / "models"
RECORDS = ROOT / "src" / "gatetwin" / "data" / "records"
#: The record-checking stages of gatetwin run (seconds, not a minute).
CHECKING = STAGES[:3]


@pytest.fixture()
def records_dir(tmp_path: Path) -> Path:
    folder = tmp_path / "records"
    folder.mkdir()
    for name in ("A.csv", "A.json", "static.csv"):
        shutil.copyfile(RECORDS / name, folder / name)
    return folder


@pytest.fixture()
def read_only(tmp_path: Path):
    """A folder nothing can be written into: mode 0o555, or immutable when running as root
    (root ignores modes); skipped where neither holds."""
    folder = tmp_path / "locked"
    folder.mkdir()
    folder.chmod(0o555)
    immutable = False
    if os.access(folder, os.W_OK) and shutil.which("chattr"):
        immutable = subprocess.run(["chattr", "+i", str(folder)], capture_output=True,
                                   check=False).returncode == 0  # fmt: skip
    try:
        probe = folder / "probe"
        try:
            probe.write_text("x")
        except OSError:
            pass
        else:
            probe.unlink()
            pytest.skip("cannot make a read-only folder here")
        yield folder
    finally:
        if immutable:
            subprocess.run(["chattr", "-i", str(folder)], check=False)
        folder.chmod(0o755)


def _one_error_line(capsys) -> str:
    """The one error line, last on stderr (``run`` prints its progress lines before it)."""
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if line.startswith("gatetwin: error: ")]
    assert len(errors) == 1 and err.splitlines()[-1] == errors[0], err
    assert "Traceback" not in err
    return errors[0]


# --------------------------------------------------------------------------- read-only


@pytest.mark.parametrize(
    "argv",
    [["export", str(MODELS / "arx_3F.json"), "--backend", "c", "--out", "{ro}/m.fmu"],
     ["export", str(MODELS / "arx_3F.json"), "--backend", "python", "--out", "{ro}/d/m.fmu"],
     ["identify", str(RECORDS / "A.csv"), "--json", "{ro}/a.json"],
     ["models", "--out", "{ro}/models"],
     ["run", "--out", "{ro}/out"]],
    ids=["export-c", "export-python", "identify", "models", "run"],
)  # fmt: skip
def test_a_read_only_destination_is_one_line(read_only, capsys, monkeypatch, argv):
    import importlib

    suite = importlib.import_module("gatetwin.identification.suite")

    def never(*args, **kwargs):  # refused before the long identification starts
        raise AssertionError("identification ran before the destination was checked")

    monkeypatch.setattr(suite, "identify_folder", never)
    code = main([a.replace("{ro}", str(read_only)) for a in argv])
    line = _one_error_line(capsys)
    assert code == 2 and str(read_only) in line and "cannot write" in line
    assert list(read_only.iterdir()) == []


def test_atomic_write_into_a_read_only_folder_is_an_output_error(read_only):
    with pytest.raises(OutputError, match="cannot write"):
        write_json_atomic(read_only / "x.json", {"a": 1})
    assert list(read_only.iterdir()) == []


# --------------------------------------------------------------------------- ownership


def _stage(action):
    return PipelineStage("meddling", action)


def test_a_folder_created_at_out_during_the_run_is_left_alone(records_dir, tmp_path):
    target = tmp_path / "out"

    def someone_creates_it(ctx: PipelineContext) -> None:
        target.mkdir()
        (target / "thesis.tex").write_text("precious", encoding="utf-8")

    with pytest.raises(PipelineError, match="was created while the run went") as info:
        run_pipeline(target, records_dir=records_dir,
                     stages=(*CHECKING, _stage(someone_creates_it)))  # fmt: skip
    assert (target / "thesis.tex").read_text(encoding="utf-8") == "precious"
    kept = Path(str(info.value).rsplit("output is in ", 1)[1])
    assert kept.parent == tmp_path and kept.name.startswith("out.gatetwin-run-")
    assert (kept / "records.json").is_file() and (kept / MARKER).is_file()
    assert not (kept / RUN_PID_FILE).exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["records", "out", kept.name])


def test_an_own_folder_swapped_for_another_during_the_run_is_left_alone(records_dir, tmp_path):
    target = run_pipeline(tmp_path / "out", records_dir=records_dir, stages=CHECKING)

    def someone_swaps_it(ctx: PipelineContext) -> None:
        target.rename(tmp_path / "moved")
        target.mkdir()
        (target / "data.csv").write_text("mine", encoding="utf-8")
        (target / MARKER).write_text("copied along", encoding="utf-8")

    with pytest.raises(PipelineError, match="replaced by another folder"):
        run_pipeline(target, records_dir=records_dir, stages=(*CHECKING, _stage(someone_swaps_it)))
    assert (target / "data.csv").read_text(encoding="utf-8") == "mine"


def test_an_own_folder_that_lost_its_marker_is_left_alone(records_dir, tmp_path):
    target = run_pipeline(tmp_path / "out", records_dir=records_dir, stages=CHECKING)

    def someone_takes_it_over(ctx: PipelineContext) -> None:
        (target / MARKER).unlink()

    with pytest.raises(PipelineError, match="lost its 'gatetwin run' marker"):
        run_pipeline(target, records_dir=records_dir,
                     stages=(*CHECKING, _stage(someone_takes_it_over)))  # fmt: skip
    assert (target / "records.json").is_file()


def test_cli_run_says_where_the_result_went_in_one_line(tmp_path, capsys, monkeypatch):
    import functools

    import gatetwin.run.pipeline as pipeline

    target = tmp_path / "out"
    stages = (_stage(lambda ctx: target.mkdir()),)
    monkeypatch.setattr(pipeline, "run_pipeline", functools.partial(run_pipeline, stages=stages))
    assert main(["run", "--out", str(target)]) == 2
    line = _one_error_line(capsys)
    assert "was created while the run went" in line and "out.gatetwin-run-" in line


# --------------------------------------------------------------------------- stale folders


def _dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def _work_folder(parent: Path, name: str, pid: int) -> Path:
    folder = parent / name
    folder.mkdir()
    (folder / RUN_PID_FILE).write_text(f"{pid}\n{os.uname().nodename}\n", encoding="utf-8")
    (folder / "records.json").write_text("[]", encoding="utf-8")
    return folder


def test_stale_work_folders_are_removed_and_live_ones_reported(tmp_path):
    import socket

    assert os.uname().nodename == socket.gethostname()
    dead = _work_folder(tmp_path, ".out.dead1234.tmp", _dead_pid())
    live = _work_folder(tmp_path, ".out.live1234.tmp", os.getppid())
    foreign = tmp_path / ".out.user.tmp"  # named alike, but no run's file in it: not ours
    foreign.mkdir()
    lines: list[str] = []
    # a pid file that does not parse (a disk that filled as it was written) is no live run's
    empty = _work_folder(tmp_path, ".out.empty123.tmp", 0)
    (empty / RUN_PID_FILE).write_text("", encoding="utf-8")
    removed = clean_stale_work(tmp_path / "out", lines.append)
    assert sorted(removed) == sorted([dead, empty]) and not dead.exists() and not empty.exists()
    assert live.exists() and foreign.exists()
    assert any(str(live) in line and "may still be going" in line for line in lines)


# --------------------------------------------------------------------------- a full disk

#: A file-size limit (RLIMIT_FSIZE, bytes) the command runs under: a write past it fails as
#: on a full disk (EFBIG instead of ENOSPC). The flume's A.csv (38 kB) fits, C.csv (75 kB)
#: does not.
FSIZE_BYTES = 50_000


def _limited(command: list[str], fsize: int) -> subprocess.CompletedProcess[str]:
    """``gatetwin COMMAND`` in a child process whose files may not grow past ``fsize``."""

    def limit() -> None:
        import resource

        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # the write fails instead
        if fsize >= 0:  # -1: no limit
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))

    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    return subprocess.run([sys.executable, "-m", "gatetwin.cli", *command], env=env,
                          capture_output=True, text=True, preexec_fn=limit,
                          timeout=300)  # fmt: skip


def test_a_flume_run_that_runs_out_of_room_leaves_nothing(tmp_path):
    """A.csv and its sidecar are written, C.csv cannot be: the command fails in one line and
    removes what it wrote and the folders it made (here two levels)."""
    # once without the limit first: a fresh install's first run writes its bytecode and
    # numba caches, which the limit would stop before any record
    warm = tmp_path.parent / f"{tmp_path.name}_warm"
    assert _limited(["flume", "--out", str(warm), "--only", "A"], -1).returncode == 0
    shutil.rmtree(warm)
    out = tmp_path / "new" / "flume"
    done = _limited(["flume", "--out", str(out), "--only", "A", "C"], FSIZE_BYTES)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert lines[-1].startswith("gatetwin: error:") and "C.csv: cannot write" in lines[-1]
    assert "Traceback" not in done.stderr
    assert list(tmp_path.iterdir()) == []


def test_a_run_whose_pid_file_cannot_be_written_leaves_no_work_folder(tmp_path):
    done = _limited(["run", "--out", str(tmp_path / "out")], 0)
    assert done.returncode == 2 and "cannot write the output" in done.stderr, done.stderr
    assert list(tmp_path.iterdir()) == []


def test_what_a_failed_block_added_is_undone_and_what_was_there_stays(tmp_path):
    from gatetwin._io import undone_on_failure

    out = tmp_path / "out"  # a folder that existed: nothing in it is touched
    (out / "kept").mkdir(parents=True)
    (out / "mine.txt").write_text("mine")
    with pytest.raises(OutputError), undone_on_failure(out):
        (out / "written.csv").write_text("x")
        raise OutputError("disk full")
    assert sorted(p.name for p in out.iterdir()) == ["kept", "mine.txt", "written.csv"]
    for keep_files in (False, True):  # a folder the block made goes, or only its empty ones
        new = tmp_path / f"new_{keep_files}"
        with pytest.raises(OutputError), undone_on_failure(new, keep_files=keep_files):
            (new / "empty" / "deeper").mkdir(parents=True)
            (new / "gate").mkdir()
            (new / "gate" / "model.json").write_text("{}")
            raise OutputError("disk full")
        left = sorted(str(p.relative_to(new)) for p in new.rglob("*")) if new.exists() else []
        assert left == (["gate", "gate/model.json"] if keep_files else [])
    with pytest.raises(KeyboardInterrupt), undone_on_failure(tmp_path / "a" / "b") as made:
        (made / "c.csv").parent.mkdir(parents=True)
        (made / "c.csv").write_text("x")
        raise KeyboardInterrupt
    assert not (tmp_path / "a").exists()
    with undone_on_failure(tmp_path / "ok") as made:  # nothing raised: all stays
        made.mkdir()
        (made / "x").write_text("x")
    assert (tmp_path / "ok" / "x").is_file()


SLOW_RUN = """
import sys, time
from gatetwin.run.pipeline import STAGES, PipelineStage, run_pipeline
def wait(ctx):
    print("started", flush=True)
    time.sleep(120)
run_pipeline(sys.argv[1], records_dir=sys.argv[2],
             stages=(*STAGES[:1], PipelineStage("waiting", wait)))
"""


def test_the_work_folder_of_a_killed_run_is_cleaned_by_the_next(records_dir, tmp_path):
    target = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    with subprocess.Popen([sys.executable, "-c", SLOW_RUN, str(target), str(records_dir)],
                          stdout=subprocess.PIPE, text=True, env=env) as run:  # fmt: skip
        try:
            assert run.stdout.readline().strip() == "started"
        finally:
            run.send_signal(signal.SIGKILL)
            run.wait()
    left = list(tmp_path.glob(".out.*.tmp"))
    assert len(left) == 1 and (left[0] / RUN_PID_FILE).is_file()
    lines: list[str] = []
    run_pipeline(target, progress=lines.append, records_dir=records_dir, stages=CHECKING)
    assert not left[0].exists() and (target / MARKER).is_file()
    assert any("removed" in line and str(left[0]) in line for line in lines)


# --------------------------------------------------------------------------- FMU archives


@pytest.mark.parametrize(
    ("member", "why"),
    [("/tmp/evil.txt", "is an absolute path"), ("../evil.txt", "climbs out"),
     ("resources/../../evil.txt", "climbs out"), ("C:/evil.txt", "is an absolute path"),
     ("..\\evil.txt", "climbs out")],
)  # fmt: skip
def test_an_fmu_with_members_outside_its_folder_is_refused(tmp_path, capsys, member, why):
    fmu = tmp_path / "evil.fmu"
    with zipfile.ZipFile(fmu, "w") as zf:
        zf.writestr("modelDescription.xml", '<?xml version="1.0"?><fmiModelDescription/>')
        info = zipfile.ZipInfo("placeholder")
        info.filename = member  # ZipInfo would normalise it; the attack writes it raw
        zf.writestr(info, b"evil")
    with pytest.raises(ValidationError, match=why):
        inspect_fmu(fmu)
    out = tmp_path / "v.json"
    code = main(["validate", str(fmu), str(RECORDS / "A.csv"), "--json", str(out)])
    line = _one_error_line(capsys)
    assert code == 2 and why in line and not out.exists()
    assert not (tmp_path.parent / "evil.txt").exists()
    assert json.dumps(line)  # one printable line
