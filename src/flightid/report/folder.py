"""Result folders: checked before the work, locked while in use, written all at once, and
replaced only when flightid wrote everything in them.

A run's files (results.json, estimates.csv, figures/, report.html) never appear half
written, never mix with another run's, and never take the user's files with them:

1. ``ResultFolder.open(path)`` — before any estimation — checks the place. Refused: an empty
   name, the current folder, the home folder, the file system root, any folder holding one
   of these, and any folder that is or holds one of the run's own inputs (``keep``: the case
   file, its data, its model module). The parent folder must exist (missing parents are
   made) and be writable, the target must not be a file, the disk must not be full. A folder
   that already holds a run (a ``.flightid-run`` manifest, or results.json / report.html /
   estimates.csv of an older run) is only used with ``overwrite=True``, and only when every
   entry in it is one the run's manifest lists, unchanged (same size and SHA-256): a file
   added or edited by the user makes it refuse, naming each such entry; a run without a
   manifest (an older flightid) is refused too, since its files cannot be told from the
   user's. It then takes a lock, the file ``.NAME.flightid-lock`` beside the target, created
   without following symbolic links and held with ``fcntl.flock`` (released by the system
   if the process dies); a second writer gets ``OutputError("another flightid run is
   writing to DIR")``.
2. ``folder.write(writer)`` calls ``writer(tmp)`` on a fresh temporary folder
   ``.NAME.flightid-tmp-*`` beside the target (same file system, permissions from the
   umask), writes the manifest ``.flightid-run`` (every file the run wrote with its size and
   SHA-256) and moves the folder into place with one ``rename``: a missing or empty target is
   replaced atomically; with ``overwrite`` an old run is set aside, checked against its
   manifest once more, the new one renamed in and the old one deleted — the whole folder is
   replaced, no stale figure stays; an existing folder without a run (other files of the
   user) gets the run's entries moved in one by one, the manifest last. SIGINT / SIGTERM are
   held back during these renames. On an interrupt or an error the temporary folder is
   removed; a failure to write raises ``OutputError`` saying the estimate was not saved and
   whether temporary files remain.
3. ``folder.release()`` (or leaving the ``with`` block) drops the lock.

The next run that takes the lock after a killed one (``kill -9``) removes its temporary
folders; an old run it had set aside is moved back into place when the target is missing or
empty, and otherwise kept and named (``notify``, else ``folder.notices``) — never deleted.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import hashlib
import json
import os
import secrets
import shutil
import signal
import stat
import threading
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any, TypeVar

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
    "not_written_by_flightid",
    "write_manifest",
]

T = TypeVar("T")

# the manifest of a run: every file it wrote, with size and SHA-256 (JSON)
RUN_MARKER = ".flightid-run"
MANIFEST_VERSION = 1
# files that mark a folder written by an older flightid (before the marker existed)
RUN_FILES = ("results.json", "report.html", "estimates.csv")
# a disk with less free space than this is refused before estimating, bytes
MIN_FREE_BYTES = 1 << 20
# entries named in one message at most (the rest are counted)
NAMED_AT_MOST = 10
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)


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


# ---------------------------------------------------------------------------------- manifest


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _manifest(directory: Path) -> dict[str, Any]:
    """Every file (size in bytes, SHA-256) and folder under ``directory``, by relative path."""
    files: dict[str, dict[str, Any]] = {}
    folders: list[str] = []
    for root, dirs, names in os.walk(directory):
        dirs.sort()
        here = Path(root)
        for name in dirs:
            relative = (here / name).relative_to(directory).as_posix()
            if (here / name).is_symlink():
                # a writer's bug: reported as an internal error, the estimate not saved
                raise RuntimeError(f"the run wrote a symbolic link {relative}; expected files")
            folders.append(relative)
        for name in sorted(names):
            path = here / name
            relative = path.relative_to(directory).as_posix()
            if relative == RUN_MARKER:
                continue
            if path.is_symlink() or not path.is_file():
                raise RuntimeError(f"the run wrote {relative}, which is not a regular file")
            files[relative] = {"bytes": path.stat().st_size, "sha256": _sha256(path)}
    return {"files": files, "folders": folders}


def write_manifest(directory: Path) -> None:
    """Write ``directory/.flightid-run``: the flightid version, the time, and every file in
    ``directory`` with its size and SHA-256 — what ``--overwrite`` may later delete."""
    document = {
        "flightid": _version(),
        "manifest_version": MANIFEST_VERSION,
        "written": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        **_manifest(directory),
    }
    (directory / RUN_MARKER).write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")


def _read_manifest(directory: Path) -> dict[str, Any] | None:
    """The manifest in ``directory`` (None: missing, unreadable or not a manifest)."""
    try:
        document = json.loads((directory / RUN_MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(document, dict) or document.get("manifest_version") != MANIFEST_VERSION:
        return None
    files, folders = document.get("files"), document.get("folders")
    if not isinstance(files, dict) or not isinstance(folders, list):
        return None
    if not all(isinstance(v, dict) for v in files.values()):
        return None
    return document


def _changed(path: Path, recorded: dict[str, Any]) -> bool:
    """True unless ``path`` has the size and SHA-256 the manifest recorded."""
    try:
        if path.stat().st_size != recorded.get("bytes"):
            return True
        return _sha256(path) != recorded.get("sha256")
    except OSError:
        return True


def not_written_by_flightid(directory: Path) -> list[str]:
    """The entries of ``directory`` that its run's manifest does not vouch for, each with why:
    ``"notes.txt (not written by flightid)"``, ``"results.json (changed since flightid wrote
    it)"``, ``"drafts/ (not written by flightid)"``. Empty: replacing ``directory`` deletes
    only files flightid wrote. Without a readable manifest every entry is named."""
    manifest = _read_manifest(directory)
    if manifest is None:
        return [
            f"{name}{'/' if (directory / name).is_dir() else ''} (no manifest)"
            for name in _entries(directory)
            if name != RUN_MARKER
        ]
    files, folders = manifest["files"], set(manifest["folders"])
    found: list[str] = []

    def visit(folder: Path, prefix: str) -> None:
        for entry in sorted(os.scandir(folder), key=lambda e: e.name):
            relative = prefix + entry.name
            if relative == RUN_MARKER:
                continue
            if entry.is_dir(follow_symlinks=False):
                if relative in folders:
                    visit(Path(entry.path), relative + "/")
                else:
                    found.append(f"{relative}/ (not written by flightid)")
            elif entry.is_file(follow_symlinks=False) and relative in files:
                if _changed(Path(entry.path), files[relative]):
                    found.append(f"{relative} (changed since flightid wrote it)")
            else:
                found.append(f"{relative} (not written by flightid)")

    visit(directory, "")
    return found


def _named(entries: list[str]) -> str:
    shown = ", ".join(entries[:NAMED_AT_MOST])
    if len(entries) > NAMED_AT_MOST:
        shown += f" and {len(entries) - NAMED_AT_MOST} more"
    return shown


def _not_replaceable(directory: Path) -> str | None:
    """Why replacing the run folder ``directory`` would delete what flightid may not (None:
    its manifest vouches for every entry)."""
    foreign = not_written_by_flightid(directory)
    if not foreign:
        return None
    if _read_manifest(directory) is None:
        why = (
            "holds a run without a manifest of the files flightid wrote (an older "
            "flightid, or the .flightid-run file was removed or edited), so its files "
            "cannot be told from yours"
        )
    else:
        why = "holds entries that flightid did not write or that changed since"
    return (
        f"--overwrite would delete what flightid may not: {why}: {_named(foreign)}; "
        "nothing was deleted — move these out of the folder, or choose another folder"
    )


# ---------------------------------------------------------------------------------- signals


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


def _make_folder(parent: Path, prefix: str) -> Path:
    """A new folder ``parent/prefix<random>``, made with mode 0o777 so that the umask sets
    its permissions (``tempfile.mkdtemp`` would force 0o700 on the result folder)."""
    for _ in range(100):
        path = parent / f"{prefix}{secrets.token_hex(4)}"
        try:
            os.mkdir(path, 0o777)
        except FileExistsError:
            continue
        return path
    raise FileExistsError(f"no free name {prefix}* in {parent}")  # pragma: no cover


def _refused_places(keep: Iterable[str | os.PathLike]) -> list[tuple[Path, str]]:
    """(folder, what it is) that a result folder may neither be nor hold."""
    places = [(Path(p), f"{Path(p).name}, an input of this run") for p in keep]
    places.append((Path.cwd(), "the current folder"))
    with contextlib.suppress(RuntimeError, KeyError):
        places.append((Path.home(), "the home folder"))
    refused = []
    for path, what in places:
        # the path as given (a symbolic link in the case folder) and the file it points to
        with contextlib.suppress(OSError, RuntimeError):
            refused.append((Path(os.path.abspath(path.expanduser())), what))
            refused.append((path.expanduser().resolve(), what))
    return refused


class ResultFolder:
    """A checked and locked result folder (see the module docstring).

    Use ``ResultFolder.open(path, overwrite=...)`` before the work, ``write(writer)`` after it
    and ``release()`` (or a ``with`` block) at the end. What the user should know that is
    not an error (an old run restored or kept after an interrupted replace) goes to
    ``notify`` when given, else to the list ``notices``.
    """

    def __init__(
        self,
        target: Path,
        overwrite: bool,
        label: str,
        notify: Callable[[str], None] | None = None,
    ) -> None:
        self.target = target
        self.overwrite = overwrite
        self.label = label
        self.notices: list[str] = []
        self._notify = notify
        self._lock_path = target.parent / f".{target.name}.flightid-lock"
        self._lock_fd: int | None = None

    # ------------------------------------------------------------------ checks and lock

    @classmethod
    def open(
        cls,
        path: str | os.PathLike,
        *,
        overwrite: bool = False,
        label: str = "--out",
        keep: Iterable[str | os.PathLike] = (),
        notify: Callable[[str], None] | None = None,
    ) -> ResultFolder:
        """Check ``path`` as a result folder and lock it (raises ``OutputError``).

        Args:
            path: the result folder (need not exist; missing parent folders are made).
            overwrite: replace a folder that already holds a run, when flightid wrote
                everything in it.
            label: how the path is named in messages (the CLI option).
            keep: the run's inputs (case file, data files, model module): the folder may
                neither be one of them nor hold one.
            notify: called with each notice as it arises (else they are kept in
                ``notices``), also when ``open`` then refuses the folder.
        """
        text = os.fspath(path)
        if not text.strip():
            raise OutputError(f"{label}: expected a folder name, got an empty string")
        target = Path(text).expanduser().resolve()
        if target.parent == target:
            raise OutputError(f"{label} {text}: the root folder cannot be a result folder")
        folder = cls(target, overwrite, label, notify)
        folder._check_place(keep)
        folder._check()
        folder._lock()
        try:
            folder._recover_interrupted()
            folder._check()  # again, now that no other flightid run can change it
        except BaseException:
            folder.release()
            raise
        return folder

    def _note(self, text: str) -> None:
        if self._notify is not None:
            self._notify(text)
        else:
            self.notices.append(text)

    def _fail(self, problem: str) -> OutputError:
        return OutputError(f"{self.label} {self.target}: {problem}")

    def _check_place(self, keep: Iterable[str | os.PathLike]) -> None:
        """Refuse a folder that is, or holds, the current or home folder or a run input."""
        for place, what in _refused_places(keep):
            if place == self.target or place.is_relative_to(self.target):
                relation = "is" if place == self.target else "holds"
                raise self._fail(
                    f"{relation} {what} ({place}); a result folder must be a folder of its "
                    "own, apart from your files (e.g. --out results/my_run)"
                )

    def _check(self) -> None:
        target, parent = self.target, self.target.parent
        self._check_parent(parent)
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
            if marker is not None:
                self._check_replaceable(target)
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

    def _check_parent(self, parent: Path) -> None:
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

    def _check_replaceable(self, directory: Path) -> None:
        """Refuse to replace a run folder holding anything its manifest does not vouch for."""
        problem = _not_replaceable(directory)
        if problem is not None:
            raise self._fail(problem)

    def _open_lock_file(self) -> int | None:
        """The lock file's descriptor, made or opened without following a symbolic link;
        None when it vanished meanwhile (its holder released it: try again)."""
        flags = os.O_RDWR | _NOFOLLOW
        try:
            return os.open(self._lock_path, flags | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            if fcntl is None:  # pragma: no cover - Windows: an existing lock file is a lock
                raise
            # else left by a killed run, or held by a running one: the flock tells
        try:
            fd = os.open(self._lock_path, flags)
        except FileNotFoundError:
            return None
        except OSError as exc:
            if self._lock_path.is_symlink():
                raise self._fail(
                    f"the lock file {self._lock_path} is a symbolic link, which flightid never "
                    "makes; remove it (flightid does not write through it)"
                ) from None
            raise self._fail(
                f"cannot open the lock file {self._lock_path} ({exc.strerror or exc})"
            ) from None
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode) or info.st_nlink != 1:
            os.close(fd)
            raise self._fail(
                f"the lock file {self._lock_path} is not a plain file of its own (a hard link "
                "or a special file), which flightid never makes; remove it"
            )
        return fd

    def _lock(self) -> None:
        busy = self._fail(
            f"another flightid run is writing to {self.target} (lock file {self._lock_path})"
        )
        for _ in range(10):
            try:
                fd = self._open_lock_file()
            except FileExistsError:  # pragma: no cover - Windows
                raise busy from None
            if fd is None:
                continue
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
                same = os.lstat(self._lock_path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                self._lock_fd = fd
                break
            os.close(fd)
        else:  # pragma: no cover - ten lost races in a row
            raise busy
        os.ftruncate(self._lock_fd, 0)
        os.write(self._lock_fd, f"{os.getpid()}\n".encode())

    def _recover_interrupted(self) -> None:
        """After a killed run into this target (we hold the lock): remove its temporary
        folders; move an old run it had set aside back into place when the target is missing
        or empty, else keep it and name it in ``notices``."""
        parent, name = self.target.parent, self.target.name
        # names compared as text: a folder name may hold glob characters ([, *)
        beside = [parent / n for n in _entries(parent)]
        for stale in beside:
            if stale.name.startswith(f".{name}.flightid-tmp-") and not stale.is_symlink():
                if stale.is_dir():
                    shutil.rmtree(stale, ignore_errors=True)
        set_aside = sorted(
            (
                p
                for p in beside
                if p.name.startswith(f".{name}.flightid-old-") and p.is_dir() and not p.is_symlink()
            ),
            key=lambda p: p.stat().st_mtime,
        )
        for old in reversed(set_aside):
            target = self.target
            if not target.exists() or (target.is_dir() and not _entries(target)):
                os.rename(old, target)
                self._note(
                    f"the run that an interrupted --overwrite had set aside ({old.name}) was "
                    f"moved back to {target}"
                )
            else:
                self._note(
                    f"{old} holds a run that an interrupted --overwrite set aside; it is kept: "
                    "look through it and delete it yourself"
                )

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
            OutputError: the files could not be written or moved, or an old run may not be
                replaced (the message says that the estimate was not saved and whether
                temporary files remain).
            KeyboardInterrupt: passed on after the temporary folder is removed.
        """
        if self._lock_fd is None:
            raise OutputError(f"{self.label} {self.target}: the folder is not locked (released)")
        parent, name = self.target.parent, self.target.name
        try:
            tmp = _make_folder(parent, f".{name}.flightid-tmp-")
        except OSError as exc:
            raise self._not_saved(exc, None) from exc
        try:
            result = writer(tmp)
            write_manifest(tmp)
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
            self._replace(tmp)
            return
        self._merge(tmp)

    def _replace(self, tmp: Path) -> None:
        """Set the old run aside, check it against its manifest, move the new one in, delete
        the old one (we hold the lock, so the set-aside name is ours)."""
        target = self.target
        old = target.parent / f".{target.name}.flightid-old-{os.getpid()}-{secrets.token_hex(4)}"
        os.rename(target, old)
        # checked again where nobody else writes: what is deleted below is what was checked
        problem = _not_replaceable(old)
        if problem is not None:
            os.rename(old, target)
            raise self._fail(f"the estimate was not saved: {problem}")
        try:
            os.rename(tmp, target)
        except BaseException:
            os.rename(old, target)
            raise
        if not _remove(old):
            self._note(f"the replaced run could not be removed entirely: {old}")

    def _merge(self, tmp: Path) -> None:
        """A folder with other files: move our entries in, the manifest last."""
        target = self.target
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
    from flightid._version import __version__

    return __version__
