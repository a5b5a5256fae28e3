"""Bounded reading of ``.npz`` archives from a result directory (gains and verdict traces).

An ``.npz`` is a zip of ``.npy`` members; ``np.load`` trusts both the zip's
declared sizes and each member's header, so a 2 MB file of compressed zeros can
make it allocate gigabytes. `read_npz` reads an archive's bytes (already read
with a size cap, `tanksynth.artefacts.io.read_limited`) member by member: the
member count, each member's declared uncompressed size and the archive's total
are checked first, then each member's ``.npy`` header (shape, dtype) is read
from the zip stream and judged by the caller's limits before any array is
allocated, and the data are decompressed only up to the size the header implies.
"""

from __future__ import annotations

import io
import zipfile
import zlib
from pathlib import Path
from typing import IO, Callable

import numpy as np
from numpy.lib import format as npy_format

from tanksynth.errors import ArtefactError

__all__ = ["MemberCheck", "MalformedNPZ", "read_npz", "npy_bytes"]

#: Judge of one member from its header: ``check(key, shape, dtype)`` returns None when the
#: array may be read, else why not (one phrase).
MemberCheck = Callable[[str, tuple[int, ...], np.dtype], "str | None"]

class MalformedNPZ(ArtefactError):
    """An archive that is not a well-formed ``.npz`` (not a zip, not ``.npy`` members, a bad
    CRC, data that do not match a header), as opposed to one beyond the caller's limits."""


#: Largest ``.npy`` header read (bytes): numpy writes a few hundred at most.
_MAX_HEADER = 10_000


#: Bytes of one central-directory entry at most (fixed part, name, zip64 extra): numpy writes ~100.
_MAX_ENTRY = 1024


def _central_directory_size(data: bytes) -> int | None:
    """Size (bytes) of the zip's central directory as its end record states; None without one.

    Found as zipfile finds it (the last end-of-central-directory signature within the final
    64 KiB + 22 bytes), the zip64 end record's size when a zip64 locator precedes it.
    """
    end = data.rfind(b"PK\x05\x06", max(0, len(data) - 22 - 65535))
    if end < 0 or len(data) < end + 22:
        return None
    size = int.from_bytes(data[end + 12:end + 16], "little")
    if end >= 20 and data[end - 20:end - 16] == b"PK\x06\x07":   # zipfile then reads the zip64 record
        # the record just before the locator (where zipfile reads it) or where the locator points
        for start in (end - 20 - 56, int.from_bytes(data[end - 12:end - 4], "little")):
            if 0 <= start and data[start:start + 4] == b"PK\x06\x06" and len(data) >= start + 48:
                size = max(size, int.from_bytes(data[start + 40:start + 48], "little"))
    return size


def npy_bytes(shape: tuple[int, ...], dtype: np.dtype) -> int:
    """Bytes of the data of an array of ``shape`` and ``dtype`` (no header).

    Parameters
    ----------
    shape : tuple of int
        The array's shape.
    dtype : numpy.dtype
        Its element type.
    """
    count = 1
    for n in shape:
        count *= int(n)
    return count * int(dtype.itemsize)


def _header(fh: IO[bytes]) -> tuple[tuple[int, ...], bool, np.dtype]:
    """Shape, Fortran order and dtype of the ``.npy`` stream ``fh`` (its data not read)."""
    version = npy_format.read_magic(fh)
    if version == (1, 0):
        return npy_format.read_array_header_1_0(fh, max_header_size=_MAX_HEADER)
    if version == (2, 0):
        return npy_format.read_array_header_2_0(fh, max_header_size=_MAX_HEADER)
    raise ValueError(f"npy format version {version} not read")


def read_npz(data: bytes, path: str | Path, *, max_members: int, max_total: int,
             member_limit: Callable[[str], int], check: MemberCheck) -> dict[str, np.ndarray]:
    """The arrays of an ``.npz`` held in ``data``, every size checked before it is allocated.

    Parameters
    ----------
    data : bytes
        The archive's bytes (read with a cap).
    path : str or Path
        The file they were read from (named in errors).
    max_members : int
        Most members accepted.
    max_total : int
        Most bytes all members may declare uncompressed, together.
    member_limit : callable
        ``member_limit(key)``: most bytes the member ``<key>.npy`` may declare
        uncompressed (header included); 0 or less refuses the key.
    check : callable
        ``check(key, shape, dtype)`` (`MemberCheck`): None to read the array, else the
        reason it is refused.

    Returns
    -------
    dict of str to ndarray
        Each member's array under its key (the member name without ``.npy``), in the
        archive's order; writable copies.

    Raises
    ------
    ArtefactError
        One line naming the file (and the member): not a zip of ``.npy`` members,
        too many members, a declared size beyond its limit or the total, a header the
        caller refuses (shape, dtype), data that do not match the header, a bad CRC
        (`MalformedNPZ` for what is not a well-formed archive, whatever its size).
    """
    directory = _central_directory_size(data)
    if directory is not None and directory > max_members * _MAX_ENTRY:
        # zipfile would parse every entry of the central directory into objects first
        raise ArtefactError(f"{path}: a zip directory of {directory} bytes, more than "
                            f"{max_members} members need")
    try:
        archive = zipfile.ZipFile(io.BytesIO(data))
    except (zipfile.BadZipFile, zipfile.LargeZipFile, ValueError, OSError, EOFError,
            NotImplementedError) as exc:
        raise MalformedNPZ(f"{path}: not an NPZ archive ({_brief(exc)})") from None
    with archive:
        infos = archive.infolist()
        if len(infos) > max_members:
            raise ArtefactError(f"{path}: {len(infos)} members, more than the {max_members} accepted")
        keys: list[str] = []
        total = 0
        for info in infos:
            key = info.filename[:-len(".npy")] if info.filename.endswith(".npy") else ""
            if not key or key in keys:
                raise MalformedNPZ(f"{path}: member {info.filename!r} is not one .npy array of a "
                                    "distinct name")
            limit = member_limit(key)
            if limit <= 0:
                raise ArtefactError(f"{path}: unexpected member {info.filename!r}")
            if info.file_size > limit:
                raise ArtefactError(f"{path}: member {info.filename!r} declares {info.file_size} bytes "
                                    f"uncompressed, more than the {limit} it may hold")
            total += info.file_size
            if total > max_total:
                raise ArtefactError(f"{path}: members declare more than the {max_total} bytes "
                                    "uncompressed the file may hold")
            if info.flag_bits & 0x1 or info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
                raise ArtefactError(f"{path}: member {info.filename!r} is encrypted or compressed "
                                    "with another method than deflate")
            keys.append(key)
        return {key: _member(archive, info, key, path, check) for key, info in zip(keys, infos)}


def _member(archive: zipfile.ZipFile, info: zipfile.ZipInfo, key: str, path: str | Path,
            check: MemberCheck) -> np.ndarray:
    """One member's array: header judged, then at most its implied bytes decompressed."""
    where = f"{path}: member {info.filename!r}"
    try:
        with archive.open(info) as fh:
            try:
                shape, fortran, dtype = _header(fh)
            except (ValueError, TypeError, SyntaxError) as exc:
                raise MalformedNPZ(f"{where}: not an .npy array ({_brief(exc)})") from None
            if any(int(n) < 0 for n in shape):
                raise MalformedNPZ(f"{where}: negative dimension in its header's shape {tuple(shape)}")
            if dtype.hasobject or dtype.itemsize == 0:
                raise ArtefactError(f"{where}: dtype {dtype} is not an array of numbers or text")
            reason = check(key, tuple(shape), dtype)
            if reason is not None:
                raise ArtefactError(f"{where}: {reason}")
            size = npy_bytes(shape, dtype)
            if size > info.file_size:
                raise ArtefactError(f"{where}: its header's shape {tuple(shape)} needs {size} bytes, "
                                    f"more than the {info.file_size} it declares")
            raw = fh.read(size + 1)
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError) as exc:
        raise MalformedNPZ(f"{where}: unreadable ({_brief(exc)})") from None
    if len(raw) != size:
        raise MalformedNPZ(f"{where}: holds {'more' if len(raw) > size else 'fewer'} bytes than "
                            f"its header's shape {tuple(shape)} of {dtype}")
    array = np.frombuffer(raw, dtype=dtype).reshape(shape, order="F" if fortran else "C")
    return array.copy()


def _brief(exc: BaseException) -> str:
    """An exception as one short phrase."""
    return " ".join(str(exc).split())[:160] or type(exc).__name__
