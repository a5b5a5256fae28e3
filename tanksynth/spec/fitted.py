"""``fitted.toml``: a spec's text with its free parameters replaced by their fitted values.

`fitted_spec_text` edits the TOML text line by line and keeps everything else as written
(comments, order, layout): each free parameter's table (``mu13 = {value = 0.5, min = 0.2, max =
0.9, fit = true}``, or a ``[plant.parameters.mu13]`` table) becomes its fitted value as a plain
number, with a comment giving its interval; the ``[[design]]`` tables of method ``fit`` are
removed (their result is the fit file); a design with ``uncertain = "fit"`` gets ``fit = "<fit
file>"`` (relative to the fitted spec, which lies beside the fit file).
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass
from typing import Mapping

from tanksynth.errors import SpecError

__all__ = ["FittedValue", "fitted_spec_text"]

_HEADER = re.compile(r"^\s*(\[\[?)\s*([^\]]+?)\s*(\]\]?)\s*(#.*)?$")


@dataclass(frozen=True)
class FittedValue:
    """A fitted parameter as ``fitted.toml`` writes it.

    Attributes
    ----------
    value : float
        The fitted value (the parameter's unit).
    lower, upper : float
        Its interval (the parameter's unit).
    level : float
        The interval's confidence level, in (0, 1) (dimensionless).
    unit : str
        The parameter's unit.
    determined : bool
        False for a parameter the data do not determine: ``value`` is then its start value,
        kept, and ``lower``, ``upper`` its search box.
    """

    value: float
    lower: float
    upper: float
    level: float
    unit: str = ""
    determined: bool = True

    def line(self, name: str, indent: str = "") -> str:
        """``name = value  # fitted: 95 % interval [lo, hi] unit``.

        Parameters
        ----------
        name : str
            The parameter's key as written in the spec.
        indent : str
            Leading whitespace.
        """
        unit = f" {self.unit}" if self.unit not in ("", "-", "1") else ""
        if not self.determined:
            return (f"{indent}{name} = {self.value!r}  # not determined by the data: start value kept "
                    f"(search box [{self.lower:.6g}, {self.upper:.6g}]{unit})")
        return (f"{indent}{name} = {self.value!r}  # fitted: {100 * self.level:g} % interval "
                f"[{self.lower:.6g}, {self.upper:.6g}]{unit}")


def _key_name(raw: str) -> str:
    raw = raw.strip()
    return raw[1:-1] if len(raw) >= 2 and raw[0] == raw[-1] and raw[0] in "\"'" else raw


def _blocks(lines: list[str]) -> list[tuple[str, bool, int, int]]:
    """(table name, is array table, first line, end line) of every table header, in order."""
    heads = []
    for i, line in enumerate(lines):
        m = _HEADER.match(line)
        if m and not line.lstrip().startswith("#"):
            heads.append((".".join(_key_name(p) for p in m.group(2).split(".")),
                          m.group(1) == "[[", i))
    out = []
    for k, (name, array, i) in enumerate(heads):
        out.append((name, array, i, heads[k + 1][2] if k + 1 < len(heads) else len(lines)))
    return out


def fitted_spec_text(text: str, fitted: Mapping[str, FittedValue], fit_file: str) -> str:
    """The spec text with the fitted values, ready for ``tanksynth run``.

    Parameters
    ----------
    text : str
        The spec as written (TOML).
    fitted : mapping of str to FittedValue
        Free parameter name -> its fitted value and interval.
    fit_file : str
        The fit file's path relative to the fitted spec (``"fit.json"``).

    Returns
    -------
    str
        TOML text; parses with `tomllib` to the same tables except the edited ones.

    Raises
    ------
    SpecError
        A free parameter written in a form this editor does not rewrite (it must be an inline
        table in ``[plant.parameters]`` or a ``[plant.parameters.<name>]`` table), or the result
        does not parse.
    """
    lines = text.splitlines()
    done: set[str] = set()
    drop: set[int] = set()
    insert: dict[int, list[str]] = {}
    replace: dict[int, str] = {}
    blocks = _blocks(lines)
    parent_lines: list[str] | None = None  # the [plant.parameters] inserted for sub-tables
    for name, array, start, end in blocks:
        if name == "plant.parameters" and not array:
            for i in range(start + 1, end):
                m = re.match(r"^(\s*)(\"[^\"]+\"|'[^']+'|[A-Za-z0-9_-]+)\s*=\s*\{.*\}\s*(#.*)?$", lines[i])
                if m and _key_name(m.group(2)) in fitted:
                    nm = _key_name(m.group(2))
                    replace[i] = fitted[nm].line(m.group(2), m.group(1))
                    done.add(nm)
        elif name.startswith("plant.parameters.") and not array and name[17:] in fitted:
            nm = name[17:]
            drop.update(range(start, end))
            parent = [b for b in blocks if b[0] == "plant.parameters" and not b[1]]
            line = fitted[nm].line(nm)
            if parent:
                insert.setdefault(parent[0][3], []).append(line)
            elif parent_lines is None:  # one [plant.parameters] for every fitted sub-table
                parent_lines = insert.setdefault(start, [])
                parent_lines.extend(["[plant.parameters]", line, ""])
            else:
                parent_lines.insert(len(parent_lines) - 1, line)
            done.add(nm)
        elif name == "design" and array:
            body = "\n".join(lines[start + 1:end])
            try:
                table = tomllib.loads(body)
            except tomllib.TOMLDecodeError:
                table = {}
            if table.get("method") == "fit":
                drop.update(range(start, end))
                insert.setdefault(start, []).append(
                    f"# [[design]] {table.get('name', '')!s} (method fit): fitted, see {fit_file}")
            elif table.get("uncertain") == "fit":
                found = False
                for i in range(start + 1, end):
                    if re.match(r"^\s*fit\s*=", lines[i]):
                        replace[i] = f'fit = "{fit_file}"'
                        found = True
                if not found:
                    insert.setdefault(start + 1, []).append(f'fit = "{fit_file}"')
    missing = [nm for nm in fitted if nm not in done]
    if missing:
        raise SpecError(f"cannot write the fitted value of {missing[0]!r} into the spec text: write "
                        f"it as {missing[0]} = {{value = ..., min = ..., max = ..., fit = true}} in "
                        "[plant.parameters]", key=f"plant.parameters.{missing[0]}")
    out: list[str] = []
    for i in range(len(lines) + 1):
        out.extend(insert.get(i, []))
        if i < len(lines) and i not in drop:
            out.append(replace.get(i, lines[i]))
    # the original's comments are kept below: say first what this file is and what changed
    header = (f"# Written by tanksynth fit: the spec below with each free parameter replaced by its "
              f"fitted value ({fit_file});\n# the comments are the original spec's (its start values "
              "and search boxes are gone).\n")
    result = header + "\n".join(out) + "\n"
    try:
        tomllib.loads(result)
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(f"the fitted spec text does not parse ({exc}); edit the spec by hand",
                        key="plant.parameters") from None
    return result


