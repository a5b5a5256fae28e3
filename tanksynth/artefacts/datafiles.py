"""Data files copied into a result directory beside the artefact that read them (``DIR/data/``).

A ``fit`` artefact names its data files in ``diagnostics.data_files`` (``{file, source,
sha256}``: the copy's path relative to the directory, the file read, its sha256). The design
writer copies each file there (`data_copies`, atomically, under the directory's lock,
before the artefact itself, and put back as they were when the artefact's write fails), so the verdict and the report read the data from the result
directory (`read_data_copy`, hash checked) and never from the user's original paths.
"""

from __future__ import annotations

import hashlib
import shutil
from contextlib import contextmanager
from pathlib import Path, PurePosixPath
from typing import Any, BinaryIO, Callable, Iterator, Mapping, Sequence

from tanksynth.artefacts.atomic import commit, discard, stage
from tanksynth.artefacts.io import read_limited
from tanksynth.errors import ArtefactError

__all__ = ["DATA_DIRECTORY", "data_files", "data_copy_path", "write_data_copies", "data_copies",
           "read_data_copy"]

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


def _staged_copies(directory: str | Path, files: Sequence[Mapping[str, Any]]
                   ) -> list[tuple[Path, Path]]:
    """Every copy read, hash-checked and staged beside its target: ``(staged, target)`` each
    (nothing staged is left behind when one fails)."""
    staged: list[tuple[Path, Path]] = []
    try:
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
            staged.append((stage(target, raw), target))
    except BaseException:
        for tmp, _ in staged:
            discard(tmp)
        raise
    return staged


def _copier(path: Path) -> Callable[[BinaryIO], None]:
    """``write(fh)`` copying ``path`` into ``fh`` (a payload of `stage`)."""
    def write(fh: BinaryIO) -> None:
        with path.open("rb") as src:
            shutil.copyfileobj(src, fh)
    return write


def _remove_if_empty(path: Path) -> None:
    try:
        path.rmdir()
    except OSError:
        pass


def write_data_copies(directory: str | Path, files: Sequence[Mapping[str, Any]]) -> list[Path]:
    """Copy data files into ``DIR/data/`` (each atomically), checking each one's sha256; none
    is copied unless every one is read and matches.

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
    staged = _staged_copies(directory, files)
    try:
        return [commit(tmp, target) for tmp, target in staged]
    finally:
        for tmp, _ in staged:
            discard(tmp)


@contextmanager
def data_copies(directory: str | Path, files: Sequence[Mapping[str, Any]]) -> Iterator[list[Path]]:
    """Copy data files into ``DIR/data/`` for the artefact written in the ``with`` body: when the
    body fails (or is interrupted) the directory is put back as it was (new copies removed, the
    copies of an earlier fit they replaced restored).

    Call it under the directory's lock.

    Parameters
    ----------
    directory : str or Path
        The result directory.
    files : sequence of mapping
        ``{file, source, sha256}`` each (`data_files`).

    Yields
    ------
    list of Path
        The copies.

    Raises
    ------
    ArtefactError
        As `write_data_copies` (before anything is written).
    """
    directory = Path(directory)
    made_dir = bool(files) and not (directory / DATA_DIRECTORY).exists()
    try:
        staged = _staged_copies(directory, files)
    except BaseException:
        if made_dir:
            _remove_if_empty(directory / DATA_DIRECTORY)
        raise
    done: list[tuple[Path, Path | None]] = []   # (target, the staged copy of what it replaced)
    try:
        try:
            for tmp, target in staged:
                backup = None
                if target.is_file():
                    backup = stage(target, _copier(target))
                done.append((target, backup))
                commit(tmp, target)
            yield [target for _, target in staged]
        except BaseException:
            for target, backup in reversed(done):
                if backup is None:
                    target.unlink(missing_ok=True)
                else:
                    commit(backup, target)
            if made_dir:
                _remove_if_empty(directory / DATA_DIRECTORY)
            raise
    finally:
        for tmp, _ in staged:
            discard(tmp)
        for _, backup in done:
            if backup is not None:
                discard(backup)


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
