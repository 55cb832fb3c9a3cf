"""Generated model source as an importable module, kept in a file named by its content.

numba's disk cache (``flightid.model.kernel_cache``) needs the source file of every function it
caches: its cache files sit next to that file (or under ``NUMBA_CACHE_DIR``) and record its
time stamp. A module made by ``exec`` of a string has no file, so its functions, and every
kernel built on them, would be compiled again in each process. ``load_source`` therefore
writes the source to ``<folder>/flightid_generated_<h>.py``, with h the SHA-256 of the
source, and imports it from there:

* the same source gives the same file, written once (atomically: a temporary file, then
  ``os.replace``) and reused as it is afterwards, so its time stamp, and the numba cache
  entries that record it, stay valid across processes;
* another source (another table, constant or flightid version of the generator) gives
  another file and another module, never a stale one;
* the module is registered in ``sys.modules`` under its name, which is how numba finds the
  globals of a cached function again when it loads it.

The folder is ``$NUMBA_CACHE_DIR/flightid_generated`` if that is set, else
``$XDG_CACHE_HOME/flightid/generated`` (default ``~/.cache/flightid/generated``). Where no
folder is writable, or ``FLIGHTID_KERNEL_CACHE=0`` turns the disk cache off, the module is
made by ``exec`` (correct, compiled in every process).

Clean-up: each new file written prunes the folder of generated files (and their numba cache
entries beside them) neither read nor written for ``PRUNE_AFTER_DAYS`` days — a file is
never touched to mark it used, because numba's cache entries record its time stamp, so the
last read (atime) is the sign of use. A pruned source that is needed again is written again
and its kernels compiled once more: the cost of a wrong guess is one compilation, never a
wrong kernel.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
import tempfile
import types
from pathlib import Path

__all__ = ["load_source", "module_name", "prune", "source_folder"]

_PREFIX = "flightid_generated_"
# generated files neither read nor written for this long are removed (module docstring)
PRUNE_AFTER_DAYS = 30


def module_name(source: str) -> str:
    """``flightid_generated_<first 32 hex digits of SHA-256(source)>``."""
    return _PREFIX + hashlib.sha256(source.encode()).hexdigest()[:32]


def source_folder() -> Path | None:
    """The folder of the generated files (module docstring), created if needed; None if it
    cannot be written or the disk cache is off."""
    if os.environ.get("FLIGHTID_KERNEL_CACHE", "1").strip().lower() in ("0", "no", "off"):
        return None
    numba_dir = os.environ.get("NUMBA_CACHE_DIR")
    if numba_dir:
        folder = Path(numba_dir) / "flightid_generated"
    else:
        base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
        folder = Path(base) / "flightid" / "generated"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    return folder if os.access(folder, os.W_OK) else None


def _write_once(path: Path, source: str) -> bool:
    """Make ``path`` hold ``source``: keep a file already holding it, else write it
    atomically. False if it cannot be written."""
    try:
        if path.read_text(encoding="utf-8") == source:
            return True
    except (OSError, UnicodeDecodeError):
        pass
    try:
        handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=".tmp_", suffix=".py")
        try:
            with os.fdopen(handle, "w", encoding="utf-8") as stream:
                stream.write(source)
            os.replace(temporary, path)
        except BaseException:
            Path(temporary).unlink(missing_ok=True)
            raise
    except OSError:
        return False
    return True


def prune(folder: Path, days: float = PRUNE_AFTER_DAYS, keep: Path | None = None) -> int:
    """Remove the generated files in ``folder`` last read and written more than ``days``
    days ago (``keep`` excepted), with numba's cache entries for them in the folder and its
    ``__pycache__``; returns the number of sources removed. Errors (a file another process
    removed first, no permission) are skipped: pruning is best effort."""
    import time

    limit = time.time() - days * 86400.0
    removed = 0
    for path in folder.glob(f"{_PREFIX}*.py"):
        if keep is not None and path == keep:
            continue
        try:
            stat = path.stat()
            if max(stat.st_atime, stat.st_mtime) >= limit:
                continue
            path.unlink()
        except OSError:
            continue
        removed += 1
        # numba's index (.nbi) and data (.nbc) files of the module's functions
        for cache_dir in (folder, folder / "__pycache__"):
            for entry in cache_dir.glob(f"{path.stem}.*.nb[ic]"):
                entry.unlink(missing_ok=True)
    return removed


def load_source(source: str) -> types.ModuleType:
    """The module of ``source``: imported from its content-named file (module docstring),
    else made by ``exec``; one module per source and process."""
    name = module_name(source)
    module = sys.modules.get(name)
    if module is not None:
        return module
    folder = source_folder()
    path = folder / f"{name}.py" if folder is not None else None
    new_file = path is not None and not path.exists()
    if path is not None and _write_once(path, source):
        if new_file:
            prune(folder, keep=path)
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        # the source itself, for writers that copy it (flightid.export.python_module)
        module.__flightid_source__ = source
        try:
            spec.loader.exec_module(module)
            return module
        except Exception:
            del sys.modules[name]
            raise
    module = types.ModuleType(name)
    module.__flightid_source__ = source
    exec(compile(source, f"<{name}>", "exec"), module.__dict__)  # noqa: S102
    sys.modules[name] = module
    return module
