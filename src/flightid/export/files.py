"""Writing exported files without losing the user's: never over a file flightid did not
write, never half written.

Each exported file ``NAME`` gets a record ``.NAME.flightid-export`` beside it (JSON: the
flightid version, the time, the file's size and SHA-256). An existing ``NAME`` is replaced
only with ``overwrite=True``, and only when its record vouches for it (same size and
SHA-256): a file of the user's, or an export edited since, is refused by name. Every file
is written to a temporary name in the same folder and renamed into place (atomic), its
record after it.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import os
import secrets
from collections.abc import Callable, Sequence
from pathlib import Path

from flightid.errors import InputError

__all__ = ["ExportError", "ExportOverwriteError", "export_record", "write_exports"]

RECORD_SUFFIX = ".flightid-export"


class ExportError(InputError):
    """An export that cannot be made as asked."""


class ExportOverwriteError(ExportError):
    """An export would replace a file that exists (without ``overwrite``) or that flightid
    did not write."""


def export_record(path: Path) -> Path:
    """The record beside the exported file ``path``: ``.NAME.flightid-export``."""
    return path.parent / f".{path.name}{RECORD_SUFFIX}"


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _written_by_flightid(path: Path) -> bool:
    """True when the record beside ``path`` vouches for its present bytes."""
    try:
        record = json.loads(export_record(path).read_text(encoding="utf-8"))
        return (
            isinstance(record, dict)
            and path.is_file()
            and not path.is_symlink()
            and record.get("bytes") == path.stat().st_size
            and record.get("sha256") == _sha256(path)
        )
    except (OSError, ValueError):
        return False


def check_targets(paths: Sequence[Path], overwrite: bool) -> None:
    """Refuse (``ExportOverwriteError``) when any of ``paths`` exists and may not be replaced."""
    for path in paths:
        if not path.parent.is_dir():
            raise ExportError(f"--out {path}: the folder {path.parent} does not exist")
        if not (path.exists() or path.is_symlink()):
            continue
        if not overwrite:
            raise ExportOverwriteError(
                f"--out {path}: exists; give --overwrite to replace it (only a file flightid "
                "exported is replaced), or choose another name"
            )
        if not _written_by_flightid(path):
            raise ExportOverwriteError(
                f"--out {path}: exists and flightid did not write it (or it changed since "
                f"flightid exported it: no matching record {export_record(path).name}); "
                "nothing was replaced — move it away or choose another name"
            )


def _write_atomic(path: Path, write: Callable[[Path], None]) -> None:
    tmp = path.parent / f".{path.name}.flightid-tmp-{secrets.token_hex(4)}{path.suffix}"
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_exports(
    writers: dict[Path, Callable[[Path], None]], overwrite: bool = False
) -> list[Path]:
    """Write each ``path`` with ``writers[path](tmp_path)`` (after checking all of them), each
    with its record; returns the paths written."""
    paths = [Path(p) for p in writers]
    check_targets(paths, overwrite)
    from flightid._version import __version__

    for path, write in zip(paths, writers.values(), strict=True):
        _write_atomic(path, write)
        record = {
            "flightid": __version__,
            "written": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "file": path.name,
            "bytes": path.stat().st_size,
            "sha256": _sha256(path),
        }
        text = json.dumps(record, indent=1) + "\n"
        _write_atomic(export_record(path), lambda tmp, text=text: tmp.write_text(text, "utf-8"))
    return paths
