"""Many gates: one model set per gate, the same bytes serially, on a local process pool and
on a real dask.distributed cluster; a broken gate is reported, not fatal."""

from __future__ import annotations

import filecmp
import json
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

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


def test_every_gate_gets_a_model_set_and_the_summary_lists_it(serial):
    doc = json.loads((serial / "fleet.json").read_text())
    assert (doc["n_gates"], doc["n_ok"], doc["n_failed"]) == (3, 3, 0)
    for gate in ("gate001", "gate002", "gate003"):
        names = {p.name.split("_")[0] for p in (serial / gate).glob("*_*.json")}
        assert {"fopdt", "physical"} <= names, (gate, names)


def test_a_process_pool_writes_the_same_model_files(district, serial, tmp_path):
    out = tmp_path / "pool"
    done = _models("--records", str(district), "--out", str(out), "--workers", "2")
    assert done.returncode == 0, done.stderr[-2000:]
    assert _same_model_files(serial, out) == []


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_dask_scheduler_and_two_workers_write_the_same_model_files(district, serial,
                                                                     tmp_path):  # fmt: skip
    pytest.importorskip("distributed")
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    dask = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
    procs = [subprocess.Popen([*dask, "--host", "127.0.0.1", "--port", str(port),
                               "--dashboard-address", ":0"], cwd=tmp_path,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]  # fmt: skip
    try:
        time.sleep(2.0)
        worker = [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nworkers",
                  "1", "--nthreads", "1", "--no-dashboard"]  # fmt: skip
        procs += [subprocess.Popen(worker, cwd=tmp_path, stdout=subprocess.DEVNULL,
                                   stderr=subprocess.DEVNULL) for _ in range(2)]  # fmt: skip
        out = tmp_path / "dask"
        done = _models("--records", str(district), "--out", str(out), "--scheduler", address)
        assert done.returncode == 0, done.stderr[-2000:]
        assert _same_model_files(serial, out) == []
        assert "dask" in json.loads((out / "fleet.json").read_text())["mode"]
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            p.wait(timeout=30)


def test_a_broken_gate_is_reported_and_the_others_are_written(district, tmp_path):
    records = tmp_path / "records"
    shutil.copytree(district, records)
    victim = next(p for p in sorted((records / "gate002").glob("*.csv")) if "static" not in p.name)
    victim.write_text("time_s,opening_mm\nnot,a,record\n")
    out = tmp_path / "out"
    done = _models("--records", str(records), "--out", str(out), "--workers", "1")
    assert done.returncode == 1, done.stderr[-2000:]
    doc = json.loads((out / "fleet.json").read_text())
    assert (doc["n_ok"], doc["n_failed"]) == (2, 1)
    failed = [g for g in doc["gates"] if g["status"] != "ok"]
    assert [g["gate"] for g in failed] == ["gate002"] and victim.name in json.dumps(failed[0])
    assert any((out / "gate001").glob("*.json")) and not (out / "gate002").exists()
