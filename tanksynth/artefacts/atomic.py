"""The one atomic write: every file tanksynth leaves in a result directory goes through here.

A file is written to a temporary file in the target's directory, given the
mode of the file it replaces (a new file: ``0666`` less the umask, as any
ordinary file, so every output file of a run shares one mode), and renamed
over the target (``os.replace``, atomic on POSIX): a reader sees the old file
or the new one, never a partial one, and an interrupted run leaves no partial
file. `stage` / `commit` split the two steps for writers that must publish
several files together.

`directory_lock` makes a result directory written by one run at a time: a
lock file ``DIR/.tanksynth.lock`` holds the writer's pid, host and start
time; a second run is refused naming them, and a lock left by a process that
died (same host, pid gone) is taken over.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import stat
import tempfile
import threading
import time
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO, Callable, Iterator

from tanksynth.errors import ArtefactError

__all__ = ["Payload", "atomic_write", "stage", "commit", "discard", "file_mode", "directory_lock", "LOCK_NAME",
           "staged_target", "stale_temporaries", "remove_stale", "build_directory", "BUILD_MARKER"]

#: The lock file of a result directory.
LOCK_NAME = ".tanksynth.lock"
_umask_lock = threading.Lock()


def file_mode(target: str | Path) -> int:
    """The mode a file written to ``target`` gets: the existing file's permission bits, else
    ``0o666`` less the process umask (what ``open(target, "w")`` would create).

    Parameters
    ----------
    target : str or Path
        The file about to be written (it may not exist yet).
    """
    try:
        return os.stat(target).st_mode & 0o7777
    except OSError:
        with _umask_lock:
            mask = os.umask(0o022)
            os.umask(mask)
        return 0o666 & ~mask

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
        The staged file (mode: `file_mode` of the target); `commit` renames
        it, `discard` removes it.
    """
    target = Path(target)
    mode = file_mode(target)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.{STAGE_TAG}", suffix=".tmp", dir=target.parent)
    except OSError as exc:  # name the file the user asked for, not the temporary one
        raise OSError(exc.errno, exc.strerror, str(target)) from None
    try:
        with os.fdopen(fd, "wb") as fh:
            if isinstance(payload, str):
                fh.write(payload.encode("utf-8"))
            elif isinstance(payload, (bytes, bytearray)):
                fh.write(payload)
            else:
                payload(fh)
        os.chmod(tmp, mode)  # mkstemp creates owner-only files; keep the target's mode
    except OSError as exc:
        discard(Path(tmp))
        if exc.errno is None:
            raise
        raise OSError(exc.errno, exc.strerror, str(target)) from None
    except BaseException:
        discard(Path(tmp))
        raise
    return Path(tmp)


#: Part of every staged file's name: a user's ``.notes.json.abcdefgh.tmp`` is never taken for
#: the tool's and removed (the cleanup goes by name).
STAGE_TAG = "tanksynth-"

#: Names of what tanksynth writes to a result directory before renaming it: `stage`'s files
#: (``.<target>.tanksynth-<8 characters of mkstemp>.tmp``, the target one of the kinds of file tanksynth
#: writes there), the build directories of a law export
#: (``.law-build-<8>.tmp``) and of a PDF (``.report-build-<8>``), and a lock being taken over
#: (``.tanksynth.lock.stale.<pid>``).
_STAGED_FILE = re.compile(r"\.(?P<target>.+\.(json|npz|mat|h|c|casadi|toml|csv|tex|pdf|log|png|svg))"
                          r"\." + re.escape(STAGE_TAG) + r"[a-z0-9_]{8}\.tmp")
_BUILD_DIR = re.compile(r"\.law-build-[a-z0-9_]{8}\.tmp|\.report-build-[a-z0-9_]{8}")
_STALE_LOCK = re.compile(re.escape(LOCK_NAME) + r"\.stale\.[0-9]+")
#: The file `build_directory` puts in every build directory it makes: a directory of a build
#: name without it (a user's, e.g. ``.report-build-mydrafts``) is never removed, unless empty.
BUILD_MARKER = ".tanksynth-build"


def build_directory(directory: str | Path, prefix: str, suffix: str = "") -> Path:
    """A new temporary build directory in ``directory``, marked as the tool's (`BUILD_MARKER`).

    Parameters
    ----------
    directory : str or Path
        Where it is made (a result directory).
    prefix, suffix : str
        Its name's ends (``tempfile.mkdtemp``; 8 random characters between them).

    Returns
    -------
    Path
        The directory; `stale_temporaries` lists it when a killed run leaves it behind.
    """
    path = Path(tempfile.mkdtemp(prefix=prefix, suffix=suffix, dir=directory))
    (path / BUILD_MARKER).touch()
    return path


def _tool_build_dir(path: Path) -> bool:
    """A build directory the tool made (its marker in it) or an empty one (nothing to lose)."""
    try:
        return os.path.isfile(path / BUILD_MARKER) or not any(path.iterdir())
    except OSError:
        return False


def staged_target(path: str | Path) -> str | None:
    """The name of the file a temporary file of `stage` was for; None for any other name.

    Parameters
    ----------
    path : str or Path
        A file name (``.<target>.tanksynth-<8 characters>.tmp``).
    """
    match = _STAGED_FILE.fullmatch(Path(path).name)
    return None if match is None else match.group("target")


def stale_temporaries(directory: str | Path) -> list[Path]:
    """What a tanksynth run killed mid-write left in ``directory``: temporary files and build
    directories of the tool's own naming (see `stage`), never any other file.

    Only meaningful under `directory_lock` (no other run is writing then); regular files
    and real directories only (a symlink of such a name is not the tool's).

    Parameters
    ----------
    directory : str or Path
        A result directory.

    Returns
    -------
    list of Path
        Sorted.
    """
    out = []
    try:
        entries = sorted(Path(directory).iterdir())
    except OSError:
        return []
    for path in entries:
        try:
            mode = os.lstat(path).st_mode
        except OSError:
            continue
        name = path.name
        if stat.S_ISREG(mode) and (_STAGED_FILE.fullmatch(name) or _STALE_LOCK.fullmatch(name)):
            out.append(path)
        elif stat.S_ISDIR(mode) and _BUILD_DIR.fullmatch(name) and _tool_build_dir(path):
            out.append(path)
    return out


def remove_stale(paths: list[Path]) -> None:
    """Remove what `stale_temporaries` listed (files, and build directories with their content).

    Parameters
    ----------
    paths : list of Path
        From `stale_temporaries`.
    """
    for path in paths:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)


def commit(staged: Path, target: str | Path) -> Path:
    """Rename a staged file over its target (atomic); returns the target.

    Parameters
    ----------
    staged : Path
        The file `stage` returned.
    target : str or Path
        The file it replaces (in the same directory).
    """
    target = Path(target)
    os.replace(staged, target)
    return target


def discard(staged: Path) -> None:
    """Remove a staged file that will not be committed (no error if it is gone).

    Parameters
    ----------
    staged : Path
        The file `stage` returned.
    """
    Path(staged).unlink(missing_ok=True)


def atomic_write(target: str | Path, payload: Payload) -> Path:
    """Write ``payload`` to ``target`` atomically (see the module docstring); returns the target.

    Parameters
    ----------
    target : str or Path
        The file to write (its directory must exist).
    payload : bytes, str or callable
        Bytes, text (written as UTF-8) or ``write(fh)`` on a binary file.
    """
    staged = stage(target, payload)
    try:
        return commit(staged, target)
    finally:
        discard(staged)


#: Largest pid a lock file may name (``pid_t`` is a signed 32-bit int on POSIX).
_MAX_PID = 2 ** 31 - 1


def _lock_pid(info: dict) -> int | None:
    """The pid of a lock's holder record; None unless an int in ``[1, _MAX_PID]`` (not a bool)."""
    pid = info.get("pid")
    if isinstance(pid, bool) or not isinstance(pid, int) or not 1 <= pid <= _MAX_PID:
        return None
    return pid


def _alive(pid: int) -> bool | None:
    """True if process ``pid`` exists, False if not, None if ``os.kill`` rejects the pid."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    except (OverflowError, ValueError, OSError):
        return None
    return True


def _holder(lock: Path) -> dict:
    """The lock's holder record; {} for anything but a small regular file of JSON (a FIFO or
    a device in its place must not block or flood the reader)."""
    try:
        fd = os.open(lock, os.O_RDONLY | os.O_NONBLOCK)
        with os.fdopen(fd, "rb", buffering=0) as fh:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                return {}
            info = json.loads(fh.read(65536).decode("utf-8"))
        return info if isinstance(info, dict) else {}
    except (OSError, ValueError, RecursionError):
        return {}


@contextmanager
def directory_lock(directory: str | Path, command: str = "tanksynth") -> Iterator[Path]:
    """Hold ``DIR/.tanksynth.lock`` while a command writes into ``directory`` (created if missing).

    Parameters
    ----------
    directory : str or Path
        Created if missing (and removed again if the run left it empty).
    command : str
        What holds the lock (shown to a second run).

    Yields
    ------
    Path
        The lock file; removed on exit.

    Raises
    ------
    ArtefactError
        Another live process holds the lock (its pid, host, command and
        start time are named). A lock of a dead process on this host is taken
        over; a lock from another host is never broken automatically.
        A lock whose holder cannot be read (not JSON, no ``host``, or a
        ``pid`` that is not an int in ``[1, 2**31 - 1]``, e.g. 0, -5 or
        10**20, or one ``os.kill`` rejects) is never taken over, whatever
        the host: it is refused as an unreadable lock file, to be removed by
        hand if no tanksynth run is using the directory (a lock being written
        right now, less than 5 s old and empty, is waited for).
    """
    directory = Path(directory)
    created = not directory.exists()
    directory.mkdir(parents=True, exist_ok=True)
    lock = directory / LOCK_NAME
    me = {"pid": os.getpid(), "host": socket.gethostname(), "command": command,
          "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    for _ in range(3):
        try:
            fd = os.open(lock, os.O_WRONLY | os.O_CREAT | os.O_EXCL, file_mode(lock))
        except FileExistsError:
            info = _holder(lock)
            pid, host = _lock_pid(info), info.get("host")
            alive = None if pid is None else _alive(pid)
            if not info and time.time() - _mtime(lock) < 5:
                time.sleep(0.2)  # a lock being written right now
                continue
            if alive is None or not isinstance(host, str):
                raise ArtefactError(f"{directory}: unreadable lock file {lock} (no valid pid and host of "
                                    "a tanksynth run); remove it if no tanksynth run is using "
                                    f"{directory}") from None
            if host == me["host"] and not alive:
                stale = lock.with_name(f"{LOCK_NAME}.stale.{os.getpid()}")
                try:  # take over atomically: only one run renames the stale lock away
                    os.replace(lock, stale)
                    stale.unlink(missing_ok=True)
                except FileNotFoundError:
                    pass
                continue
            raise ArtefactError(
                f"{directory}: in use by another run (pid {pid}, host {host}, "
                f"{info.get('command', '?')} started {info.get('started', '?')}); wait for it to "
                f"finish, or remove {lock} if that run is gone") from None
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(json.dumps(me) + "\n")
        break
    else:
        raise ArtefactError(f"{directory}: could not take the lock {lock} (unreadable, not written "
                            "by tanksynth); remove it if no run is using the directory")
    try:
        yield lock
    finally:
        if _holder(lock).get("pid") == me["pid"]:
            lock.unlink(missing_ok=True)
        if created:  # a run that wrote nothing leaves no empty directory behind
            try:
                directory.rmdir()
            except OSError:
                pass


def _mtime(path: Path) -> float:
    try:
        return path.stat().st_mtime
    except OSError:
        return 0.0
