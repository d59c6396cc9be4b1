"""What the reader agrees to open: regular files within size and line-length limits.

A record comes from a user, so the reader opens it without trusting it: only a regular
file is read (never a FIFO, socket, device such as ``/dev/zero`` reached through a
symlink, or directory), and only up to :class:`ReadLimits`. The defaults hold about ten
million samples of a nine-column record; a longer history raises them with keyword
arguments, the ``gatetwin check`` options ``--max-bytes``/``--max-line-bytes`` or the
environment variables ``GATETWIN_MAX_BYTES``/``GATETWIN_MAX_LINE_BYTES``.

This module opens files; it does not parse them.
"""

from __future__ import annotations

import os
import stat
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from gatetwin.errors import GatetwinError, RecordError

__all__ = [
    "DEFAULT_MAX_BYTES",
    "DEFAULT_MAX_LINE_BYTES",
    "ENV_MAX_BYTES",
    "ENV_MAX_LINE_BYTES",
    "MAX_SIDECAR_BYTES",
    "ReadLimits",
    "check_archive",
    "check_unpacked_size",
    "open_regular",
    "resolve_limits",
    "unsafe_member",
]

#: Default largest record file, bytes (512 MiB: about 10 million rows of 9 columns).
DEFAULT_MAX_BYTES = 512 * 1024 * 1024
#: Default longest CSV line, bytes (64 KiB: some thousand columns).
DEFAULT_MAX_LINE_BYTES = 64 * 1024
#: Largest sidecar, bytes (a sidecar is a handful of fields).
MAX_SIDECAR_BYTES = 1024 * 1024
#: Environment variables overriding the defaults.
ENV_MAX_BYTES = "GATETWIN_MAX_BYTES"
ENV_MAX_LINE_BYTES = "GATETWIN_MAX_LINE_BYTES"


@dataclass(frozen=True)
class ReadLimits:
    """Size limits a record must respect to be read.

    Attributes
    ----------
    max_bytes : int
        Largest file, bytes (for Parquet also its uncompressed size).
    max_line_bytes : int
        Longest CSV line, bytes (header included).
    """

    max_bytes: int = DEFAULT_MAX_BYTES
    max_line_bytes: int = DEFAULT_MAX_LINE_BYTES

    def __post_init__(self) -> None:
        for name in ("max_bytes", "max_line_bytes"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
                raise RecordError(
                    f"read limit '{name}': {value!r}; expected a positive whole number of bytes"
                )

    @classmethod
    def from_env(cls, environ: dict[str, str] | None = None) -> ReadLimits:
        """The defaults, overridden by ``GATETWIN_MAX_BYTES``/``GATETWIN_MAX_LINE_BYTES``."""
        env = os.environ if environ is None else environ
        return cls(
            max_bytes=_env_bytes(env, ENV_MAX_BYTES, DEFAULT_MAX_BYTES),
            max_line_bytes=_env_bytes(env, ENV_MAX_LINE_BYTES, DEFAULT_MAX_LINE_BYTES),
        )


def _env_bytes(env: os._Environ[str] | dict[str, str], name: str, default: int) -> int:
    text = env.get(name, "").strip()
    if not text:
        return default
    if not (text.isascii() and text.isdigit()) or int(text) <= 0:
        raise RecordError(
            f"environment variable {name}: {text[:60]!r}; expected a positive whole number of bytes"
        )
    return int(text)


def resolve_limits(limits: ReadLimits | None) -> ReadLimits:
    """``limits`` as given, else the defaults with the environment's overrides."""
    return ReadLimits.from_env() if limits is None else limits


def check_unpacked_size(archive: zipfile.ZipFile, where: str,
                        error: type[GatetwinError] = RecordError,
                        max_bytes: int = DEFAULT_MAX_BYTES) -> None:  # fmt: skip
    """Refuse a zip archive (an FMU, an SSP package) whose members unpack to more than
    ``max_bytes`` in all: a zip bomb would fill the disk before anything reads it. Python's
    zipfile stops every member at its declared size, so the declared sizes bound what
    unpacking writes."""
    total = sum(info.file_size for info in archive.infolist())
    if total > max_bytes:
        raise error(f"{where}: its members unpack to {total} bytes, more than the limit of "
                    f"{max_bytes} bytes")  # fmt: skip


def unsafe_member(name: str) -> str:
    """Why an archive member name could land outside the folder it is extracted to ("" when
    it cannot): an absolute path, a drive letter, a ``..`` part, a NUL byte."""
    parts = name.replace("\\", "/").split("/")
    if name.startswith(("/", "\\")) or (len(name) > 1 and name[1] == ":"):
        return "is an absolute path"
    if ".." in parts:
        return "climbs out of the FMU's folder ('..')"
    if "\0" in name:
        return "holds a NUL byte"
    return ""


def check_archive(archive: zipfile.ZipFile, where: str,
                  error: type[GatetwinError] = RecordError) -> list[str]:  # fmt: skip
    """The member names of an FMU's zip archive, refused when it would unpack to more than
    :data:`DEFAULT_MAX_BYTES` (:func:`check_unpacked_size`) or a member would land outside
    the folder it is unpacked into (:func:`unsafe_member`)."""
    check_unpacked_size(archive, where, error)
    names = archive.namelist()
    for name in names:
        why = unsafe_member(name)
        if why:
            shown = name[:60].encode("unicode_escape", "backslashreplace").decode("ascii")
            raise error(f"{where}: refused: the archive member '{shown}' {why}; "
                        "an FMU's files stay inside its folder")  # fmt: skip
    return names


def open_regular(path: str | Path, max_bytes: int, what: str = "a CSV record",
                 error: type[GatetwinError] = RecordError) -> BinaryIO:  # fmt: skip
    """Open ``path`` for binary reading if it is a regular file of at most ``max_bytes``.

    The file is opened without blocking (a FIFO without a writer would otherwise hang)
    and checked through its open descriptor, so a symlink swapped after the check cannot
    lead elsewhere. Every file gatetwin reads from a user (records, sidecars, model files,
    FMUs, SSP packages, SWMM models) is opened here.

    Raises
    ------
    RecordError
        (or ``error``) One line naming the file, for a missing file, a directory, anything
        that is not a regular file, an unreadable file or one larger than ``max_bytes``.
    """
    name = str(path)
    try:
        fd = os.open(name, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise error(f"{name}: no such file; expected {what}") from None
    except OSError as exc:
        raise error(f"{name}: cannot be read ({exc.strerror or exc})") from None
    try:
        info = os.fstat(fd)
        _check_kind(name, info.st_mode, what, error)
        if info.st_size > max_bytes:
            raise error(
                f"{name}: {info.st_size} bytes, more than the limit of {max_bytes} bytes; "
                f"raise it with --max-bytes or {ENV_MAX_BYTES} for a longer history"
            )
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def _check_kind(name: str, mode: int, what: str, error: type[GatetwinError]) -> None:
    if stat.S_ISDIR(mode):
        raise error(f"{name}: is a directory; expected {what}")
    if not stat.S_ISREG(mode):
        raise error(f"{name}: is a {_kind_word(mode)}, not a regular file; expected {what}")


def _kind_word(mode: int) -> str:
    for test, word in ((stat.S_ISFIFO, "FIFO (named pipe)"), (stat.S_ISCHR, "character device"),
                       (stat.S_ISBLK, "block device"), (stat.S_ISSOCK, "socket")):  # fmt: skip
        if test(mode):
            return word
    return "special file"
