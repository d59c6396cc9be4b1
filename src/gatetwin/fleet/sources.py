"""Which records belong to which gate: folders of gate folders, globs, manifests, sidecars.

A *source* is a folder, a glob pattern, a record file (CSV or Parquet), or a manifest (a
text file listing one source per line, relative to the manifest's folder; blank lines and
``#`` comments are skipped). A *record* is a CSV or Parquet file (``.csv``, ``.parquet``,
``.pq``), or a history folder: a folder of day files next to its own sidecar
``FOLDER.json`` that says ``test: "routine"`` (one routine history, read a file at a time,
as ``gatetwin routine FOLDER`` reads it). A folder with records directly inside
contributes those records; a folder without any contributes each of its sub-folders that
has records. Each record belongs to the gate its sidecar's ``gate`` field names, else to
the gate named like its folder.

Only names are read here (and the sidecars' ``gate``); the records themselves are read and
checked by the gate's own task, so that one corrupt record fails its gate and nothing else.
"""

from __future__ import annotations

import glob
import json
import re
from dataclasses import dataclass
from pathlib import Path

from gatetwin.errors import GatetwinError
from gatetwin.fleet.summary import summary_paths
from gatetwin.records.chunks import HISTORY_SUFFIXES

__all__ = [
    "GateRecords",
    "discover_gates",
    "is_history_folder",
    "is_one_records_folder",
    "sidecar_gate",
]

_GLOB_CHARS = frozenset("*?[")
#: A gate name becomes a folder name in the output: letters, digits, ``._-``, no leading dot.
_GATE_NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]*")
#: Names a gate's folder cannot take: the fleet's summary files beside the gate folders
#: (compared case-blind: some file systems are).
_RESERVED = frozenset(p.name.casefold() for p in summary_paths(Path(".")).values())


@dataclass(frozen=True)
class GateRecords:
    """One gate's records: files and history folders (absolute paths, sorted by name)."""

    gate: str
    paths: tuple[str, ...]


def sidecar_gate(csv_path: Path) -> str | None:
    """The ``gate`` field of a record's sidecar; ``None`` without a readable one."""
    side = csv_path.with_suffix(".json")
    try:
        data = json.loads(side.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    gate = data.get("gate") if isinstance(data, dict) else None
    return str(gate) if gate not in (None, "") else None


def _csvs(folder: Path) -> list[Path]:
    return sorted(p for p in folder.glob("*.csv") if p.is_file())


def is_history_folder(path: Path) -> bool:
    """Whether ``path`` is a folder of day files whose own sidecar (``FOLDER.json`` next to
    it) says ``test: "routine"``."""
    if not path.is_dir() or not path.name:
        return False
    try:
        data = json.loads(path.with_suffix(".json").read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return False
    return isinstance(data, dict) and data.get("test") == "routine"


def _records(folder: Path) -> list[Path]:
    """The records directly inside ``folder``: record files and history folders."""
    return sorted(p for p in folder.iterdir()
                  if (p.is_file() and p.suffix.lower() in HISTORY_SUFFIXES)
                  or is_history_folder(p))  # fmt: skip


def _expand_folder(folder: Path) -> list[Path]:
    if is_history_folder(folder):
        return [folder]
    direct = _records(folder)
    if direct:
        return direct
    return [p for sub in sorted(folder.iterdir()) if sub.is_dir() for p in _records(sub)]


def _manifest_entries(manifest: Path) -> list[str]:
    try:
        text = manifest.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise GatetwinError(f"{manifest}: cannot read the manifest ({exc})") from None
    entries = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            path = Path(line)
            entries.append(str(path if path.is_absolute() else manifest.parent / path))
    if not entries:
        raise GatetwinError(f"{manifest}: the manifest lists no records")
    return entries


def _expand(source: str, depth: int = 0) -> list[Path]:
    if _GLOB_CHARS & set(source):
        matches = sorted(glob.glob(source))
        if not matches:
            raise GatetwinError(f"{source}: the pattern matches no file or folder")
        return [p for m in matches for p in _expand(m, depth)]
    path = Path(source)
    if path.is_dir():
        return _expand_folder(path)
    if path.is_file() and path.suffix.lower() in HISTORY_SUFFIXES:
        return [path]
    if path.is_file():
        if depth > 0:
            raise GatetwinError(f"{path}: a manifest may list folders, record files or "
                                "patterns, not another manifest")  # fmt: skip
        return [p for e in _manifest_entries(path) for p in _expand(e, depth + 1)]
    raise GatetwinError(f"{source}: no such file or folder")


def discover_gates(sources: list[str]) -> list[GateRecords]:
    """The gates of ``sources`` with their records (files and history folders), sorted by
    gate name.

    Raises
    ------
    GatetwinError
        A source that does not exist, a pattern or manifest that names nothing, no record
        at all, or two different folders giving the same gate name without ``gate`` fields.
    """
    files: dict[Path, None] = {}
    for source in sources:
        for path in _expand(source):
            files[path.resolve()] = None
    if not files:
        raise GatetwinError(f"{' '.join(sources)}: no records (CSV, Parquet or history "
                            "folders) found")  # fmt: skip
    gates: dict[str, list[Path]] = {}
    folders: dict[str, Path] = {}
    for path in files:
        named = sidecar_gate(path)
        gate = named or path.parent.name
        if named is None:
            seen = folders.setdefault(gate, path.parent)
            if seen != path.parent:
                raise GatetwinError(
                    f"gate {gate!r}: records in two folders ({seen} and {path.parent}) and no "
                    "'gate' field in their sidecars to tell the gates apart"
                )
        if not _GATE_NAME.fullmatch(gate):
            raise GatetwinError(f"{path}: gate name {gate!r} is not usable as a folder name "
                                "(letters, digits, '.', '_', '-')")  # fmt: skip
        if gate.casefold() in _RESERVED:
            names = ", ".join(sorted(_RESERVED))
            raise GatetwinError(f"{path}: gate name {gate!r} is the name of a fleet summary "
                                f"file ({names}); rename the gate")  # fmt: skip
        gates.setdefault(gate, []).append(path)
    return [GateRecords(g, tuple(str(p) for p in sorted(ps, key=lambda p: (p.name, str(p)))))
            for g, ps in sorted(gates.items())]  # fmt: skip


def is_one_records_folder(sources: list[str]) -> bool:
    """Whether ``sources`` is one plain records folder: CSV files directly inside and no
    sidecar naming a gate (the single-gate layout of ``gatetwin models``)."""
    if len(sources) != 1 or _GLOB_CHARS & set(sources[0]):
        return False
    folder = Path(sources[0])
    if not folder.is_dir():
        return False
    direct = _csvs(folder)
    return bool(direct) and all(sidecar_gate(p) is None for p in direct)
