"""Binaries of the C FMU for other platforms, cross-compiled with Zig's C compiler.

The host's binary is built by the system compiler (:func:`gatetwin.fmu.c_build.find_compiler`);
the others by ``zig cc`` from the ``ziglang`` package (``pip install 'gatetwin[cross]'``),
with the same flags (``-ffp-contract=off`` above all: every binary performs the operations the
Python reference performs). Folder names are the FMI 2.0 standard's where it has one
(``linux64``, ``win64``, ``darwin64``); FMI 2.0 names no 64-bit ARM folders, so those
binaries go where FMI 3.0 puts them (``aarch64-linux``, ``aarch64-darwin``), which FMI 3.0
importers and FMPy's platform tuples look for.
"""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import dataclass

from gatetwin.errors import ExportError


@dataclass(frozen=True)
class Platform:
    """One binary of the FMU: its folder under ``binaries/``, Zig target and file suffix."""

    folder: str
    zig_target: str
    extension: str


#: Every platform gatetwin builds, by folder name.
PLATFORMS = {
    p.folder: p
    for p in (
        Platform("linux64", "x86_64-linux-gnu.2.17", ".so"),
        Platform("win64", "x86_64-windows-gnu", ".dll"),
        Platform("darwin64", "x86_64-macos", ".dylib"),
        Platform("aarch64-linux", "aarch64-linux-gnu.2.17", ".so"),
        Platform("aarch64-darwin", "aarch64-macos", ".dylib"),
    )
}
HOST = "host"


def zig_available() -> bool:
    """Whether the ``ziglang`` package (Zig's C compiler) is installed."""
    return importlib.util.find_spec("ziglang") is not None


def zig_cc(target: str) -> list[str]:
    """The command line of Zig's C compiler for ``target``; one-line error without it."""
    if not zig_available():
        raise ExportError(
            "cross-compiling needs Zig's C compiler: pip install 'gatetwin[cross]' (the "
            "ziglang package), or export for the host only (--platforms host)"
        )
    return [sys.executable, "-m", "ziglang", "cc", "-target", target]


def resolve(requested: str | tuple[str, ...] | list[str], host_folder: str) -> tuple[str, ...]:
    """The folders to build for ``requested``: ``"host"``, ``"all"`` or names of
    :data:`PLATFORMS` (comma-separated in one string, or a sequence); the host's own folder
    comes first and is built by the system compiler."""
    names = requested.split(",") if isinstance(requested, str) else list(requested)
    names = [n.strip() for n in names if n.strip()]
    if not names:
        raise ExportError("platforms: name at least one (host, all, or a folder name)")
    folders: list[str] = []
    for name in names:
        if name == HOST:
            wanted = [host_folder]
        elif name == "all":
            wanted = [host_folder, *PLATFORMS]
        elif name in PLATFORMS:
            wanted = [name]
        else:
            known = ", ".join([HOST, "all", *PLATFORMS])
            raise ExportError(f"platforms: unknown {name[:40]!r}; known: {known}")
        folders += [f for f in wanted if f not in folders]
    return tuple(folders)
