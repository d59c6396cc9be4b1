"""Binaries of the C FMU for other platforms, cross-compiled with Zig's C compiler.

The host's binary is built by the system compiler (:func:`gatetwin.fmu.c_build.find_compiler`);
the others by ``zig cc`` from the ``ziglang`` package (``pip install 'gatetwin[cross]'``),
with the same flags (``-ffp-contract=off`` above all: every binary performs the operations the
Python reference performs). Folder names are the FMI standard's:
FMI 2.0's where it has one (``linux64``, ``win64``, ``darwin64``; it names no 64-bit ARM
folders, so those binaries go where FMI 3.0 puts them, ``aarch64-linux`` and
``aarch64-darwin``, which FMPy's platform tuples look for); FMI 3.0's platform tuples
(``x86_64-linux``, ``x86_64-windows``, ...) in an FMI 3.0 FMU.
"""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import dataclass

from gatetwin.errors import ExportError

__all__ = ["HOST", "PLATFORMS", "Platform", "platforms_of", "resolve", "zig_available", "zig_cc"]


@dataclass(frozen=True)
class Platform:
    """One binary of the FMU: its folder under ``binaries/``, Zig target and file suffix."""

    folder: str
    zig_target: str
    extension: str


#: Every platform gatetwin builds: Zig target, suffix, FMI 2.0 folder, FMI 3.0 folder.
_TARGETS = (
    ("x86_64-linux-gnu.2.17", ".so", "linux64", "x86_64-linux"),
    ("x86_64-windows-gnu", ".dll", "win64", "x86_64-windows"),
    ("x86_64-macos", ".dylib", "darwin64", "x86_64-darwin"),
    ("aarch64-linux-gnu.2.17", ".so", "aarch64-linux", "aarch64-linux"),
    ("aarch64-macos", ".dylib", "aarch64-darwin", "aarch64-darwin"),
)


def platforms_of(fmi_version: str) -> dict[str, Platform]:
    """Every platform gatetwin builds, by its folder name in ``fmi_version``'s layout."""
    column = 2 if fmi_version == "2.0" else 3
    return {t[column]: Platform(t[column], t[0], t[1]) for t in _TARGETS}


#: Every platform gatetwin builds for FMI 2.0, by folder name.
PLATFORMS = platforms_of("2.0")
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


def resolve(
    requested: str | tuple[str, ...] | list[str], host_folder: str, fmi_version: str = "2.0"
) -> tuple[str, ...]:
    """The folders to build for ``requested``: ``"host"``, ``"all"`` or folder names of
    :func:`platforms_of` ``(fmi_version)`` (comma-separated in one string, or a sequence); the
    host's own folder comes first and is built by the system compiler."""
    known_platforms = platforms_of(fmi_version)
    names = requested.split(",") if isinstance(requested, str) else list(requested)
    names = [n.strip() for n in names if n.strip()]
    if not names:
        raise ExportError("platforms: name at least one (host, all, or a folder name)")
    folders: list[str] = []
    for name in names:
        if name == HOST:
            wanted = [host_folder]
        elif name == "all":
            wanted = [host_folder, *known_platforms]
        elif name in known_platforms:
            wanted = [name]
        else:
            known = ", ".join([HOST, "all", *known_platforms])
            raise ExportError(f"platforms: unknown {name[:40]!r}; known: {known}")
        folders += [f for f in wanted if f not in folders]
    return tuple(folders)
