"""The output folder of ``gatetwin run``: whose it is, replacing it, and stale work folders.

Ownership rule: ``gatetwin run --out DIR`` replaces ``DIR`` only when it is the run's own,
i.e. it carries the marker file :data:`MARKER` that every run writes (or is empty). This is
checked when the run starts and again at the moment the folder is replaced: if ``DIR`` was
created, replaced by another folder or lost its marker while the run went, the run leaves
it alone, keeps its own result in a named sibling ``DIR.gatetwin-run-XXXXXXXX`` and says so
in its error line.

A run writes into a hidden sibling ``.DIR.XXXXXXXX.tmp`` holding :data:`RUN_PID_FILE`
(process id and host). A run that was killed leaves that folder behind; the next run on
the same ``DIR`` removes it when its process is gone, and reports it when it cannot tell
(another host, a process with that id alive, a folder it cannot remove).
"""

from __future__ import annotations

import os
import shutil
import socket
import tempfile
from collections.abc import Callable
from pathlib import Path

from gatetwin._io import write_text_atomic
from gatetwin.errors import PipelineError

__all__ = [
    "MARKER",
    "RUN_PID_FILE",
    "Identity",
    "check_replaceable",
    "clean_stale_work",
    "keep_aside",
    "make_work_dir",
    "make_world_readable",
    "replace_output",
]

#: File marking a directory as written by ``gatetwin run`` (only such are replaced).
MARKER = ".gatetwin-run"
#: File in a run's temporary folder: the running process's id and host.
RUN_PID_FILE = ".gatetwin-run.pid"

Identity = tuple[int, int]


def check_replaceable(target: Path) -> Identity | None:
    """Refuse a target that is not the run's own; its identity when it exists."""
    if not (target.exists() or target.is_symlink()):
        return None
    if not target.is_dir() or target.is_symlink():
        raise PipelineError(f"{target}: exists and is not a directory; expected an output dir")
    if not _is_ours(target):
        raise PipelineError(
            f"{target}: exists and was not written by 'gatetwin run'; refusing to replace it "
            "(remove it or choose another --out)"
        )
    return _identity(target)


def _is_ours(folder: Path) -> bool:
    """Written by ``gatetwin run`` (carries the marker) or empty."""
    try:
        return (folder / MARKER).is_file() or not any(folder.iterdir())
    except OSError:
        return False


def _identity(path: Path) -> Identity | None:
    try:
        st = path.lstat()
    except OSError:
        return None
    return (st.st_dev, st.st_ino)


def make_work_dir(target: Path) -> Path:
    """The hidden temporary sibling the stages write into, holding this process's id (written
    atomically: a pid file that does not parse is never a live run's). When it cannot be
    made whole (disk full), nothing of it is left."""
    work = None
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        work = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp",
                                     dir=target.parent))  # fmt: skip
        write_text_atomic(work / RUN_PID_FILE, f"{os.getpid()}\n{socket.gethostname()}\n")
    except OSError as exc:
        if work is not None:
            shutil.rmtree(work, ignore_errors=True)
        raise PipelineError(
            f"{target.parent}: cannot write the output of 'gatetwin run' there "
            f"({exc.strerror or exc}); choose another --out"
        ) from None
    return work


def make_world_readable(path: Path) -> None:
    """mkdtemp makes a private directory; give it the usual permissions."""
    umask = os.umask(0)
    os.umask(umask)
    path.chmod(0o777 & ~umask)


# --------------------------------------------------------------------------- replacing


def _changed_hands(target: Path, owner: Identity | None) -> str:
    """Why ``target`` is no longer the folder checked at the start ("" when it is)."""
    exists = target.exists() or target.is_symlink()
    if owner is None:
        return "was created while the run went" if exists else ""
    if not exists:
        return ""  # removed meanwhile: nothing of anyone's is in the way
    if _identity(target) != owner:
        return "was replaced by another folder while the run went"
    if not _is_ours(target):
        return "lost its 'gatetwin run' marker while the run went (no longer the run's own)"
    return ""


def keep_aside(work: Path, target: Path, why: str) -> None:
    """Move this run's output to a named sibling of ``target`` and refuse, saying where."""
    try:
        kept = Path(tempfile.mkdtemp(prefix=f"{target.name}.gatetwin-run-", dir=target.parent))
        kept.rmdir()
        work.rename(kept)
    except OSError as exc:
        raise PipelineError(f"{target}: {why}; this run's output could not be kept either "
                            f"({exc.strerror or exc})") from None  # fmt: skip
    raise PipelineError(f"{target}: {why}; left it alone, this run's output is in {kept}")


def replace_output(work: Path, target: Path, owner: Identity | None) -> None:
    """Put ``work`` at ``target`` if ``target`` is still what :func:`check_replaceable` saw.

    ``owner`` is that function's answer. Otherwise (and when the folder cannot be
    replaced) the output is kept aside by :func:`keep_aside`, which raises
    :class:`~gatetwin.errors.PipelineError`.
    """
    why = _changed_hands(target, owner)
    if why:
        keep_aside(work, target, why)
    if not (target.exists() or target.is_symlink()):
        try:
            work.rename(target)  # a non-empty folder created this instant makes this fail
        except OSError:
            keep_aside(work, target, "was created while the run went")
        return
    old = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".old", dir=target.parent))
    old.rmdir()
    try:
        target.rename(old)
    except OSError as exc:
        keep_aside(work, target, f"cannot be replaced ({exc.strerror or exc})")
    if _identity(old) != owner:  # swapped between the check and the rename: put it back
        _rename_quietly(old, target)
        keep_aside(work, target, "was replaced by another folder while the run went")
    try:
        work.rename(target)
    except OSError as exc:
        _rename_quietly(old, target)
        keep_aside(work, target, f"cannot be replaced ({exc.strerror or exc})")
    shutil.rmtree(old, ignore_errors=True)


def _rename_quietly(source: Path, target: Path) -> None:
    try:
        source.rename(target)
    except OSError:
        pass


# --------------------------------------------------------------------------- stale folders


def _process_gone(pid_file: Path) -> bool | None:
    """True when the run that wrote ``pid_file`` is over, None when that cannot be told.

    A pid file that is there but does not parse (empty: a disk that filled as it was
    written) is over: a run writes its pid file whole or not at all."""
    try:
        pid_text, host = (pid_file.read_text(encoding="utf-8").split("\n") + [""])[:2]
    except (OSError, UnicodeDecodeError):
        return None
    try:
        pid = int(pid_text)
    except ValueError:
        return True
    if host != socket.gethostname() or pid == os.getpid():
        return None
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:
        return False
    return False


def clean_stale_work(target: Path, say: Callable[[str], None]) -> list[Path]:
    """Remove the temporary folders killed runs on ``target`` left; report the others.

    Only folders named like a run's (``.DIR.*.tmp``, ``.DIR.*.old``) and carrying a run's
    file (:data:`RUN_PID_FILE`, or :data:`MARKER` for a replaced output) are considered.
    Returns the folders removed.
    """
    removed = []
    for folder in sorted(target.parent.glob(f".{target.name}.*.tmp")):
        gone = _process_gone(folder / RUN_PID_FILE) if folder.is_dir() else None
        if gone is None and not (folder / RUN_PID_FILE).is_file():
            continue
        if gone:
            removed += _remove(folder, "temporary folder of a run that was stopped", say)
        else:
            say(f"      note: {folder} belongs to a run that may still be going; left alone")
    for folder in sorted(target.parent.glob(f".{target.name}.*.old")):
        if not (folder / MARKER).is_file():
            continue
        if (target / MARKER).is_file():
            removed += _remove(folder, "earlier output a stopped run was replacing", say)
        else:
            say(f"      note: {folder} holds the output a stopped run was replacing and "
                f"{target} is not a run's output; left alone")  # fmt: skip
    return removed


def _remove(folder: Path, what: str, say: Callable[[str], None]) -> list[Path]:
    shutil.rmtree(folder, ignore_errors=True)
    if folder.exists():
        say(f"      note: could not remove {folder} ({what})")
        return []
    say(f"      removed {folder} ({what})")
    return [folder]
