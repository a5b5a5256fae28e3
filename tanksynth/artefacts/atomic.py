"""The one atomic write: every file tanksynth leaves in a result directory goes through here.

A file is written to a temporary file in the target's directory, made an
ordinary readable file (0644), and renamed over the target (``os.replace``,
atomic on POSIX): a reader sees the old file or the new one, never a partial
one, and an interrupted run leaves no partial file. `stage` / `commit` split
the two steps for writers that must publish several files together.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import BinaryIO, Callable

__all__ = ["atomic_write", "stage", "commit", "discard"]

#: What to write: bytes, text (UTF-8), or a function writing to a binary file object.
Payload = bytes | str | Callable[[BinaryIO], None]


def stage(target: str | Path, payload: Payload) -> Path:
    """Write ``payload`` to a temporary file beside ``target`` and return its path.

    Parameters
    ----------
    target : str or Path
        The file the payload is for (its directory must exist).
    payload : bytes, str or callable
        Bytes, text (written as UTF-8) or ``write(fh)`` on a binary file.

    Returns
    -------
    Path
        The staged file (mode 0644); `commit` renames it, `discard` removes it.
    """
    target = Path(target)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            if isinstance(payload, str):
                fh.write(payload.encode("utf-8"))
            elif isinstance(payload, (bytes, bytearray)):
                fh.write(payload)
            else:
                payload(fh)
        os.chmod(tmp, 0o644)  # mkstemp creates owner-only files; results are ordinary files
    except BaseException:
        discard(Path(tmp))
        raise
    return Path(tmp)


def commit(staged: Path, target: str | Path) -> Path:
    """Rename a staged file over its target (atomic); returns the target."""
    target = Path(target)
    os.replace(staged, target)
    return target


def discard(staged: Path) -> None:
    """Remove a staged file that will not be committed (no error if it is gone)."""
    Path(staged).unlink(missing_ok=True)


def atomic_write(target: str | Path, payload: Payload) -> Path:
    """Write ``payload`` to ``target`` atomically (see the module docstring); returns the target."""
    staged = stage(target, payload)
    try:
        return commit(staged, target)
    finally:
        discard(staged)
