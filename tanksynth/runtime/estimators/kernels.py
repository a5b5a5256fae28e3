"""CasADi building blocks of the estimator kernels, and their native compilation.

SX helpers (symmetrisation, Cholesky with pivots, SPD inverse) used to write
every step of a `KernelEstimator` as one SX function; `_native` compiles
such a function to a shared library with the C compiler (``gcc``/``cc``)
and loads it (``casadi.external``).

Cache (no hidden state): compiled libraries are written to
``$TANKSYNTH_CACHE`` if set, else ``$XDG_CACHE_HOME/tanksynth/kernels``, else
``~/.cache/tanksynth/kernels`` (`cache_dir`), named by the SHA-256 of their
generated C source, compiler flags and CasADi version, so a library is never
used for another kernel; the loaded ones are also kept in memory
(``_NATIVE_CACHE``). `clear_cache` (and ``tanksynth.runtime.clear_cache``)
forgets the loaded ones and, on request, deletes the files.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import casadi as ca

__all__ = ["sx_symmetrize", "sx_cholesky", "sx_spd_inverse", "cache_dir", "clear_cache",
           "cache_info"]


def sx_symmetrize(A: ca.SX) -> ca.SX:
    """``(A + A') / 2``.

    Parameters
    ----------
    A : casadi.SX
        A square matrix.
    """
    return 0.5 * (A + A.T)


def sx_cholesky(A: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Lower Cholesky factor of a symmetric matrix, with its pivots.

    Parameters
    ----------
    A : casadi.SX, shape (n, n)

    Returns
    -------
    L : casadi.SX, shape (n, n)
        ``L L' = A`` when ``A`` is positive definite.
    pivots : casadi.SX, shape (n, 1)
        ``d_j = A_jj - sum_k L_jk^2``; ``A`` is positive definite iff all are
        > 0. (A non-positive pivot is clamped to 1e-300 inside the square
        root so that the kernel never produces NaN; the caller raises.)
    """
    n = A.shape[0]
    L = [[ca.SX(0) for _ in range(n)] for _ in range(n)]
    piv = []
    for j in range(n):
        d = A[j, j]
        for k in range(j):
            d = d - L[j][k] * L[j][k]
        piv.append(d)
        r = ca.sqrt(ca.fmax(d, 1e-300))
        L[j][j] = r
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s = s - L[i][k] * L[j][k]
            L[i][j] = s / r
    return ca.blockcat(L), ca.vertcat(*piv)


def _sx_lower_inverse(L: ca.SX) -> ca.SX:
    n = L.shape[0]
    X = [[ca.SX(0) for _ in range(n)] for _ in range(n)]
    for j in range(n):
        X[j][j] = 1 / L[j, j]
        for i in range(j + 1, n):
            s = ca.SX(0)
            for k in range(j, i):
                s = s - L[i, k] * X[k][j]
            X[i][j] = s / L[i, i]
    return ca.blockcat(X)


def sx_spd_inverse(A: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Inverse of a symmetric positive definite matrix by Cholesky, with pivots.

    Parameters
    ----------
    A : casadi.SX
        A symmetric positive definite matrix.

    Returns
    -------
    inverse : casadi.SX
    pivots : casadi.SX
        Cholesky pivots of ``A`` (see `sx_cholesky`).
    """
    if A.shape == (1, 1):
        return 1 / A, A
    L, piv = sx_cholesky(A)
    Li = _sx_lower_inverse(L)
    return Li.T @ Li, piv


def _mmin(v: ca.SX) -> ca.SX:
    out = v[0]
    for i in range(1, v.numel()):
        out = ca.fmin(out, v[i])
    return out


def cache_dir() -> Path:
    """Directory of the compiled kernels (see the module notes; not created here).

    Returns
    -------
    pathlib.Path
        ``$TANKSYNTH_CACHE``, else ``$XDG_CACHE_HOME/tanksynth/kernels``, else
        ``~/.cache/tanksynth/kernels``.
    """
    if os.environ.get("TANKSYNTH_CACHE"):
        return Path(os.environ["TANKSYNTH_CACHE"])
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "tanksynth" / "kernels"


_NATIVE_FLAGS = ("-O2", "-fPIC", "-shared", "-ffp-contract=off", "-fno-math-errno")
_NATIVE_CACHE: dict[str, ca.Function] = {}


def _compiler() -> str | None:
    return shutil.which("gcc") or shutil.which("cc")


def _native(fn: ca.Function) -> ca.Function | None:
    """Compile an SX function to a shared library (cached by source hash) and load it."""
    cc = _compiler()
    if cc is None:
        return None
    gen = ca.CodeGenerator("tk_kernel.c", {"with_header": False})
    gen.add(fn)
    code = gen.dump()
    digest = hashlib.sha256((code + " ".join(_NATIVE_FLAGS) + ca.__version__).encode()).hexdigest()
    if digest in _NATIVE_CACHE:
        return _NATIVE_CACHE[digest]
    name = f"tk_{digest[:20]}"
    try:
        directory = cache_dir()
        directory.mkdir(parents=True, exist_ok=True)
        so_path = directory / f"{name}.so"
        if not so_path.exists():
            renamed = ca.Function(name, fn.sx_in(), fn.call(fn.sx_in()), fn.name_in(),
                                  fn.name_out())
            gen = ca.CodeGenerator(f"{name}.c", {"with_header": False})
            gen.add(renamed)
            with tempfile.TemporaryDirectory(dir=directory) as tmp:
                src = Path(tmp) / f"{name}.c"
                src.write_text(gen.dump())
                out = Path(tmp) / f"{name}.so"
                subprocess.run([cc, *_NATIVE_FLAGS, str(src), "-o", str(out), "-lm"], check=True,
                               capture_output=True, timeout=300)
                os.replace(out, so_path)
        loaded = ca.external(name, str(so_path))
    except (OSError, subprocess.SubprocessError, RuntimeError):
        return None
    _NATIVE_CACHE[digest] = loaded
    return loaded


def clear_cache(disk: bool = False) -> dict[str, int]:
    """Forget the loaded native kernels; with ``disk``, delete the compiled libraries too.

    Estimators built before keep the kernel they hold; new ones compile (or
    load from disk) again.

    Parameters
    ----------
    disk : bool
        Also delete the ``tk_*.so`` libraries of `cache_dir` (other files
        there are left alone).

    Returns
    -------
    dict
        ``loaded``: kernels forgotten; ``files``: libraries deleted.
    """
    loaded = len(_NATIVE_CACHE)
    _NATIVE_CACHE.clear()
    files = 0
    if disk:
        directory = cache_dir()
        for path in directory.glob("tk_*.so") if directory.is_dir() else ():
            path.unlink(missing_ok=True)
            files += 1
    return {"loaded": loaded, "files": files}


def cache_info() -> dict[str, object]:
    """``loaded`` (native kernels in memory), ``files`` (libraries on disk), ``directory``."""
    directory = cache_dir()
    files = len(list(directory.glob("tk_*.so"))) if directory.is_dir() else 0
    return {"loaded": len(_NATIVE_CACHE), "files": files, "directory": str(directory)}
