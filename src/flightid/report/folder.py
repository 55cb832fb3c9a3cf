"""Result folders: checked before the work, locked while in use, written all at once.

A run's files (results.json, estimates.csv, figures/, report.html) never appear half
written and never mix with another run's:

1. ``ResultFolder.open(path)`` — before any estimation — checks the place: the parent folder
   exists and is writable, the target is not a file, the disk is not full, and a folder
   that already holds a run (a ``.flightid-run`` marker, or results.json / report.html /
   estimates.csv of an older run) is only used with ``overwrite=True``. It then takes a
   lock, the file ``.NAME.flightid-lock`` beside the target held with ``fcntl.flock``
   (released by the system if the process dies); a second writer gets
   ``OutputError("another flightid run is writing to DIR")``.
2. ``folder.write(writer)`` calls ``writer(tmp)`` on a fresh temporary folder
   ``.NAME.flightid-tmp-*`` beside the target (same file system), adds the run marker and
   moves the folder into place with one ``rename``: a missing or empty target is replaced
   atomically; with ``overwrite`` an old run is moved aside, the new one renamed in and the
   old one deleted — the whole folder is replaced, no stale figure stays; an existing
   folder without a run (other files of the user) gets the run's entries moved in one by
   one, the marker last. SIGINT / SIGTERM are held back during these renames. On an
   interrupt or an error the temporary folder is removed; a failure to write raises
   ``OutputError`` saying the estimate was not saved and whether temporary files remain.
3. ``folder.release()`` (or leaving the ``with`` block) drops the lock.

Temporary folders of a run that was killed (``kill -9``) are removed by the next run that
takes the lock.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import os
import shutil
import signal
import tempfile
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TypeVar

from flightid.errors import InputError

try:  # POSIX
    import fcntl
except ImportError:  # pragma: no cover - Windows: an O_EXCL lock file instead
    fcntl = None  # type: ignore[assignment]

__all__ = [
    "MIN_FREE_BYTES",
    "OutputError",
    "RUN_FILES",
    "RUN_MARKER",
    "ResultFolder",
    "holds_run",
]

T = TypeVar("T")

RUN_MARKER = ".flightid-run"
# files that mark a folder written by an older flightid (before the marker existed)
RUN_FILES = ("results.json", "report.html", "estimates.csv")
# a disk with less free space than this is refused before estimating, bytes
MIN_FREE_BYTES = 1 << 20


class OutputError(InputError):
    """The result folder cannot be used, or the results could not be written there."""


def holds_run(directory: Path) -> str | None:
    """The entry showing that ``directory`` holds a flightid run, or None."""
    for name in (RUN_MARKER, *RUN_FILES):
        if (directory / name).exists():
            return name
    return None


def _entries(directory: Path) -> list[str]:
    return sorted(os.listdir(directory))


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """Hold SIGINT / SIGTERM back while the body renames folders; one that arrived meanwhile
    is passed on afterwards (the previous handler runs: Ctrl-C raises KeyboardInterrupt).

    Python handlers, not a signal mask: a signal sent to the process may be delivered to any
    thread, and only the main thread's handler decides what happens to it."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    arrived: list[int] = []

    def hold(signum, frame) -> None:
        arrived.append(signum)

    previous = {}
    for signum in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(ValueError, OSError):
            # None: a handler not installed from Python, restored as the default
            previous[signum] = signal.signal(signum, hold) or signal.SIG_DFL
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        for signum in dict.fromkeys(arrived):
            handler = previous.get(signum)
            if callable(handler):
                handler(signum, None)
            elif handler != signal.SIG_IGN:
                signal.raise_signal(signum)


def _remove(path: Path) -> bool:
    """Remove a folder; True if it is gone."""
    shutil.rmtree(path, ignore_errors=True)
    return not path.exists()


class ResultFolder:
    """A checked and locked result folder (see the module docstring).

    Use ``ResultFolder.open(path, overwrite=...)`` before the work, ``write(writer)`` after it
    and ``release()`` (or a ``with`` block) at the end.
    """

    def __init__(self, target: Path, overwrite: bool, label: str) -> None:
        self.target = target
        self.overwrite = overwrite
        self.label = label
        self._lock_path = target.parent / f".{target.name}.flightid-lock"
        self._lock_fd: int | None = None

    # ------------------------------------------------------------------ checks and lock

    @classmethod
    def open(
        cls, path: str | os.PathLike, *, overwrite: bool = False, label: str = "--out"
    ) -> ResultFolder:
        """Check ``path`` as a result folder and lock it (raises ``OutputError``).

        Args:
            path: the result folder (need not exist; missing parent folders are made).
            overwrite: replace a folder that already holds a run.
            label: how the path is named in messages (the CLI option).
        """
        text = os.fspath(path)
        if not text.strip():
            raise OutputError(f"{label}: expected a folder name, got an empty string")
        target = Path(text).expanduser().resolve()
        if target.parent == target:
            raise OutputError(f"{label} {text}: the root folder cannot be a result folder")
        folder = cls(target, overwrite, label)
        folder._check()
        folder._lock()
        try:
            folder._check()  # again, now that no other flightid run can change it
            folder._remove_stale()
        except BaseException:
            folder.release()
            raise
        return folder

    def _fail(self, problem: str) -> OutputError:
        return OutputError(f"{self.label} {self.target}: {problem}")

    def _check(self) -> None:
        target, parent = self.target, self.target.parent
        if not parent.exists() and not parent.is_symlink():
            # missing parent folders are made (as `mkdir -p`), unless one of them is a file
            try:
                parent.mkdir(parents=True, exist_ok=True)
            except (FileExistsError, NotADirectoryError):
                raise self._fail(
                    f"the parent folder {parent} cannot be made: part of its path is a file"
                ) from None
            except OSError as exc:
                raise self._fail(
                    f"the parent folder {parent} cannot be made ({exc.strerror or exc})"
                ) from None
        if not parent.is_dir():
            raise self._fail(f"the parent folder {parent} is not a folder")
        if not os.access(parent, os.W_OK | os.X_OK):
            raise self._fail(
                f"cannot write in {parent} (permission denied); the results are written to a "
                "temporary folder there and moved into place"
            )
        if target.exists() or target.is_symlink():
            if not target.is_dir():
                raise self._fail("exists and is a file, not a folder; choose a folder")
            if not os.access(target, os.W_OK | os.X_OK):
                raise self._fail("cannot write in this folder (permission denied)")
            marker = holds_run(target)
            if marker is not None and not self.overwrite:
                raise self._fail(
                    f"already holds a flightid run ({marker}); give --overwrite to replace that "
                    "run (the whole folder), or choose another folder"
                )
            if marker is None and (target / "figures").exists():
                raise self._fail(
                    "holds an entry 'figures' that is not from a flightid run; choose another "
                    "folder"
                )
        try:
            usage = shutil.disk_usage(parent)
        except OSError:
            return
        if usage.free < MIN_FREE_BYTES:
            raise self._fail(
                f"the disk holding {parent} is full ({usage.free} bytes free; "
                f"{MIN_FREE_BYTES} needed at least)"
            )

    def _lock(self) -> None:
        busy = self._fail(
            f"another flightid run is writing to {self.target} (lock file {self._lock_path})"
        )
        for _ in range(10):
            try:
                if fcntl is None:  # pragma: no cover - Windows
                    fd = os.open(self._lock_path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
                else:
                    fd = os.open(self._lock_path, os.O_RDWR | os.O_CREAT, 0o644)
            except FileExistsError:  # pragma: no cover - Windows
                raise busy from None
            except OSError as exc:
                raise self._fail(
                    f"cannot create the lock file {self._lock_path} ({exc.strerror or exc})"
                ) from None
            if fcntl is None:  # pragma: no cover - Windows
                self._lock_fd = fd
                break
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                os.close(fd)
                raise busy from None
            # the holder before us may have removed the file after we opened it: lock the
            # file that is at the path now
            try:
                same = os.stat(self._lock_path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                self._lock_fd = fd
                break
            os.close(fd)
        else:  # pragma: no cover - ten lost races in a row
            raise busy
        os.write(fd, f"{os.getpid()}\n".encode())

    def _remove_stale(self) -> None:
        """Temporary and set-aside folders of killed runs into this target (we hold the lock)."""
        parent, name = self.target.parent, self.target.name
        for pattern in (f".{name}.flightid-tmp-*", f".{name}.flightid-old-*"):
            for stale in parent.glob(pattern):
                if stale.is_dir():
                    shutil.rmtree(stale, ignore_errors=True)

    def release(self) -> None:
        """Drop the lock (idempotent)."""
        if self._lock_fd is None:
            return
        with contextlib.suppress(OSError):
            os.unlink(self._lock_path)
        with contextlib.suppress(OSError):
            os.close(self._lock_fd)
        self._lock_fd = None

    def __enter__(self) -> ResultFolder:
        return self

    def __exit__(self, *exc_info) -> None:
        self.release()

    # ------------------------------------------------------------------ writing

    def write(self, writer: Callable[[Path], T]) -> T:
        """Run ``writer(tmp)`` on a temporary folder and move the result into place.

        Raises:
            OutputError: the files could not be written or moved (the message says that the
                estimate was not saved and whether temporary files remain).
            KeyboardInterrupt: passed on after the temporary folder is removed.
        """
        if self._lock_fd is None:
            raise OutputError(f"{self.label} {self.target}: the folder is not locked (released)")
        parent, name = self.target.parent, self.target.name
        try:
            tmp = Path(tempfile.mkdtemp(prefix=f".{name}.flightid-tmp-", dir=parent))
        except OSError as exc:
            raise self._not_saved(exc, None) from exc
        try:
            result = writer(tmp)
            marker = {
                "flightid": _version(),
                "written": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            }
            (tmp / RUN_MARKER).write_text(json.dumps(marker) + "\n", encoding="utf-8")
            with _signals_held():
                self._commit(tmp)
        except OutputError as exc:
            _remove(tmp)
            raise exc
        except Exception as exc:
            raise self._not_saved(exc, tmp) from exc
        except BaseException:  # KeyboardInterrupt, SystemExit: leave no half-written run
            _remove(tmp)
            raise
        return result

    def _not_saved(self, exc: BaseException, tmp: Path | None) -> OutputError:
        if isinstance(exc, OSError):
            reason = exc.strerror or str(exc)
            if exc.filename:
                reason = f"{reason}: {exc.filename}"
        else:
            reason = f"internal error: {type(exc).__name__}: {exc}"
        if tmp is None:
            left = "no files were written"
        elif _remove(tmp):
            left = "the partial files were removed"
        else:
            left = f"partial files remain in {tmp}"
        return self._fail(f"the estimate was not saved: writing failed ({reason}); {left}")

    def _commit(self, tmp: Path) -> None:
        target = self.target
        if not target.exists():
            os.rename(tmp, target)  # atomic
            return
        if not target.is_dir():
            raise self._fail("the estimate was not saved: the folder became a file meanwhile")
        if not _entries(target):
            os.rename(tmp, target)  # POSIX: replaces an empty folder atomically
            return
        marker = holds_run(target)
        if marker is not None:
            if not self.overwrite:
                raise self._fail(
                    f"the estimate was not saved: the folder now holds another run ({marker}); "
                    "give --overwrite to replace it"
                )
            # the old run is set aside beside the target (we hold the lock, so the name is ours)
            old = target.parent / f".{target.name}.flightid-old-{os.getpid()}"
            if old.exists():
                shutil.rmtree(old)
            os.rename(target, old)
            try:
                os.rename(tmp, target)
            except BaseException:
                os.rename(old, target)
                raise
            shutil.rmtree(old, ignore_errors=True)
            return
        # a folder with other files: move our entries in, the marker last
        names = [n for n in _entries(tmp) if n != RUN_MARKER] + [RUN_MARKER]
        clash = [n for n in names if (target / n).exists()]
        if clash:
            raise self._fail(f"the estimate was not saved: the folder now holds {clash}")
        moved: list[str] = []
        try:
            for n in names:
                os.rename(tmp / n, target / n)
                moved.append(n)
        except BaseException:
            for n in moved:
                with contextlib.suppress(OSError):
                    os.rename(target / n, tmp / n)
            raise
        _remove(tmp)


def _version() -> str:
    from flightid import __version__

    return __version__
