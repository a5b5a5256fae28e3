"""Data file formats: CSV (header row), NumPy ``.npz`` and MATLAB ``.mat``, as named columns.

Each reader turns the bytes of one file into a `ColumnFile`: the column names in file order
and, on demand, one column as a float vector (NaN where a sample is missing). A column is
converted only when it is used, so a text column the plant does not need (a date, a comment)
does not stop the read. Every error is a `DataError` naming the file, the column and the row
(rows are numbered from 1, the first sample; a CSV error also gives the line, the header being
line 1).
"""

from __future__ import annotations

import csv
import io
import math
import zipfile
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from tanksynth.errors import DataError
from tanksynth.spec.options import short_repr

__all__ = ["ColumnFile", "FORMATS", "MAX_ROWS", "MAX_COLUMNS", "MAX_UNPACKED_BYTES",
           "parse_csv", "parse_npz", "parse_mat"]

#: Most samples (rows) read from one file.
MAX_ROWS = 1_000_000
#: Most columns (variables) in one file.
MAX_COLUMNS = 512
#: Largest total size of the arrays unpacked from a compressed ``.npz`` or ``.mat`` (bytes).
MAX_UNPACKED_BYTES = 256 * 1024 ** 2
#: What an empty cell means, said in the errors.
_MISSING = "an empty cell or NaN marks a missing sample"


@dataclass
class ColumnFile:
    """The named columns of one data file.

    Attributes
    ----------
    source : str
        The file, named in every error.
    names : tuple of str
        Column names in file order.
    load : callable
        ``load(name) -> ndarray (N,)`` float, NaN where missing; raises `DataError` for a
        column that is not numeric or not a vector.
    lines : ndarray of int or None
        File line of each row (CSV), for the errors; None for binary formats.
    """

    source: str
    names: tuple[str, ...]
    load: Callable[[str], np.ndarray]
    lines: np.ndarray | None = None
    _cache: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    def column(self, name: str) -> np.ndarray:
        """Column ``name`` as float (N,) (converted once).

        Parameters
        ----------
        name : str
            One of `names`.
        """
        if name not in self._cache:
            self._cache[name] = self.load(name)
        return self._cache[name]

    def where(self, row: int) -> str:
        """``"row R"`` (1-based) of the 0-based sample index ``row``, with the CSV line.

        Parameters
        ----------
        row : int
            0-based sample index.
        """
        line = f" (line {int(self.lines[row])})" if self.lines is not None and row < len(self.lines) else ""
        return f"row {row + 1}{line}"


def _check_names(names: Sequence[str], source: str, what: str) -> tuple[str, ...]:
    if len(names) > MAX_COLUMNS:
        raise DataError(f"{len(names)} {what}s, more than the {MAX_COLUMNS} a data file may have",
                        source=source)
    seen: set[str] = set()
    for i, nm in enumerate(names):
        if not nm:
            raise DataError(f"{what} {i + 1} has no name; every {what} needs one", source=source)
        if nm in seen:
            raise DataError(f"{what} {nm!r} appears twice; {what} names must be unique", source=source)
        seen.add(nm)
    return tuple(names)


def parse_csv(data: bytes, source: str) -> ColumnFile:
    """Columns of a CSV file: a header row of names, then one row per sample (comma-separated).

    Parameters
    ----------
    data : bytes
        The file (UTF-8, an optional byte-order mark).
    source : str
        The file name, for the errors.

    Returns
    -------
    ColumnFile

    Raises
    ------
    DataError
        Not UTF-8, no header, a row whose cell count differs from the header's, more than
        `MAX_ROWS` rows or `MAX_COLUMNS` columns; on use, a cell that is not a number.
    """
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DataError(f"not UTF-8 text (byte {exc.start}); expected a CSV file with a header row",
                        source=source) from None
    reader = csv.reader(io.StringIO(text, newline=""), strict=True)
    rows: list[list[str]] = []
    lines: list[int] = []
    header: list[str] | None = None
    try:
        for cells in reader:
            if not cells or all(not c.strip() for c in cells):
                continue  # blank line
            if header is None:
                header = [c.strip() for c in cells]
                _check_names(header, source, "column")
                if len(header) == 1 and any(sep in header[0] for sep in ";\t"):
                    raise DataError(f"the header {short_repr(header[0])} is one column: the "
                                    "separator must be ',' (comma)", source=source)
                continue
            if len(cells) != len(header):
                raise DataError(f"row {len(rows) + 1} (line {reader.line_num}) has {len(cells)} "
                                f"cells, the header has {len(header)} columns", source=source)
            if len(rows) >= MAX_ROWS:
                raise DataError(f"more than the {MAX_ROWS} rows a data file may have", source=source)
            rows.append(cells)
            lines.append(reader.line_num)
    except csv.Error as exc:
        raise DataError(f"line {reader.line_num}: malformed CSV ({exc})", source=source) from None
    if header is None:
        raise DataError("empty file; expected a header row of column names, then one row per sample",
                        source=source)
    index = {nm: j for j, nm in enumerate(header)}
    line_arr = np.asarray(lines, dtype=np.int64)

    def load(name: str) -> np.ndarray:
        j = index[name]
        cells = [r[j].strip() for r in rows]
        try:
            return np.array([c if c else "nan" for c in cells], dtype=float)
        except ValueError:
            pass
        values = np.empty(len(cells))
        for i, c in enumerate(cells):
            try:
                values[i] = float(c) if c else math.nan
            except ValueError:
                raise DataError(f"column {name!r}, row {i + 1} (line {lines[i]}): "
                                f"{short_repr(c)} is not a number ({_MISSING})",
                                source=source) from None
        return values

    return ColumnFile(source, tuple(header), load, line_arr)


def _reason(exc: BaseException) -> str:
    """A library's error message as one short line."""
    return " ".join(str(exc).split())[:120] or type(exc).__name__


def _vector(value: Any, name: str, source: str) -> np.ndarray:
    """A numeric vector (N,), (N, 1) or (1, N) as float (N,)."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "iuf":
        raise DataError(f"column {name!r} is not numeric (dtype {arr.dtype}); expected a vector of "
                        f"numbers ({_MISSING})", source=source)
    if arr.ndim == 2 and 1 in arr.shape:
        arr = arr.reshape(-1)
    if arr.ndim != 1:
        raise DataError(f"column {name!r} has shape {arr.shape}; expected a vector (one value per "
                        "sample)", source=source)
    if arr.shape[0] > MAX_ROWS:
        raise DataError(f"column {name!r} has {arr.shape[0]} rows, more than the {MAX_ROWS} a data "
                        "file may have", source=source)
    return np.array(arr, dtype=float)


def parse_npz(data: bytes, source: str) -> ColumnFile:
    """Columns of a NumPy ``.npz`` archive: one array per column name (no pickles).

    Parameters
    ----------
    data : bytes
        The archive.
    source : str
        The file name, for the errors.

    Returns
    -------
    ColumnFile

    Raises
    ------
    DataError
        Not a readable archive, more than `MAX_COLUMNS` arrays or `MAX_UNPACKED_BYTES`
        unpacked; on use, an array that is not a numeric vector.
    """
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            infos = zf.infolist()
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise DataError(f"not a readable .npz archive ({_reason(exc)})", source=source) from None
    unpacked = sum(i.file_size for i in infos)
    if unpacked > MAX_UNPACKED_BYTES:
        raise DataError(f"unpacks to {unpacked} bytes, more than the {MAX_UNPACKED_BYTES} a data "
                        "file may hold", source=source)
    try:
        archive = np.load(io.BytesIO(data), allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise DataError(f"not a readable .npz archive ({_reason(exc)})", source=source) from None
    if not hasattr(archive, "files"):
        raise DataError("a single .npy array, not an .npz archive of named columns", source=source)
    names = _check_names(list(archive.files), source, "array")

    def load(name: str) -> np.ndarray:
        try:
            value = archive[name]
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise DataError(f"column {name!r} cannot be read ({_reason(exc)})",
                            source=source) from None
        return _vector(value, name, source)

    return ColumnFile(source, names, load)


def parse_mat(data: bytes, source: str) -> ColumnFile:
    """Columns of a MATLAB ``.mat`` file (v4 to v7): one variable per column.

    Parameters
    ----------
    data : bytes
        The file.
    source : str
        The file name, for the errors.

    Returns
    -------
    ColumnFile

    Raises
    ------
    DataError
        A v7.3 (HDF5) file (not read: save with ``-v7``), an unreadable file, more than
        `MAX_COLUMNS` variables or `MAX_UNPACKED_BYTES` of them; on use, a variable that is
        not a numeric vector.
    """
    from scipy.io import loadmat, whosmat
    from scipy.io.matlab import MatReadError

    errors = (MatReadError, ValueError, TypeError, OSError, EOFError, KeyError, IndexError,
              AttributeError, UnicodeDecodeError, OverflowError, MemoryError)
    if data[:512].find(b"MATLAB 7.3") >= 0 or data[128:136] == b"\x89HDF\r\n\x1a\n":
        raise DataError("a MATLAB v7.3 (HDF5) file: save it with save(..., '-v7') (v4 to v7 are "
                        "read)", source=source)
    try:
        listing = whosmat(io.BytesIO(data))
    except NotImplementedError:
        raise DataError("a MATLAB v7.3 (HDF5) file: save it with save(..., '-v7') (v4 to v7 are "
                        "read)", source=source) from None
    except errors as exc:
        raise DataError(f"not a readable .mat file ({_reason(exc)})",
                        source=source) from None
    names = _check_names([nm for nm, _, _ in listing], source, "variable")
    shapes = {nm: shape for nm, shape, _ in listing}
    unpacked = sum(8 * math.prod(shape) for shape in shapes.values())
    if unpacked > MAX_UNPACKED_BYTES:
        raise DataError(f"holds {unpacked} bytes of numbers, more than the {MAX_UNPACKED_BYTES} a "
                        "data file may hold", source=source)

    def load(name: str) -> np.ndarray:
        try:
            value = loadmat(io.BytesIO(data), variable_names=[name])[name]
        except errors as exc:
            raise DataError(f"variable {name!r} cannot be read ({_reason(exc)})",
                            source=source) from None
        return _vector(value, name, source)

    return ColumnFile(source, names, load)


#: Reader of each data file extension (lower case).
FORMATS: dict[str, Callable[[bytes, str], ColumnFile]] = {
    ".csv": parse_csv,
    ".npz": parse_npz,
    ".mat": parse_mat,
}
