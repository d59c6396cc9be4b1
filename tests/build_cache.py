"""The tests' cache of compiled FMU binaries: many tests export the same model with the same
options, and each export compiled it again (in the default run, 124 compiles took 243 s of
about 1,000 s of test time; ``models/fopdt_3F.json``'s binary was built 17 times).

:func:`cached` wraps :func:`gatetwin.fmu.c_build.compile_shared` for the session
(``conftest.py``). A build is keyed by everything that decides what the binary computes:
the compiler's command and ``--version`` text, the flags, the files compiled and every file
of the sources folder (the headers they include) byte for byte, and the binary's name. A
key seen before gets the binary compiled then, copied; any difference compiles again. So a
test of a missing or failing compiler still meets it, and a changed template is rebuilt.
Entries live in the user's cache folder (``$XDG_CACHE_HOME`` or ``~/.cache``,
``gatetwin-test-builds``, mode 0700; a folder another user could write is not used),
shared by the xdist workers and by later sessions (CI's slow and default runs), each key
behind a file lock so that two workers do not build it twice. Entries are removed two days
after they were built, so a changed linker or C library is picked up by then. Without
``fcntl`` (Windows) nothing is cached.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
import stat
import subprocess
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from functools import cache
from pathlib import Path
from typing import Any

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

#: Where the binaries are kept (one folder per user).
FOLDER = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "gatetwin-test-builds"
#: Entries are removed this long after they were built, s.
MAX_AGE_S = 2 * 86400.0


def available() -> bool:
    """Whether binaries are cached here: ``fcntl``, and a cache folder only this user can
    write (created so)."""
    if fcntl is None:
        return False
    try:
        FOLDER.mkdir(mode=0o700, parents=True, exist_ok=True)
        info = FOLDER.stat()
    except OSError:
        return False
    return info.st_uid == os.getuid() and not info.st_mode & (stat.S_IWGRP | stat.S_IWOTH)


def prune(now: float | None = None) -> None:
    """Remove the entries built more than :data:`MAX_AGE_S` ago that no one holds (their
    lock files stay: removing one would let two builds of a key run at once)."""
    now = time.time() if now is None else now
    for entry in FOLDER.glob("*.bin"):
        with contextlib.suppress(OSError), open(entry.with_suffix(".lock"), "a+b") as lock:
            try:
                fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                continue  # in use
            if now - entry.stat().st_mtime > MAX_AGE_S:
                entry.unlink()


@cache
def _compiler_version(command: tuple[str, ...]) -> str:
    try:
        # in a folder of its own: Zig's `cc --version` compiles an empty a.c there, leaving a.o
        with tempfile.TemporaryDirectory() as folder:
            done = subprocess.run([*command, "--version"], capture_output=True, text=True,
                                  timeout=60, check=False, cwd=folder)  # fmt: skip
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


def _copy(source: Path, target: Path) -> None:
    """``source`` to ``target`` (mode included) through a new file renamed into place."""
    part = target.with_name(f".{target.name}.{os.getpid()}.{threading.get_ident()}.part")
    shutil.copy2(source, part)
    os.replace(part, target)


def cached(c_build: Any) -> Callable[..., None]:
    """``c_build.compile_shared`` (same signature) serving a build seen before from the
    cache; the flags and the compiler are ``c_build``'s at each call."""
    compile_shared = c_build.compile_shared

    def compile_cached(sources_dir: Path, c_files: tuple[str, ...], out: Path,
                       extra_flags: tuple[str, ...] = (),
                       compiler: list[str] | None = None) -> None:  # fmt: skip
        command = compiler or c_build.find_compiler()
        key = build_key(command, (*c_build.CFLAGS, *extra_flags), sources_dir, c_files, out)
        with _locked(key) as entry:
            try:
                _copy(entry, Path(out))
                return
            except FileNotFoundError:
                pass
            compile_shared(sources_dir, c_files, out, extra_flags, command)
            _copy(Path(out), entry)

    return compile_cached
