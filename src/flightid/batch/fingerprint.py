"""Fingerprints of a batch case: what its result depends on, for skip and resume.

    fingerprint = SHA-256 of { case text (after substitution), the case's path,
                               SHA-256 of each data file (estimation and prediction maneuvers)
                               and of the model module, flightid version and the SHA-256 of
                               its Python sources, accuracy option }

A case whose fingerprint equals the one stored with its result (``cases/<name>/batch.json``)
is not run again. A data file that cannot be found enters as ``"missing"``: the case fails
when it runs, and runs again once the file is there. A case text that cannot be read as a
case enters with its text only (its run reports the error).
"""

from __future__ import annotations

import functools
import hashlib
import json
import tomllib
from pathlib import Path

from flightid.batch.plan import BatchCase

__all__ = ["file_sha256", "fingerprint"]


def file_sha256(path: Path) -> str:
    """SHA-256 (hex) of a file's bytes, read in 1 MiB blocks; ``"missing"`` if unreadable."""
    digest = hashlib.sha256()
    try:
        with path.open("rb") as stream:
            for block in iter(lambda: stream.read(1 << 20), b""):
                digest.update(block)
    except OSError:
        return "missing"
    return digest.hexdigest()


@functools.cache
def code_digest() -> str:
    """SHA-256 of the flightid package's Python sources (the code that computes a result):
    a changed solver, model builder or report changes every fingerprint, also where the
    version string stays the same (a development checkout). Computed once per process."""
    # the flightid package folder: this module lives in flightid/batch/
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode("utf-8") + b"\0")
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _input_files(case: BatchCase, data_dir: str | Path | None) -> dict[str, str]:
    """Data files and model module of the case → SHA-256 (empty when the text is no case)."""
    from flightid.cases.build import resolve_data_dir
    from flightid.cases.spec import parse_case
    from flightid.errors import FlightIdError

    try:
        parsed = parse_case(tomllib.loads(case.text), case.path)
        directory = resolve_data_dir(parsed, data_dir)
    except (FlightIdError, tomllib.TOMLDecodeError):
        return {}
    files: dict[str, str] = {}
    for spec in (*parsed.maneuvers, *parsed.prediction):
        path = Path(spec.file)
        path = path if path.is_absolute() else directory / path
        files[str(path)] = file_sha256(path)
    module = parsed.model.get("module")
    if isinstance(module, str):
        path = Path(module).expanduser()
        path = path if path.is_absolute() else parsed.directory / path
        files[str(path.resolve())] = file_sha256(path)
    return files


def fingerprint(case: BatchCase, data_dir: str | Path | None, accuracy: str | None) -> str:
    """The case's fingerprint (hex SHA-256; see the module docstring).

    Args:
        case: the planned case.
        data_dir: the ``--data-dir`` override (None: the case's own).
        accuracy: the ``--accuracy`` option (None: the case's ``accuracy.methods``).
    """
    from flightid._version import __version__

    document = {
        "text": case.text,
        "path": str(case.path),
        "files": _input_files(case, data_dir),
        "flightid": __version__,
        "code": code_digest(),
        "accuracy": accuracy,
    }
    return hashlib.sha256(json.dumps(document, sort_keys=True).encode("utf-8")).hexdigest()
