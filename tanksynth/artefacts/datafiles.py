"""Data files copied into a result directory beside the artefact that read them (``DIR/data/``).

A ``fit`` artefact names its data files in ``diagnostics.data_files`` (``{file, source,
sha256}``: the copy's path relative to the directory, the file read, its sha256). The design
writer copies each file there (`write_data_copies`, atomically, under the directory's lock,
before the artefact itself), so the verdict and the report read the data from the result
directory (`read_data_copy`, hash checked) and never from the user's original paths.
"""

from __future__ import annotations

import hashlib
from pathlib import Path, PurePosixPath
from typing import Any, Mapping, Sequence

from tanksynth.artefacts.atomic import atomic_write
from tanksynth.artefacts.io import read_limited
from tanksynth.errors import ArtefactError

__all__ = ["DATA_DIRECTORY", "data_files", "data_copy_path", "write_data_copies", "read_data_copy"]

#: The sub-directory of a result directory that holds the copied data files.
DATA_DIRECTORY = "data"


def data_files(diagnostics: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The data files an artefact's diagnostics name: ``{file, source, sha256}`` each (``file``
    the copy's path relative to the result directory); empty when it names none.

    Parameters
    ----------
    diagnostics : mapping
        The artefact's diagnostics.

    Returns
    -------
    list of dict
    """
    files = diagnostics.get("data_files") if isinstance(diagnostics, Mapping) else None
    return [dict(f) for f in files if isinstance(f, Mapping)] if isinstance(files, list) else []


def data_copy_path(directory: str | Path, file: Any) -> Path:
    """The path of a copy named ``file`` (``data/<name>``) in a result directory.

    Parameters
    ----------
    directory : str or Path
        The result directory.
    file : str
        The copy's path relative to it, as an artefact records it.

    Returns
    -------
    Path

    Raises
    ------
    ArtefactError
        ``file`` is not ``data/<name>`` (an absolute path, ``..``, another directory).
    """
    if not isinstance(file, str):
        raise ArtefactError(f"{directory}: a data file's name must be a string, got {file!r}")
    parts = PurePosixPath(file).parts
    if len(parts) != 2 or parts[0] != DATA_DIRECTORY or parts[1] in (".", "..") or "\\" in file \
            or parts[1].startswith("."):
        raise ArtefactError(f"{directory}: data file name {file!r} is not data/<name>")
    return Path(directory) / DATA_DIRECTORY / parts[1]


def write_data_copies(directory: str | Path, files: Sequence[Mapping[str, Any]]) -> list[Path]:
    """Copy data files into ``DIR/data/`` (each atomically), checking each one's sha256.

    Call it under the directory's lock, before the artefact that names them is written.

    Parameters
    ----------
    directory : str or Path
        The result directory.
    files : sequence of mapping
        ``{file, source, sha256}`` each (`data_files`).

    Returns
    -------
    list of Path
        The copies.

    Raises
    ------
    ArtefactError
        A source changed since it was read (sha256 differs), is unreadable or too large, or a
        copy's name is not ``data/<name>``.
    """
    out = []
    for f in files:
        target = data_copy_path(directory, f.get("file"))
        source = Path(str(f.get("source")))
        try:
            raw = read_limited(source)
        except OSError as exc:
            raise ArtefactError(f"{source}: cannot read data file: {exc.strerror}") from None
        if hashlib.sha256(raw).hexdigest() != f.get("sha256"):
            raise ArtefactError(f"{source}: the data file changed while it was being fitted "
                                "(sha256 differs); run again")
        target.parent.mkdir(parents=True, exist_ok=True)
        out.append(atomic_write(target, raw))
    return out


def read_data_copy(directory: str | Path, file: Any, sha256: Any) -> Path:
    """The path of a copied data file, after checking that its sha256 is the recorded one.

    Parameters
    ----------
    directory : str or Path
        The result directory.
    file : str
        The copy's name (``data/<name>``).
    sha256 : str
        Its recorded sha256.

    Returns
    -------
    Path

    Raises
    ------
    ArtefactError
        Missing, unreadable, too large, or edited (sha256 differs).
    """
    path = data_copy_path(directory, file)
    raw = read_limited(path)
    if hashlib.sha256(raw).hexdigest() != sha256:
        raise ArtefactError(f"{path}: edited since the fit (sha256 differs from the artefact's "
                            "record)")
    return path
