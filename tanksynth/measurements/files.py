"""Bounded reading of data files: regular files only, a size cap, no hang on a FIFO.

Data files are input written by other programs (a rig's logger, MATLAB): a path that names a
FIFO, a device such as ``/dev/zero``, a directory or a huge file must give one line naming it,
not a hang or an exhausted memory. The pattern is the one of `tanksynth.artefacts.io`
(``read_limited``), rewritten here because this layer sits below the artefacts.
"""

from __future__ import annotations

import hashlib
import os
import stat
from pathlib import Path

from tanksynth.errors import DataError

__all__ = ["MAX_DATA_BYTES", "read_data_bytes", "file_sha256"]

#: Largest data file read (bytes): a log of a million samples of a few signals in CSV.
MAX_DATA_BYTES = 64 * 1024 ** 2
#: Bytes hashed per read in `file_sha256`.
_CHUNK = 1 << 20


def _open_regular(path: Path, limit: int) -> tuple[int, int]:
    """An open descriptor (blocking again) of a regular file of at most ``limit`` bytes, and its
    size; the descriptor is closed when the file is refused."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a FIFO must not block the open
    except OSError as exc:
        raise DataError(f"cannot read data file: {exc.strerror or exc}", source=str(path)) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            kind = ("a directory" if stat.S_ISDIR(st.st_mode) else "a FIFO" if stat.S_ISFIFO(st.st_mode)
                    else "a device or special file")
            raise DataError(f"not a regular file ({kind}); expected a .csv, .npz or .mat data file",
                            source=str(path))
        if st.st_size > limit:
            raise DataError(f"{st.st_size} bytes, more than the {limit} a data file may have",
                            source=str(path))
        os.set_blocking(fd, True)
    except BaseException:
        os.close(fd)
        raise
    return fd, int(st.st_size)


def read_data_bytes(path: str | Path, limit: int = MAX_DATA_BYTES) -> bytes:
    """The bytes of a regular data file of at most ``limit`` bytes.

    Parameters
    ----------
    path : str or Path
        The data file.
    limit : int, optional
        Largest size accepted (bytes; default `MAX_DATA_BYTES`).

    Returns
    -------
    bytes

    Raises
    ------
    DataError
        Missing or unreadable, not a regular file (a FIFO, a directory, a device), or larger
        than ``limit`` (naming the file).
    """
    path = Path(path)
    fd, _ = _open_regular(path, limit)
    try:
        with os.fdopen(fd, "rb", buffering=0) as fh:
            data = fh.read(limit + 1)
    except OSError as exc:
        raise DataError(f"cannot read data file: {exc.strerror or exc}", source=str(path)) from None
    if len(data) > limit:  # grew while being read
        raise DataError(f"more than the {limit} bytes a data file may have", source=str(path))
    return data


def file_sha256(path: str | Path, limit: int = MAX_DATA_BYTES) -> str:
    """sha256 (hex) of a regular file's bytes (read bounded, as `read_data_bytes`).

    Parameters
    ----------
    path : str or Path
        The file.
    limit : int, optional
        Largest size accepted (bytes; default `MAX_DATA_BYTES`).

    Returns
    -------
    str
        64 hexadecimal digits.

    Raises
    ------
    DataError
        As `read_data_bytes`.
    """
    path = Path(path)
    fd, _ = _open_regular(path, limit)
    digest = hashlib.sha256()
    total = 0
    try:
        with os.fdopen(fd, "rb", buffering=0) as fh:
            while chunk := fh.read(_CHUNK):
                total += len(chunk)
                if total > limit:
                    raise DataError(f"more than the {limit} bytes a data file may have",
                                    source=str(path))
                digest.update(chunk)
    except OSError as exc:
        raise DataError(f"cannot read data file: {exc.strerror or exc}", source=str(path)) from None
    return digest.hexdigest()
