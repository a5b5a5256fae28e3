"""What the option readers know of the spec being parsed: its file's directory (files a spec
names are relative to it) and its free parameters.

A ``[[design]]`` option may name a file (``data = ["logs/run1.csv"]`` of ``fit``, ``fit =
"out/fit"`` of a robust design with ``uncertain = "fit"``). Such a path is relative to the
directory of the spec FILE that names it. While `tanksynth.spec.load_spec` reads a spec file,
`spec_directory` gives that directory, and the option readers check that the files exist.

A spec parsed from text (`tanksynth.spec.parse_spec_text`, e.g. the copy ``DIR/spec.toml`` of a
result directory that ``verify`` and ``report`` read) has no directory: the files are not read
again then; the artefacts hold what was read (the fit's data copied into ``DIR/data/`` with
their sha256, a robust design's box with the fit file's sha256).
"""

from __future__ import annotations

from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path
from typing import Any, Iterator

from tanksynth.errors import SpecError

__all__ = ["spec_directory", "reading_spec_file", "parse_path", "parse_paths", "resolve",
           "free_parameter_scope", "free_parameters_in_scope"]

_DIRECTORY: ContextVar[Path | None] = ContextVar("tanksynth_spec_directory", default=None)
_FREE: ContextVar[tuple[str, ...] | None] = ContextVar("tanksynth_spec_free", default=None)
#: Longest path a spec may write (characters).
_MAX_PATH = 4096
#: Most files one option may list.
_MAX_FILES = 256


def spec_directory() -> Path | None:
    """The directory of the spec file being read, or None (a spec parsed from text).

    Returns
    -------
    Path or None
    """
    return _DIRECTORY.get()


@contextmanager
def reading_spec_file(path: str | Path) -> Iterator[Path]:
    """Within it, `spec_directory` is the directory of ``path`` (the spec file being read).

    Parameters
    ----------
    path : str or Path
        The spec file.

    Yields
    ------
    Path
        That directory.
    """
    directory = Path(path).parent
    token = _DIRECTORY.set(directory)
    try:
        yield directory
    finally:
        _DIRECTORY.reset(token)


@contextmanager
def free_parameter_scope(names: Any) -> Iterator[None]:
    """Within it, `free_parameters_in_scope` gives ``names`` (the spec parser sets it while it
    validates the ``[[design]]`` tables, so that ``fit`` refuses a plant without a free one).

    Parameters
    ----------
    names : iterable of str
        The spec's free parameter names.

    Yields
    ------
    None
    """
    token = _FREE.set(tuple(str(n) for n in names))
    try:
        yield
    finally:
        _FREE.reset(token)


def free_parameters_in_scope() -> tuple[str, ...] | None:
    """The free parameter names of the spec being parsed; None outside the spec parser.

    Returns
    -------
    tuple of str or None
    """
    return _FREE.get()


def resolve(path: str | Path, base: str | Path | None = None) -> Path:
    """``path`` relative to ``base`` (default `spec_directory`, else the working directory).

    Parameters
    ----------
    path : str or Path
        As written in the spec (absolute, or relative to the spec file).
    base : str or Path, optional
        The directory a relative path is relative to.

    Returns
    -------
    Path
    """
    p = Path(path).expanduser()
    if p.is_absolute():
        return p
    root = Path(base) if base is not None else spec_directory()
    return p if root is None else root / p


def parse_path(value: Any, key: str, *, what: str = "file", directory: bool = False) -> str:
    """One path of a spec option, as written; checked to exist when a spec file is being read.

    Parameters
    ----------
    value : str
        The path (relative to the spec file, or absolute).
    key : str
        Spec key, for messages.
    what : str
        What the file is, for messages (``"data file"``).
    directory : bool
        A directory is accepted too.

    Returns
    -------
    str
        The path as written.

    Raises
    ------
    SpecError
        Not a non-empty string, or (reading a spec file) no such regular file.
    """
    if not isinstance(value, str) or not value.strip() or len(value) > _MAX_PATH or "\x00" in value:
        raise SpecError(f"expected a {what} path (a non-empty string, relative to the spec file), "
                        f"got {value!r}"[:200], key=key)
    if spec_directory() is not None:
        full = resolve(value)
        ok = full.is_file() or (directory and full.is_dir())
        if not ok:
            state = "is not a regular file" if full.exists() else "does not exist"
            raise SpecError(f"{what} {value!r} {state} ({full}; paths are relative to the spec "
                            "file)", key=key)
    return value


def parse_paths(value: Any, key: str, *, what: str = "file") -> tuple[str, ...]:
    """A list of paths of a spec option (one string is one path); see `parse_path`.

    Parameters
    ----------
    value : str or list of str
        The paths.
    key : str
        Spec key, for messages (each entry is named ``key[i]``).
    what : str
        What the files are, for messages.

    Returns
    -------
    tuple of str
        The paths as written, in order, without repeats.
    """
    items = [value] if isinstance(value, str) else value
    if not isinstance(items, (list, tuple)):
        raise SpecError(f"expected a list of {what} paths, got {type(value).__name__}", key=key)
    if len(items) > _MAX_FILES:
        raise SpecError(f"at most {_MAX_FILES} {what}s, got {len(items)}", key=key)
    out = [parse_path(item, f"{key}[{i}]", what=what) for i, item in enumerate(items)]
    return tuple(dict.fromkeys(out))
