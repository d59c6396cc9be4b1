"""The tests' cache of compiled FMU binaries: many tests export the same model with the same
options, and each export compiled it again (in the default run, 124 compiles took 243 s of
about 1,000 s of test time; ``models/fopdt_3F.json``'s binary was built 17 times).

:func:`cached_compile_shared` stands in for :func:`gatetwin.fmu.c_build.compile_shared`
during the session (``conftest.py``). A build is keyed by everything that decides its output:
the compiler's command and ``--version`` text, the flags, the files compiled and every file
of the sources folder (the headers they include) byte for byte, and the binary's name. A
key seen before gets the binary compiled then, copied; any difference compiles again. So a
test of a missing or failing compiler still meets it, and a changed template is rebuilt.
Entries live in a folder of the system's temporary directory shared by the xdist workers
and by later sessions (CI's slow and default runs), each key behind a file lock so that two
workers do not build it twice; entries unused for two days are removed at the session's
start. Without ``fcntl`` (Windows) nothing is cached.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable, Iterator
from functools import cache
from pathlib import Path

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

#: Where the binaries are kept (one folder per user).
FOLDER = Path(tempfile.gettempdir()) / f"gatetwin-test-builds-{getattr(os, 'getuid', int)()}"
#: Entries not used for this long are removed at a session's start, s.
MAX_AGE_S = 2 * 86400.0


def available() -> bool:
    return fcntl is not None


def prune(now: float | None = None) -> None:
    """Remove the entries (and their locks) not used for :data:`MAX_AGE_S`."""
    now = time.time() if now is None else now
    for entry in FOLDER.glob("*.bin"):
        with contextlib.suppress(OSError):
            if now - entry.stat().st_mtime > MAX_AGE_S:
                entry.unlink()
                entry.with_suffix(".lock").unlink(missing_ok=True)


@cache
def _compiler_version(command: tuple[str, ...]) -> str:
    try:
        done = subprocess.run([*command, "--version"], capture_output=True, text=True,
                              timeout=60, check=False)  # fmt: skip
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"cannot run: {exc}"
    return done.stdout + done.stderr


def build_key(command: list[str], flags: tuple[str, ...], sources_dir: Path,
              c_files: tuple[str, ...], out: Path) -> str:  # fmt: skip
    digest = hashlib.sha256()
    for part in (*command, _compiler_version(tuple(command)), *flags, "|", *c_files, "|",
                 Path(out).name):  # fmt: skip
        digest.update(part.encode() + b"\0")
    for path in sorted(p for p in Path(sources_dir).iterdir() if p.is_file()):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


@contextlib.contextmanager
def _locked(key: str) -> Iterator[Path]:
    FOLDER.mkdir(parents=True, exist_ok=True)
    with open(FOLDER / f"{key}.lock", "a+b") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield FOLDER / f"{key}.bin"
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def cached(compile_shared: Callable[..., None], cflags: tuple[str, ...],
           find_compiler: Callable[[], list[str]]) -> Callable[..., None]:  # fmt: skip
    """``compile_shared`` (same signature) that serves a build seen before from the cache."""

    def compile_cached(sources_dir: Path, c_files: tuple[str, ...], out: Path,
                       extra_flags: tuple[str, ...] = (),
                       compiler: list[str] | None = None) -> None:  # fmt: skip
        command = compiler or find_compiler()
        key = build_key(command, (*cflags, *extra_flags), sources_dir, c_files, out)
        with _locked(key) as entry:
            if entry.is_file():
                shutil.copyfile(entry, out)
                os.utime(entry)
                return
            compile_shared(sources_dir, c_files, out, extra_flags, command)
            part = entry.with_suffix(f".{os.getpid()}.part")
            shutil.copyfile(out, part)
            os.replace(part, entry)

    return compile_cached
