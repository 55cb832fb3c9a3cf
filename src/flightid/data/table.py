"""The ``Table`` every reader returns, its errors, and the lazy import of optional readers.

A ``Table`` is a numeric matrix (samples × columns) with optional column names and units
(``flightid.data.loaders`` turns it into ``FlightData``). The readers of
``flightid.data.loaders``, ``flightid.data.mat_tables`` and ``flightid.data.formats`` build
it through ``_finish_table``, which checks the matrix and the names once for all of them.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from flightid.errors import InputError, describe
from flightid.results import MissingDependencyError


class DataFileError(InputError):
    """A data file that is missing, unreadable or not a numeric table."""


class ChannelError(InputError):
    """A channel specification naming an unknown column or malformed expression."""


class FileUnitError(ChannelError):
    """A channel's declared unit contradicts the unit its file states for the column, or the
    file states a unit flightid cannot read for a channel that declares none. The message
    names both units and the key that settles it (``ignore_file_unit = true``)."""


class FileTooLargeError(DataFileError):
    """A data file that would not fit in the memory available to read it."""


@dataclass(frozen=True)
class TableStream:
    """Columns of a ``Table`` sampled together, on their own time base (a flight-log
    message stream): ``rows`` (0-based row numbers where the stream has a sample) and
    ``columns`` (0-based column numbers it fills; NaN on the other rows)."""

    name: str
    rows: np.ndarray
    columns: tuple[int, ...]


@dataclass(frozen=True, eq=False)
class Table:
    """A numeric table read from a file.

    Attributes:
        data: (N, k) float matrix.
        names: column names (``""`` where the file gives none).
        units: column units as written in the file (``""`` where unknown).
        source: where it came from (path or description), for messages.
        constants: scalar values stored beside the table (e.g. ``sarea`` in SIDPAC files).
        streams: for a log whose streams have different time bases: the streams (the rows
            are the union of their time stamps; a column is NaN where its stream has no
            sample). Empty: every column is sampled at every row.
        left_out: names in the file that are not columns, with the reason (a MATLAB struct
            field of another length), for the message when a channel names one.
    """

    data: np.ndarray
    names: tuple[str, ...]
    units: tuple[str, ...]
    source: str = ""
    constants: Mapping[str, float] = field(default_factory=dict)
    streams: tuple[TableStream, ...] = ()
    left_out: Mapping[str, str] = field(default_factory=dict)

    @property
    def n_rows(self) -> int:
        return int(self.data.shape[0])

    @property
    def n_columns(self) -> int:
        return int(self.data.shape[1])

    def column_index(self, key: int | str, where: str = "column") -> int:
        """0-based index of a column given as a 1-based number or a name."""
        if isinstance(key, bool) or not isinstance(key, (int, str)):
            raise ChannelError(
                f"{where}: expected a 1-based column number or a column name, got {describe(key)}"
            )
        if isinstance(key, int):
            if not 1 <= key <= self.n_columns:
                raise ChannelError(
                    f"{where}: column {key} does not exist; {self.source or 'the table'} has "
                    f"columns 1..{self.n_columns}"
                )
            return key - 1
        exact = [i for i, n in enumerate(self.names) if n == key]
        folded = [i for i, n in enumerate(self.names) if n.lower() == key.lower()]
        matches = exact or folded
        if len(matches) == 1:
            return matches[0]
        if len(matches) > 1:
            raise ChannelError(
                f"{where}: {self.source or 'the table'} has {len(matches)} columns named "
                f"{key!r}{'' if exact else ' (case ignored)'}: columns "
                f"{[i + 1 for i in matches]} ({[self.names[i] for i in matches]}); "
                "name one by its number (column = N, or $N in an expression)"
            )
        if key in self.left_out:
            raise ChannelError(
                f"{where}: {key!r} in {self.source or 'the table'} is not a column: "
                f"{self.left_out[key]}"
            )
        known = [n for n in self.names if n]
        raise ChannelError(
            f"{where}: no column named {key!r} in {self.source or 'the table'}; "
            + (f"columns: {known}" if known else "the file has no column names (use numbers)")
        )

    def column(self, key: int | str, where: str = "column") -> np.ndarray:
        return self.data[:, self.column_index(key, where)]


def _finish_table(
    data: np.ndarray, names, units, source: str, constants=None, left_out=None
) -> Table:
    data = np.asarray(data, dtype=float)
    if data.ndim == 1:
        data = data[:, None]
    if data.ndim != 2 or data.shape[0] < 2 or data.shape[1] < 1:
        raise DataFileError(f"{source}: expected a table of at least 2 rows, got {describe(data)}")
    k = data.shape[1]
    names = tuple(str(n).strip() for n in (names or [""] * k))
    units = tuple(str(u).strip() for u in (units or [""] * k))
    if len(names) != k or len(units) != k:
        raise DataFileError(
            f"{source}: {k} data columns but {len(names)} names and {len(units)} units"
        )
    data = np.ascontiguousarray(data)
    data.flags.writeable = False
    return Table(data, names, units, source, dict(constants or {}), left_out=dict(left_out or {}))


# a header "name [unit]" or "name (unit)": group 1 the name, group 2 the unit
_CSV_UNIT = re.compile(r"(.*?)\s*[\[(]([^\])]*)[\])]\s*")


def _require(module: str, extra: str, what: str) -> Any:
    """Import ``module`` or raise ``MissingDependencyError`` naming the extra."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        package = module.split(".")[0]
        raise MissingDependencyError(
            f"reading {what} needs {package}, which is not installed; install it with "
            f"pip install 'flightid[{extra}]' (or pip install {package})"
        ) from None
