"""Documentation generated from the code: the method catalogue and the plant families.

Everything here is read from the method table (`tanksynth.methods.TABLE`: each
row's kinds, summary and Options dataclass, whose fields declare defaults and
units and whose docstring says what each option means) and from the plant
builders (`tanksynth.plants.BUILTIN_PLANTS`: signature and numpydoc
``Parameters``). The same text feeds ``tanksynth methods``, ``tanksynth
plants``, the README's generated sections and the Sphinx pages.

Run ``python -m tanksynth.docgen`` to rewrite the README's generated sections
(``--check`` exits 1 when they are stale instead).
"""

from __future__ import annotations

import inspect
import re
import sys
from pathlib import Path
from typing import Any, Callable, Sequence

from tanksynth.errors import SpecError
from tanksynth.spec.method_options.base import numpydoc_section

__all__ = ["method_catalogue", "method_options", "methods_markdown", "method_markdown", "option_cells",
           "plant_families", "plants_markdown", "plant_markdown", "custom_plant_markdown",
           "gain_names_markdown", "GENERATED_SECTIONS", "DOC_PAGES", "generated_section", "update_readme",
           "write_pages", "main"]


def method_catalogue() -> list[dict[str, Any]]:
    """Every design method: name, kinds, summary and option names, in table order.

    Returns
    -------
    list of dict
        ``{"name", "kinds", "summary", "options"}`` per method.
    """
    from tanksynth.methods import TABLE

    return [{"name": row.name, "kinds": list(row.kinds), "summary": row.summary,
             "options": list(row.options.option_names())} for row in TABLE]


def method_options(name: str) -> list[dict[str, Any]]:
    """Each option of method ``name``: type, default, unit and meaning.

    Parameters
    ----------
    name : str
        A method of `tanksynth.methods.TABLE`.

    Returns
    -------
    list of dict
        `tanksynth.spec.method_options.base.OptionDoc.as_dict` of every option.

    Raises
    ------
    SpecError
        Unknown method (listing the known ones).
    """
    from tanksynth.methods import method

    return [d.as_dict() for d in method(name).options.describe()]


def option_cells(doc: dict[str, Any]) -> tuple[str, str]:
    """The type and default texts of one option of the catalogue (README, ``tanksynth methods``).

    The type lists every allowed value of a choice option (``str: "auto" | "lmi"``);
    the default says what a None or computed default IS (``computed: ...``).

    Parameters
    ----------
    doc : dict
        One entry of `method_options`.

    Returns
    -------
    (str, str)
        The type text and the default text (``"required"`` for a required option).
    """
    typ = doc["type"].replace("``", "")
    if doc["choices"]:
        typ += (": " if typ.startswith("str") else " or ") + " | ".join(doc["choices"])
    if doc["required"]:
        return typ, "required"
    default = doc["default"]
    if doc["default_text"]:
        text = doc["default_text"].replace("``", "")
        default = text if default == "None" else f"{default} ({text})"
    return typ, default


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _table(header: tuple[str, ...], rows: Sequence[tuple[str, ...]]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in rows]
    return out


def method_markdown(name: str, level: int = 3) -> str:
    """The Markdown of one method: heading, kinds, summary and its options table.

    Parameters
    ----------
    name : str
        A method of the table.
    level : int
        Heading level (number of ``#``).

    Returns
    -------
    str
    """
    from tanksynth.methods import method

    row = method(name)
    lines = [f"{'#' * level} `{row.name}`", "",
             f"*{' or '.join(row.kinds)}*: {row.summary}.", ""]
    docs = row.options.describe()
    if not docs:
        lines += ["No options.", ""]
    else:
        rows = []
        for d in docs:
            typ, default = option_cells(d.as_dict())
            if d.required:
                default = "**required**"
            elif not d.default_text:
                default = f"`{default}`"
            rows.append((f"`{d.name}`", typ, default, d.unit, d.meaning))
        lines += _table(("option", "type", "default", "unit", "meaning"), rows)
        lines.append("")
    return "\n".join(lines)


def methods_markdown(level: int = 3) -> str:
    """The Markdown catalogue of every method (an index table, then one section each).

    Parameters
    ----------
    level : int
        Heading level of each method's section.

    Returns
    -------
    str
    """
    from tanksynth.methods import ALIASES

    cat = method_catalogue()
    lines = _table(("method", "kind", "designs"),
                   [(f"`{m['name']}`", " / ".join(m["kinds"]), m["summary"]) for m in cat])
    lines += ["", "Aliases: a spec may name these instead (the artefact records the method it ran "
                  "and the alias, `diagnostics.method_alias`).", ""]
    lines += _table(("alias", "runs"), [(f"`{a.name}`", a.describe()) for a in ALIASES.values()])
    lines.append("")
    body = "\n".join(lines) + "\n" + "\n".join(method_markdown(m["name"], level) for m in cat)
    return body.rstrip("\n") + "\n"


def plant_families() -> list[dict[str, Any]]:
    """Each built-in plant family: description, options, signals (default options).

    Returns
    -------
    list of dict
        ``{"name", "description", "options": [{"name", "type", "default",
        "meaning"}], "states", "inputs", "outputs", "parameters"}`` per family,
        the signals and parameters of the family built with its defaults.
    """
    from tanksynth.plants import BUILTIN_PLANTS

    out = []
    for name, builder in BUILTIN_PLANTS.items():
        documented = numpydoc_section(builder.__doc__, "Parameters")
        options = []
        for p in inspect.signature(builder).parameters.values():
            typ, text = documented.get(p.name, ("", ""))
            options.append({"name": p.name, "type": typ, "default": repr(p.default), "meaning": text})
        summary = builder().summary()
        out.append({"name": name, "description": summary["description"], "options": options,
                    **{k: summary[k] for k in ("states", "inputs", "outputs", "parameters")}})
    return out


def _signals(family: dict[str, Any]) -> str:
    return "; ".join(f"{what}: " + ", ".join(f"`{v['name']}` [{v['unit']}]" for v in family[what])
                     for what in ("states", "inputs", "outputs"))


def plant_markdown(family: dict[str, Any], level: int = 3) -> str:
    """The Markdown of one plant family (from `plant_families`).

    Parameters
    ----------
    family : dict
        One entry of `plant_families`.
    level : int
        Heading level.

    Returns
    -------
    str
    """
    lines = [f"{'#' * level} `model = \"{family['name']}\"`", "", family["description"] + ".", ""]
    if family["options"]:
        lines += _table(("option", "type", "default", "meaning"),
                        [(f"`{o['name']}`", o["type"], f"`{o['default']}`", o["meaning"])
                         for o in family["options"]])
    else:
        lines.append("No options.")
    lines += ["", "With the defaults: " + _signals(family) + ". Parameters (override under "
              "`[plant.parameters]`): " + ", ".join(f"`{p['name']}` [{p['unit']}]"
                                                   for p in family["parameters"]) + ".", ""]
    return "\n".join(lines)


def custom_plant_markdown(level: int = 3) -> str:
    """How to write a ``custom`` plant: its keys and an example (from `tanksynth.plants.custom`).

    Parameters
    ----------
    level : int
        Heading level.

    Returns
    -------
    str
    """
    from tanksynth.plants import custom

    keys = numpydoc_section(custom.custom_plant.__doc__, "Parameters")["spec"][1]
    example = (inspect.getdoc(custom) or "").split("Example::", 1)[1].split("\n\n")[1]
    example = inspect.cleandoc(example)
    return "\n".join([
        f"{'#' * level} `model = \"custom\"`", "",
        "A plant written in the spec as equations, " + keys[0].lower() + keys[1:].rstrip(".") + ". "
        "States are tables `{unit, min, max, description}` (min/max: the operating region), inputs "
        "`{unit, min, max}`, parameters `{value, unit, min, max}`, one equation `dx/dt` per "
        "state and each output an expression (or `{expr, unit}`). Equations are read by a "
        "whitelist parser (numbers, declared names, `+ - * / **`, `sqrt abs sign exp log min "
        "max`, parentheses); nothing is evaluated as Python.", "",
        "```toml", example, "```", ""])


def plants_markdown(level: int = 3) -> str:
    """The Markdown of every plant family and of the ``custom`` plant.

    Parameters
    ----------
    level : int
        Heading level of each family.

    Returns
    -------
    str
    """
    parts = [plant_markdown(f, level) for f in plant_families()] + [custom_plant_markdown(level)]
    return "\n".join(parts).rstrip("\n") + "\n"


def gain_names_markdown() -> str:
    """The README's gain-naming table, from `tanksynth.analysis.statespace.GAIN_NAMES`.

    Returns
    -------
    str
        A Markdown table (name(s), meaning), one row per entry.
    """
    from tanksynth.analysis.statespace import GAIN_NAMES

    rows = [(", ".join(f"`{n}`" for n in names), meaning) for names, meaning in GAIN_NAMES.items()]
    return "\n".join(_table(("Name", "Meaning"), rows)) + "\n"


#: The README's generated sections: marker name -> text.
GENERATED_SECTIONS: dict[str, Callable[[], str]] = {"plants": plants_markdown,
                                                    "methods": methods_markdown,
                                                    "gain_names": gain_names_markdown}


def _markers(name: str) -> tuple[str, str]:
    return (f"<!-- BEGIN GENERATED {name} (python -m tanksynth.docgen) -->",
            f"<!-- END GENERATED {name} -->")


def generated_section(text: str, name: str) -> str:
    """The text between the markers of section ``name`` in ``text`` (a README).

    Parameters
    ----------
    text : str
        The README.
    name : str
        A key of `GENERATED_SECTIONS`.

    Returns
    -------
    str

    Raises
    ------
    SpecError
        The markers are missing.
    """
    begin, end = _markers(name)
    match = re.search(re.escape(begin) + r"\n(.*?)" + re.escape(end), text, re.S)
    if not match:
        raise SpecError(f"no generated section {name!r}: expected the lines {begin!r} ... {end!r}")
    return match.group(1)


#: Pages of the documentation source (relative to the repository root) holding generated
#: sections, and which: `main` rewrites them with the README.
DOC_PAGES: dict[str, tuple[str, ...]] = {"docs/gain_names.md": ("gain_names",)}


def update_readme(path: str | Path, check: bool = False,
                  sections: Sequence[str] | None = None) -> list[str]:
    """Rewrite the generated sections of a README (or, with ``check``, only compare).

    Parameters
    ----------
    path : str or Path
        The README (or a page of `DOC_PAGES`).
    check : bool
        Do not write; only report what differs.
    sections : sequence of str, optional
        The sections the file holds (default every one of `GENERATED_SECTIONS`).

    Returns
    -------
    list of str
        The sections that were stale (rewritten unless ``check``).
    """
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    stale = []
    for name in GENERATED_SECTIONS if sections is None else sections:
        make = GENERATED_SECTIONS[name]
        current, wanted = generated_section(text, name), make()
        if current != wanted:
            stale.append(name)
            begin, end = _markers(name)
            text = text.replace(f"{begin}\n{current}{end}", f"{begin}\n{wanted}{end}")
    if stale and not check:
        path.write_text(text, encoding="utf-8")
    return stale


def write_pages(directory: str | Path) -> list[Path]:
    """Write one Markdown page per method and per plant family (for Sphinx, MyST).

    Parameters
    ----------
    directory : str or Path
        Gets ``methods/<name>.md``, ``plants/<name>.md`` and the two index pages
        ``methods/index.md`` and ``plants/index.md``.

    Returns
    -------
    list of Path
        The pages written.
    """
    directory = Path(directory)
    written = []

    def page(path: Path, text: str) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.is_file() or path.read_text(encoding="utf-8") != text:
            path.write_text(text, encoding="utf-8")
        written.append(path)

    cat = method_catalogue()
    for m in cat:
        page(directory / "methods" / f"{m['name']}.md", method_markdown(m["name"], level=1))
    index = ["# Design methods", "", "Generated from the method table `tanksynth.methods.TABLE`; "
             "`tanksynth methods NAME` prints the same.", "",
             *_table(("method", "kind", "designs"),
                     [(f"[`{m['name']}`]({m['name']}.md)", " / ".join(m["kinds"]), m["summary"])
                      for m in cat]),
             "", "```{toctree}", ":hidden:", "", *(m["name"] for m in cat), "```", ""]
    page(directory / "methods" / "index.md", "\n".join(index))
    families = plant_families()
    for f in families:
        page(directory / "plants" / f"{f['name']}.md", plant_markdown(f, level=1))
    page(directory / "plants" / "custom.md", custom_plant_markdown(level=1))
    names = [f["name"] for f in families] + ["custom"]
    index = ["# Plant families", "", "`tanksynth plants` prints the same, with every parameter "
             "value.", "", *(f"- [`{n}`]({n}.md)" for n in names), "",
             "```{toctree}", ":hidden:", "", *names, "```", ""]
    page(directory / "plants" / "index.md", "\n".join(index))
    return written


def main(argv: list[str] | None = None) -> int:
    """``python -m tanksynth.docgen [--check] [README]``: rewrite (or check) the README and, without
    a README argument, the pages of `DOC_PAGES` (run from the repository root).

    Parameters
    ----------
    argv : list of str, optional
        Arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        0 when up to date (or rewritten), 1 with ``--check`` when stale.
    """
    args = list(sys.argv[1:] if argv is None else argv)
    check = "--check" in args
    paths = [a for a in args if a != "--check"]
    files: list[tuple[str, Sequence[str] | None]] = [(paths[0], None)] if paths else [
        ("README.md", None), *((page, names) for page, names in DOC_PAGES.items() if Path(page).is_file())]
    any_stale = False
    for path, sections in files:
        stale = update_readme(path, check=check, sections=sections)
        any_stale = any_stale or bool(stale)
        for name in stale:
            sys.stdout.write(f"{path}: section {name!r} {'is stale' if check else 'rewritten'}\n")
    return 1 if check and any_stale else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
