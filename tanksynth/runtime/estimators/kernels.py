"""CasADi building blocks of the estimator kernels, and their native compilation.

SX helpers (symmetrisation, Cholesky with pivots, SPD inverse, smallest
entry) used to write every step of a `KernelEstimator` as one SX function;
`native_function` compiles such a function to a shared library and loads it
(``casadi.external``), or gives None (the caller evaluates the SX function in
CasADi's virtual machine).

Compiler, flags and cache: the one native-compile cache of tanksynth
(`tanksynth.native_cache`: ``$TANKSYNTH_CC``, else ``gcc``/``cc``; the same
flags as the simulator's kernels; locked, atomic builds; failures remembered).
The estimator kernels are its family ``kernels``: ``tk_*.so`` files in
``$TANKSYNTH_CACHE`` if set, else ``$TANKSYNTH_CACHE_DIR/kernels``, else
``$XDG_CACHE_HOME/tanksynth/kernels``, else ``~/.cache/tanksynth/kernels``
(`cache_dir`), named by the SHA-256 of their generated C source, the CasADi
version, the compiler path and its flags, so a library is never used for
another kernel; the loaded ones are also kept in memory. `clear_cache` (and
``tanksynth.runtime.clear_cache``) forgets the loaded ones and, on request,
deletes the files.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import casadi as ca

from tanksynth.native_cache import NativeBuildError, NativeCache, find_compiler

__all__ = ["sx_symmetrize", "sx_cholesky", "sx_spd_inverse", "sx_min", "native_function",
           "cache_dir", "clear_cache", "cache_info"]


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


def sx_min(v: ca.SX) -> ca.SX:
    """Smallest entry of a vector (a chain of ``fmin``; the pivots a kernel checks).

    Parameters
    ----------
    v : casadi.SX, shape (k, 1)
        A non-empty vector.
    """
    out = v[0]
    for i in range(1, v.numel()):
        out = ca.fmin(out, v[i])
    return out


#: The estimator kernels' family of the native-compile cache.
_CACHE = NativeCache("kernels", "tk_", directory_env="TANKSYNTH_CACHE")


def cache_dir() -> Path:
    """Directory of the compiled kernels (see the module notes; not created here).

    Returns
    -------
    pathlib.Path
        ``$TANKSYNTH_CACHE``, else ``$TANKSYNTH_CACHE_DIR/kernels``, else
        ``$XDG_CACHE_HOME/tanksynth/kernels``, else ``~/.cache/tanksynth/kernels``.
    """
    return _CACHE.directory()


def _c_source(fn: ca.Function, name: str) -> str:
    """C source of ``fn`` renamed ``name`` (the symbol `casadi.external` looks up).

    An SX function is renamed on SX symbols; any other (an MX function calling others, a
    horizon kernel) on MX symbols, so that its calls stay calls (no expansion to SX).
    """
    args: Any = fn.sx_in() if fn.is_a("SXFunction") else fn.mx_in()
    renamed = ca.Function(name, args, fn.call(args), fn.name_in(), fn.name_out())
    gen = ca.CodeGenerator(f"{name}.c", {"with_header": False})
    gen.add(renamed)
    return gen.dump()


def native_function(fn: ca.Function, build: bool = True) -> ca.Function | None:
    """``fn`` compiled to native code (built once, cached on disk and in memory) and loaded.

    Parameters
    ----------
    fn : casadi.Function
        An SX function (a kernel's step) or an MX function of such calls (a horizon kernel,
        `tanksynth.runtime.estimators.horizon`).
    build : bool
        Compile when the library is neither loaded nor on disk (else give None then).

    Returns
    -------
    casadi.Function or None
        The loaded library's function (same inputs and outputs, the same numbers);
        None when no C compiler is found, the build or load fails, or (``build`` False)
        the library was never built.
    """
    cc = find_compiler()
    if cc is None:
        return None
    gen = ca.CodeGenerator("tk_kernel.c", {"with_header": False})
    gen.add(fn)
    try:
        # casadi's type stubs omit __version__ (the package sets it at import)
        version = ca.__version__  # type: ignore[attr-defined]
        lib = _CACHE.library([gen.dump(), version], lambda name: _c_source(fn, name),
                             lambda path, name: ca.external(name, str(path)), cc, build)
    except NativeBuildError:
        return None
    return None if lib is None else lib.handle   # (None only for build=False)


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
    return _CACHE.clear(disk)


def cache_info() -> dict[str, object]:
    """``loaded`` (native kernels in memory), ``files`` (libraries on disk), ``directory``."""
    info = _CACHE.info()
    return {"loaded": info["loaded"], "files": info["files"], "directory": info["directory"]}
