"""Atomic output writing: a command that fails leaves no partial output file."""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from gatetwin.errors import OutputError

__all__ = [
    "check_writable",
    "undone_on_failure",
    "write_bytes_atomic",
    "write_json_atomic",
    "write_text_atomic",
]


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file renamed into place.

    Raises
    ------
    OutputError
        The file cannot be written (read-only or unusable folder, disk full): one line
        naming it; nothing is left behind.
    """
    target = Path(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", dir=target.parent)
    except OSError as exc:
        raise OutputError(f"{target}: cannot write ({exc.strerror or exc})") from None
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
        os.chmod(tmp, 0o644)
        os.replace(tmp, target)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise OutputError(f"{target}: cannot write ({exc.strerror or exc})") from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target


def write_text_atomic(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` (UTF-8, newlines as given) to ``path`` atomically."""
    return write_bytes_atomic(path, text.encode("utf-8"))


def write_json_atomic(path: str | os.PathLike[str], data: Any) -> Path:
    """Write ``data`` as indented JSON (NaN refused) through a temporary file."""
    return write_text_atomic(path, json.dumps(data, indent=2, allow_nan=False) + "\n")


def check_writable(path: str | os.PathLike[str], *, folder: bool = False) -> None:
    """Refuse early an output that cannot be written: ``path`` (a file, or a folder when
    ``folder``) must be creatable in its nearest existing ancestor, which is probed with a
    temporary file (permissions alone miss read-only mounts and immutable folders).

    Raises
    ------
    OutputError
        One line naming the output and why.
    """
    target = Path(path)
    probe_dir = target if folder else target.parent
    probe_dir = Path(os.path.abspath(probe_dir))
    while not probe_dir.exists() and probe_dir != probe_dir.parent:
        probe_dir = probe_dir.parent
    if not probe_dir.is_dir():
        raise OutputError(f"{target}: cannot write ({probe_dir} is not a folder)")
    try:
        fd, tmp = tempfile.mkstemp(prefix=".gatetwin-probe.", dir=probe_dir)
    except OSError as exc:
        raise OutputError(f"{target}: cannot write ({probe_dir}: {exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(tmp)


@contextlib.contextmanager
def undone_on_failure(folder: str | os.PathLike[str], *, keep_files: bool = False
                      ) -> Iterator[Path]:  # fmt: skip
    """Write a command's outputs into ``folder``; if the block raises (disk full, a refused
    input half-way, an interrupt) and ``folder`` did not exist before, it goes with what the
    block wrote into it (with ``keep_files``, only the folders left empty), and so do the
    parents the block created. A folder that existed before is left as it is: another
    program may write into it meanwhile (``--out ~``), and nothing in it is the block's
    alone to delete."""
    root = Path(folder)
    top = Path(os.path.abspath(root))
    while not top.exists() and top != top.parent:
        top = top.parent  # the nearest folder that exists now
    created = not root.exists()
    try:
        yield root
    except BaseException:
        if created:
            _remove_tree(root, keep_files)
            made = Path(os.path.abspath(root)).parent
            while made != top and made.is_relative_to(top):
                with contextlib.suppress(OSError):
                    made.rmdir()  # only when empty
                made = made.parent
        raise


def _remove_tree(root: Path, keep_files: bool) -> None:
    """``root`` and everything in it (``keep_files``: its files stay, empty folders go)."""
    if root.is_symlink() or not root.is_dir():
        return
    for folder, names, files in os.walk(root, topdown=False):
        for name in [*([] if keep_files else files), *names]:
            with contextlib.suppress(OSError):
                path = Path(folder) / name
                path.rmdir() if name in names else path.unlink()
    with contextlib.suppress(OSError):
        root.rmdir()
