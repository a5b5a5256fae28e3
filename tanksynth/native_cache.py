"""The one native-compile cache: C source to a shared library, built once, kept on disk.

Two parts of tanksynth compile generated C and load it: the simulator's period
kernel (`tanksynth.sim.kernel`, loaded with ``ctypes``) and the estimators'
step kernels (`tanksynth.runtime.estimators.kernels`, generated and loaded by
CasADi). Both go through a `NativeCache` of this module, which owns what they
share: the compiler and its flags, the cache directory, the build (locked,
atomic), the libraries kept in memory, the failures remembered and the
fall-back when no compiler is present (None, never an error, so that the
caller takes its numpy or CasADi route).

Place in the layers: this module imports nothing of tanksynth (the standard
library only), and ``tanksynth.sim`` and ``tanksynth.runtime``, which must not
import each other, both need it; it therefore sits in the lowest layer of
``.importlinter``, beside `tanksynth.errors`, where every stage may use it and
it can depend on no stage.

Compiler: ``$TANKSYNTH_CC`` if set (a name on the ``PATH`` or a file), else
``gcc``, else ``cc`` on the ``PATH`` (`find_compiler`). Flags: `BUILD_FLAGS`
(``-O3 -shared -fPIC -ffp-contract=off -fno-math-errno -std=c99``; no fused
multiply-add and no fast-math, so the library computes the same IEEE
operations as the numpy or CasADi code it replaces, bit for bit), plus
``-mavx2`` on an x86-64 CPU with AVX2, tried first and dropped if that build
fails (`flag_sets`).

Directory: ``<root>/<family>`` where ``<root>`` is ``$TANKSYNTH_CACHE_DIR``,
else ``$XDG_CACHE_HOME/tanksynth``, else ``~/.cache/tanksynth``
(`cache_root`); a family may also name an environment variable that gives
its directory directly (the estimator kernels: ``$TANKSYNTH_CACHE``). A
library is named by the SHA-256 of its key (the C source and whatever else
changes the code: a generator's version), the compiler path and the flags,
so a library is never used for another kernel, compiler or flag set. A build
holds the directory's lock (``.lock``, ``flock``; at most `COMPILE_TIMEOUT`
waited for, then built anyway), compiles in a temporary directory inside the
cache directory and renames the library into place: concurrent processes
build a library once, and a reader never sees half a file. A library on disk
cut short by something else (a copy, a full disk: a segment the loader maps
lies past the end of the file, which would kill the process with SIGBUS) is
built again instead of loaded; other damaged files are refused by the loader
(an error, remembered as a failed build).

Bounds: a compiler run is stopped after `COMPILE_TIMEOUT` seconds; at most
`MAX_LOADED` libraries per family are kept in memory (the oldest are
forgotten first; whoever holds one keeps it), and as many failures; a
compiler's message is cut to its first line (300 characters). Files on disk
stay until `NativeCache.clear` deletes them.
"""

from __future__ import annotations

import hashlib
import os
import platform
import shutil
import struct
import subprocess
import tempfile
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

__all__ = ["BUILD_FLAGS", "COMPILE_TIMEOUT", "MAX_LOADED", "NativeBuildError", "NativeLibrary",
           "NativeCache", "find_compiler", "flag_sets", "cache_root", "ctypes_loader"]

#: Flags of every build: position-independent shared code, IEEE arithmetic as written (no
#: contraction into fused multiply-adds, no ``errno`` from libm: ``sqrt`` stays one instruction).
BUILD_FLAGS = ("-O3", "-shared", "-fPIC", "-ffp-contract=off", "-fno-math-errno", "-std=c99")

#: Longest compiler run, and longest wait for another process's build (s).
COMPILE_TIMEOUT = 600.0

#: Libraries (and failures) kept in memory per family.
MAX_LOADED = 256

#: Characters of a compiler's message kept in an error.
_MESSAGE_CHARS = 300


class NativeBuildError(OSError):
    """No library: the compiler or the loader failed; the message says why.

    Parameters
    ----------
    reason : str
        What failed (the compiler's first line of output, or the loader's error).
    repeated : bool
        The failure was remembered from an earlier request: nothing was run this time.

    Attributes
    ----------
    repeated : bool
        As the parameter.
    """

    def __init__(self, reason: str, repeated: bool = False):
        super().__init__(reason)
        self.repeated = repeated


@dataclass(frozen=True)
class NativeLibrary:
    """A loaded library of a `NativeCache`.

    Attributes
    ----------
    handle : object
        What the family's loader returned (a ``ctypes.CDLL`` wrapper, a ``casadi.Function``).
    path : pathlib.Path
        The shared library on disk.
    flags : tuple of str
        The compiler flags it was built with.
    compile_seconds : float
        Wall time of the compiler run that built it in this process (s; 0 when it was on disk).
    """

    handle: Any
    path: Path
    flags: tuple[str, ...]
    compile_seconds: float


def ctypes_loader(symbol: str) -> Callable[[Path, str], Any]:
    """A family's ``load`` for `NativeCache.library`: ``ctypes.CDLL`` of the file, refusing one
    that defines no ``symbol`` (another library under the kernel's name) with AttributeError,
    which the cache counts as a failed build.

    Parameters
    ----------
    symbol : str
        The C function every library of the family defines (e.g. ``tk_run``).

    Returns
    -------
    callable
        ``load(path, name) -> ctypes.CDLL``.
    """
    def load(path: Path, name: str) -> Any:
        import ctypes

        lib = ctypes.CDLL(str(path))
        getattr(lib, symbol)
        return lib
    return load


def find_compiler() -> str | None:
    """The C compiler: ``$TANKSYNTH_CC`` if set, else ``gcc`` or ``cc`` on the ``PATH``.

    Returns
    -------
    str or None
        Its path; None when there is none (or ``$TANKSYNTH_CC`` names nothing that exists).
    """
    cc = os.environ.get("TANKSYNTH_CC")
    if cc:
        return shutil.which(cc) or (cc if os.path.isfile(cc) else None)
    return shutil.which("gcc") or shutil.which("cc")


def flag_sets() -> tuple[tuple[str, ...], ...]:
    """Compiler flag sets to try, best first: `BUILD_FLAGS` plus ``-mavx2`` on an AVX2 x86-64 CPU.

    AVX2 lets the compiler vectorise conditionals (clipping, hybrid branches)
    over 4 runs; the numbers do not change (the same IEEE operations, no fused
    multiply-add). The flags are part of a library's name, so a library built
    with them is never loaded on a CPU without them.

    Returns
    -------
    tuple of tuple of str
    """
    if platform.machine().lower() in ("x86_64", "amd64"):
        try:
            info = Path("/proc/cpuinfo").read_text()
        except OSError:
            info = ""
        cpu = next((ln.split(":", 1)[1].split() for ln in info.splitlines()
                    if ln.startswith("flags")), [])
        if "avx2" in cpu:
            return (BUILD_FLAGS + ("-mavx2",), BUILD_FLAGS)
    return (BUILD_FLAGS,)


def cache_root() -> Path:
    """Root of the compiled libraries (not created here).

    Returns
    -------
    pathlib.Path
        ``$TANKSYNTH_CACHE_DIR``, else ``$XDG_CACHE_HOME/tanksynth``, else
        ``~/.cache/tanksynth``.
    """
    base = os.environ.get("TANKSYNTH_CACHE_DIR")
    if base:
        return Path(base)
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "tanksynth"


@contextmanager
def _directory_lock(directory: Path) -> Iterator[None]:
    """Hold ``directory/.lock`` (``flock``) for a build; after `COMPILE_TIMEOUT` s, go on without.

    Waiting only saves a second compiler run: the build's atomic rename keeps the
    cache correct without the lock (and where ``fcntl`` does not exist).
    """
    try:
        import fcntl
    except ImportError:                                     # not POSIX: rename alone
        yield
        return
    with open(directory / ".lock", "a") as handle:
        deadline = time.monotonic() + COMPILE_TIMEOUT
        locked = False
        while not locked:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
                locked = True
            except OSError:
                if time.monotonic() > deadline:
                    break
                time.sleep(0.05)
        try:
            yield
        finally:
            if locked:
                fcntl.flock(handle, fcntl.LOCK_UN)


def _compile(source: str, cc: str, flags: Sequence[str], path: Path) -> float:
    """Compile ``source`` to ``path`` (temporary directory beside it, then rename); wall time (s).

    Raises
    ------
    NativeBuildError
        The compiler failed, timed out or could not be run.
    """
    with tempfile.TemporaryDirectory(dir=path.parent, prefix=".build-") as tmp:
        src = Path(tmp) / "kernel.c"
        src.write_text(source)
        out = Path(tmp) / "kernel.so"
        t0 = time.perf_counter()
        try:
            proc = subprocess.run([cc, *flags, str(src), "-o", str(out), "-lm"],
                                  capture_output=True, text=True, timeout=COMPILE_TIMEOUT)
        except subprocess.TimeoutExpired:
            raise NativeBuildError(f"{cc} ran longer than {COMPILE_TIMEOUT:g} s") from None
        seconds = time.perf_counter() - t0
        if proc.returncode != 0 or not out.is_file():
            msg = (proc.stderr or proc.stdout or "").strip().splitlines()
            raise NativeBuildError(f"{cc} exited with status {proc.returncode}"
                                   + (f": {msg[0][:_MESSAGE_CHARS]}" if msg else ""))
        os.replace(out, path)
    return seconds


def _whole_elf(path: Path) -> bool:
    """False when ``path`` is an ELF library cut short: a segment the loader maps lies past its
    end (the dynamic loader would map pages beyond the file and the process die of SIGBUS).

    A file that is not ELF (another platform's format, or no library at all) is True: the
    loader refuses such a file with an error, not a crash.
    """
    try:
        with open(path, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            head = f.read(64)
            if len(head) < 52 or head[:4] != b"\x7fELF" or head[4] not in (1, 2) or head[5] not in (1, 2):
                return True                  # not ELF, or too short to map: the loader refuses it
            end = "<" if head[5] == 1 else ">"
            wide = head[4] == 2
            if wide:
                (phoff,) = struct.unpack_from(end + "Q", head, 32)
                phentsize, phnum = struct.unpack_from(end + "HH", head, 54)
            else:
                (phoff,) = struct.unpack_from(end + "I", head, 28)
                phentsize, phnum = struct.unpack_from(end + "HH", head, 42)
            if phoff + phentsize * phnum > size or phentsize < (56 if wide else 32):
                return False
            f.seek(phoff)
            table = f.read(phentsize * phnum)
    except OSError:
        return True                          # (the loader says what is wrong)
    for i in range(phnum):
        at = i * phentsize
        if wide:
            (offset,) = struct.unpack_from(end + "Q", table, at + 8)
            (filesz,) = struct.unpack_from(end + "Q", table, at + 32)
        else:
            (offset,) = struct.unpack_from(end + "I", table, at + 4)
            (filesz,) = struct.unpack_from(end + "I", table, at + 16)
        if offset + filesz > size:
            return False
    return True


def _remember(table: dict, key: str, value: Any) -> None:
    """``table[key] = value``, forgetting the oldest entries beyond `MAX_LOADED`."""
    table.pop(key, None)
    table[key] = value
    while len(table) > MAX_LOADED:
        del table[next(iter(table))]


@dataclass
class NativeCache:
    """One family of compiled libraries: its directory, file names, and what is loaded.

    Parameters
    ----------
    family : str
        Subdirectory of `cache_root` (``"sim"``, ``"kernels"``).
    prefix : str
        Start of the library files' names (a C identifier; ``tk_sim_``, ``tk_``).
    directory_env : str, optional
        An environment variable that, when set, names the directory itself.

    Attributes
    ----------
    loaded : dict
        Library name -> `NativeLibrary`, loaded in this process.
    failed : dict
        Library name -> why it could not be built or loaded (not tried again).
    compiles : int
        Compiler runs of this process.
    """

    family: str
    prefix: str
    directory_env: str | None = None
    loaded: dict[str, NativeLibrary] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)
    compiles: int = 0

    def directory(self) -> Path:
        """The family's directory (not created here): ``$<directory_env>``, else ``cache_root()/<family>``."""
        given = os.environ.get(self.directory_env) if self.directory_env else None
        return Path(given) if given else cache_root() / self.family

    def name(self, key: Sequence[str], cc: str, flags: Sequence[str]) -> str:
        """File stem of a library (also a C identifier): the prefix and 24 hex digits of its hash.

        Parameters
        ----------
        key : sequence of str
            What makes the code: the C source (or what generates it) and the generator's version.
        cc : str
            Compiler path.
        flags : sequence of str
            Compiler flags.
        """
        digest = hashlib.sha256("\0".join([*key, cc, *flags]).encode()).hexdigest()
        return f"{self.prefix}{digest[:24]}"

    def library(self, key: Sequence[str], source: Callable[[str], str],
                load: Callable[[Path, str], Any], cc: str, build: bool = True
                ) -> NativeLibrary | None:
        """The library of ``key``: in memory, else on disk, else compiled (best flags first).

        Parameters
        ----------
        key : sequence of str
            What makes the code (see `name`).
        source : callable
            ``source(name) -> str``: the C source, given the library's name (called
            only when a build is needed; a CasADi function is named after it).
        load : callable
            ``load(path, name) -> handle``: loads the library (``ctypes``, ``casadi.external``).
        cc : str
            Compiler path (`find_compiler`).
        build : bool
            Compile when no library is on disk; False: only load one already built.

        Returns
        -------
        NativeLibrary or None
            None only when ``build`` is False and no library is on disk.

        Raises
        ------
        NativeBuildError
            Every flag set failed, now or (``repeated``) in an earlier request.
        """
        candidates = [(self.name(key, cc, flags), flags) for flags in flag_sets()]
        for name, _ in candidates:
            if name in self.loaded:
                return self.loaded[name]
        if all(name in self.failed for name, _ in candidates):
            raise NativeBuildError(self.failed[candidates[-1][0]], repeated=True)
        directory = self.directory()
        if not build and not any((directory / f"{name}.so").is_file() for name, _ in candidates):
            return None
        reason = ""
        for name, flags in candidates:
            path = directory / f"{name}.so"
            if name in self.failed or (not build and not path.is_file()):
                reason = self.failed.get(name, reason)
                continue
            try:
                lib = self._load_or_build(name, flags, path, source, load, cc)
            except (OSError, subprocess.SubprocessError, RuntimeError, AttributeError) as exc:
                reason = str(exc)
                _remember(self.failed, name, reason)
                continue
            _remember(self.loaded, name, lib)
            return lib
        raise NativeBuildError(reason)

    def _load_or_build(self, name: str, flags: tuple[str, ...], path: Path,
                       source: Callable[[str], str], load: Callable[[Path, str], Any],
                       cc: str) -> NativeLibrary:
        seconds = 0.0
        if not path.is_file() or not _whole_elf(path):
            path.parent.mkdir(parents=True, exist_ok=True)
            with _directory_lock(path.parent):
                # another process may have built it; a library cut short (a copy or disk
                # failure) is built again: loading it would kill the process (SIGBUS)
                if not path.is_file() or not _whole_elf(path):
                    seconds = _compile(source(name), cc, flags, path)
                    self.compiles += 1
        return NativeLibrary(load(path, name), path, flags, seconds)

    def files(self) -> list[Path]:
        """The family's libraries on disk."""
        directory = self.directory()
        return sorted(directory.glob(f"{self.prefix}*.so")) if directory.is_dir() else []

    def clear(self, disk: bool = False) -> dict[str, int]:
        """Forget the loaded libraries and the failures; with ``disk``, delete the files too.

        Whoever holds a library keeps it; the next request loads (or builds) it again.

        Parameters
        ----------
        disk : bool
            Also delete the family's ``<prefix>*.so`` files (other files are left alone).

        Returns
        -------
        dict
            ``loaded`` (libraries forgotten) and ``files`` (libraries deleted).
        """
        loaded = len(self.loaded)
        self.loaded.clear()
        self.failed.clear()
        files = 0
        for path in self.files() if disk else ():
            path.unlink(missing_ok=True)
            files += 1
        return {"loaded": loaded, "files": files}

    def info(self) -> dict[str, object]:
        """``loaded``, ``failed``, ``compiles`` (this process), ``files`` (on disk), ``directory``."""
        return {"loaded": len(self.loaded), "failed": len(self.failed), "compiles": self.compiles,
                "files": len(self.files()), "directory": str(self.directory())}
