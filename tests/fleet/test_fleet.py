"""Many gates: one model set per gate, the same bytes serially, on a local process pool and
on a real dask.distributed cluster; a broken gate is reported, not fatal."""

from __future__ import annotations

import filecmp
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from dask_support import dask_cluster
from gatetwin.fleet import write_district

#: Files that say how the fleet was run (mode, worker count): they differ by design.
RUN_DESCRIPTIONS = {"fleet.json", "fleet.md", "fleet.html", "fleet.png"}


def _models(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "gatetwin", "models", *args],
                          capture_output=True, text=True, timeout=900)  # fmt: skip


def _same_model_files(a: Path, b: Path) -> list[str]:
    """Paths that differ between two fleet outputs (gate folders only)."""
    differ = []
    for path in sorted(p for p in a.rglob("*") if p.is_file()):
        rel = path.relative_to(a)
        if rel.name in RUN_DESCRIPTIONS and len(rel.parts) == 1:
            continue
        other = b / rel
        if not other.is_file() or not filecmp.cmp(path, other, shallow=False):
            differ.append(str(rel))
    return differ


@pytest.fixture(scope="module")
def district(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("district")
    write_district(3, out, seed=7)
    return out


@pytest.fixture(scope="module")
def serial(district, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("serial") / "models"
    done = _models("--records", str(district), "--out", str(out), "--workers", "1")
    assert done.returncode == 0, done.stderr[-2000:]
    return out


# ~40 s with the serial fleet; tests/fleet/test_fleet_routine.py keeps a fleet in the default run
@pytest.mark.slow
def test_every_gate_gets_a_model_set_and_the_summary_lists_it(serial):
    doc = json.loads((serial / "fleet.json").read_text())
    assert (doc["n_gates"], doc["n_ok"], doc["n_failed"]) == (3, 3, 0)
    for gate in ("gate001", "gate002", "gate003"):
        names = {p.name.split("_")[0] for p in (serial / gate).glob("*_*.json")}
        assert {"fopdt", "physical"} <= names, (gate, names)


@pytest.mark.slow  # ~30 s; test_fleet_routine.py keeps a 2-process pool in the default run
def test_a_process_pool_writes_the_same_model_files(district, serial, tmp_path):
    out = tmp_path / "pool"
    done = _models("--records", str(district), "--out", str(out), "--workers", "2")
    assert done.returncode == 0, done.stderr[-2000:]
    assert _same_model_files(serial, out) == []


def _dask_models(district: Path, tmp_path: Path) -> Path:
    """``gatetwin models --scheduler`` on a real scheduler and two worker processes on
    localhost; the output folder."""
    with dask_cluster(tmp_path) as address:
        out = tmp_path / "dask"
        done = _models("--records", str(district), "--out", str(out), "--scheduler", address)
        assert done.returncode in (0, 1), done.stderr[-2000:]  # 1: a gate failed, reported
        assert (out / "fleet.json").is_file(), done.stderr[-2000:]
        assert "dask" in json.loads((out / "fleet.json").read_text())["mode"]
        return out


@pytest.mark.slow  # ~30 s; the default run keeps dask through test_validate_spread.py (~15 s)
def test_a_dask_scheduler_and_two_workers_write_the_same_model_files(district, serial,
                                                                     tmp_path):  # fmt: skip
    out = _dask_models(district, tmp_path)
    assert json.loads((out / "fleet.json").read_text())["n_failed"] == 0
    assert _same_model_files(serial, out) == []


@pytest.mark.long
@pytest.mark.slow
def test_fifty_gates_on_dask_write_the_serial_runs_model_files(tmp_path):
    """50 generated gates: the dask cluster's model files are the serial run's, byte for
    byte, and so is the list of gates that failed (a gate the fit cannot serve fails alike
    in both modes)."""
    district = tmp_path / "district"
    write_district(50, district, seed=11)
    serial = tmp_path / "serial"
    done = _models("--records", str(district), "--out", str(serial), "--workers", "1")
    assert done.returncode in (0, 1), done.stderr[-2000:]
    out = _dask_models(district, tmp_path)
    docs = [json.loads((d / "fleet.json").read_text()) for d in (serial, out)]
    assert docs[0]["n_gates"] == docs[1]["n_gates"] == 50
    assert docs[0]["n_ok"] == docs[1]["n_ok"] > 0
    failed = [sorted(g["gate"] for g in d["gates"] if g.get("status") != "ok") for d in docs]
    assert failed[0] == failed[1]
    assert _same_model_files(serial, out) == []


@pytest.mark.slow  # ~25 s; a fleet of three gates identified
def test_a_broken_gate_is_reported_and_the_others_are_written(district, tmp_path):
    records = tmp_path / "records"
    shutil.copytree(district, records)
    victim = next(p for p in sorted((records / "gate002").glob("*.csv")) if "static" not in p.name)
    victim.write_text("time_s,opening_mm\nnot,a,record\n")
    out = tmp_path / "out"
    # an earlier run into the same --out identified gate002: what it wrote there goes with
    # the rerun, a file the user put there stays
    (out / "gate002").mkdir(parents=True)
    (out / "gate002" / "fopdt_3F.json").write_text("{}")
    (out / "gate002" / "notes.txt").write_text("mine")
    (out / "fleet.json").write_text(json.dumps(
        {"gates": [{"gate": "gate002", "status": "ok", "models": ["fopdt_3F"]}]}))  # fmt: skip
    done = _models("--records", str(records), "--out", str(out), "--workers", "1")
    assert done.returncode == 1, done.stderr[-2000:]
    doc = json.loads((out / "fleet.json").read_text())
    assert (doc["n_ok"], doc["n_failed"]) == (2, 1)
    failed = [g for g in doc["gates"] if g["status"] != "ok"]
    assert [g["gate"] for g in failed] == ["gate002"] and victim.name in json.dumps(failed[0])
    assert any((out / "gate001").glob("*.json"))
    assert [p.name for p in (out / "gate002").iterdir()] == ["notes.txt"]


def test_a_rerun_removes_only_what_the_earlier_run_wrote_for_a_gate(tmp_path):
    from gatetwin.fleet.run import _remove_earlier_outputs

    for extra in ([], ["notes.txt"]):
        folder = tmp_path / f"gate_{len(extra)}"
        (folder / "fmus").mkdir(parents=True)
        written = ["schema.json", "fopdt_3F.json", "routine_fopdt_3F.json", "fmus/fopdt_3F.fmu"]
        for name in [*written, *extra]:
            (folder / name).write_text("x")
        _remove_earlier_outputs(folder, ["fopdt_3F"])
        if extra:
            assert sorted(p.name for p in folder.iterdir()) == extra
        else:
            assert not folder.exists()  # nothing of the user's: the folder goes too


def test_pool_processes_run_their_numerical_libraries_on_one_thread(monkeypatch):
    """A pool process starts with one BLAS/OpenMP thread unless the caller chose a count,
    and the caller's own environment is left as it was."""
    import os

    from gatetwin.fleet.execute import POOL_THREADS, FleetSettings, run_tasks

    for key in POOL_THREADS:
        monkeypatch.delenv(key, raising=False)
    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    names = sorted(POOL_THREADS)
    seen = run_tasks(os.getenv, names, FleetSettings(workers=2),
                     lambda _job, exc: exc)  # fmt: skip
    expected = {**POOL_THREADS, "OMP_NUM_THREADS": "3"}
    assert seen == [expected[k] for k in names]
    assert [os.environ.get(k) for k in names] == [
        "3" if k == "OMP_NUM_THREADS" else None for k in names]  # fmt: skip


def test_a_shared_pool_serves_every_call_and_is_replaced_when_it_loses_a_process():
    """Inside ``shared_pool`` the calls run on the same processes (what lets the stages of
    ``gatetwin run`` import and compile once); jobs that kill their process fail alone, and
    the next call gets a new pool instead of a broken one, also when a process died while
    the pool was idle."""
    import os
    import signal
    import time

    from gatetwin.fleet.execute import FleetSettings, run_tasks, shared_pool

    settings = FleetSettings(workers=2)
    with shared_pool(settings):
        first = set(run_tasks(_pid, range(6), settings, _kept_reason))
        second = set(run_tasks(_pid, range(6), settings, _kept_reason))
        died = run_tasks(os._exit, [3, 3], settings, _kept_reason)
        after = run_tasks(_pid, range(6), settings, _kept_reason)
        # a process killed while idle, between two calls: the next call gets a new pool
        os.kill(after[0], signal.SIGKILL)
        time.sleep(2.0)  # the pool's manager thread notices the death and marks it broken
        again = run_tasks(_pid, range(6), settings, _kept_reason)
    assert len(first) == 2 and first == second and os.getpid() not in first
    assert all("terminated abruptly" in r for r in died), died
    assert all(isinstance(p, int) for p in after + again), (after, again)
    assert not set(after) & first and not set(again) & set(after)


def _pid(_job: object) -> int:
    """This process's id, after 0.3 s: long enough that both processes of a pool take jobs."""
    import os
    import time

    time.sleep(0.3)
    return os.getpid()


def _kept_reason(_job: object, exc: BaseException) -> str:
    return str(exc)


@pytest.mark.parametrize("where", ["under a file", "under /proc"])
def test_an_output_that_cannot_be_written_is_refused_before_any_gate_runs(district, tmp_path,
                                                                         where):  # fmt: skip
    """The fleet checks ``--out`` as the other commands do, before identifying anything: a
    refusal comes at once (a gate's identification alone takes seconds), in one line."""
    if where == "under /proc" and not Path("/proc").is_dir():
        pytest.skip("no /proc on this platform")
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    out = blocker / "models" if where == "under a file" else Path("/proc/gatetwin-out")
    done = _models("--records", str(district), "--out", str(out), "--workers", "1")
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr[-2000:]
    assert str(out) in lines[0] and "cannot write" in lines[0]
    assert "fleet:" not in done.stderr  # no gate was started


@pytest.mark.parametrize("address", ["x:::", "tcp://no-such-host.invalid:8786"])
def test_a_scheduler_address_that_cannot_be_resolved_is_one_line_at_once(district, tmp_path,
                                                                          address):  # fmt: skip
    """Refused before a dask Client exists: one that failed half-way held the exit for 40 s
    closing itself, then printed its TimeoutError's traceback."""
    pytest.importorskip("distributed")
    done = _models("--records", str(district), "--out", str(tmp_path / "out"),
                   "--scheduler", address)  # fmt: skip
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and lines[-1].startswith("gatetwin: error:"), done.stderr
    assert "Traceback" not in done.stderr and "cannot reach the dask scheduler" in lines[-1]
    assert not (tmp_path / "out").exists()


@pytest.mark.slow  # ~15 s: a scheduler, two workers, and the wait for workers that never come
def test_jobs_of_a_scheduler_that_lost_every_worker_fail_instead_of_waiting_forever(tmp_path):
    """Every job kills the worker that runs it (``os._exit``; no nanny restarts a worker), so
    the scheduler is soon left with jobs and no worker: after ``connect_timeout_s`` with no
    worker, each job left is failed, naming why, and the run returns (before, it waited
    forever). Run in a child process under a time limit, so a regression fails rather than
    hangs."""
    with dask_cluster(tmp_path, nanny=False) as address:
        code = (
            "import json, os\n"
            "from gatetwin.fleet.execute import FleetSettings, run_tasks\n"
            f"s = FleetSettings(scheduler={address!r}, connect_timeout_s=3.0)\n"
            "out = run_tasks(os._exit, [3, 3, 3], s, lambda job, exc: str(exc))\n"
            "print(json.dumps(out))\n"
        )
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              timeout=120)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    reasons = json.loads(done.stdout.strip().splitlines()[-1])
    assert len(reasons) == 3
    assert any("has had no worker for 3 s" in r for r in reasons), reasons


def test_dask_logs_nothing_on_stderr_while_a_fleet_runs_on_it(capfd):
    """A lost scheduler makes dask's client log its reconnection attempts on stderr, on
    loggers that carry handlers of their own; while the jobs run they are silenced (each
    lost job names its reason), and afterwards they are as they were."""
    import logging

    pytest.importorskip("distributed")
    from gatetwin.fleet.execute import _quiet_dask_logs

    client_log = logging.getLogger("distributed.client")
    # dask's logging configuration gives its loggers handlers of their own (on stderr); one
    # is added here too, so the test does not depend on when dask configured its logging
    own = logging.StreamHandler(sys.stderr)
    client_log.addHandler(own)
    handlers = {h: h.level for n in ("distributed", "distributed.client")
                for h in logging.getLogger(n).handlers}  # fmt: skip
    quiet = _quiet_dask_logs()
    client_log.error("Failed to reconnect to scheduler after 20.00 seconds, closing client")
    quiet.close()
    assert capfd.readouterr().err == ""
    assert {h: h.level for h in handlers} == handlers
    client_log.error("after the run")
    client_log.removeHandler(own)
    assert "after the run" in capfd.readouterr().err


@pytest.mark.slow  # ~30 s: three gates identified
def test_each_gate_is_written_as_it_finishes(district, tmp_path):
    """When a gate's progress line comes, its model files are already on disk: a run that
    stops early (its workers lost, the process killed) keeps the gates it finished."""
    from gatetwin.fleet import FleetSettings, run_fleet

    out = tmp_path / "out"
    seen = []

    def progress(line: str) -> None:
        if "] gate" in line:
            gate = line.split("] ", 1)[1].split()[0]
            seen.append((gate, any((out / gate).glob("*.json"))))

    run_fleet([str(district)], out, FleetSettings(workers=1), progress=progress)
    assert [g for g, _ in seen] == ["gate001", "gate002", "gate003"]
    assert all(written for _, written in seen), seen
