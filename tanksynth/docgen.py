"""Documentation generated from the code: the method catalogue and the plant families.

Everything here is read from the method table (`tanksynth.methods.TABLE`: each
row's kinds, summary and Options dataclass, whose fields declare defaults and
units and whose docstring says what each option means) and from the plant
builders (`tanksynth.plants.BUILTIN_PLANTS`: signature and numpydoc
``Parameters``). The same text feeds ``tanksynth methods``, ``tanksynth
plants``, the generated sections of the documentation pages (`DOC_PAGES`: the one-page
method and plant catalogues, the gain-name table) and the Sphinx pages.

Run ``python -m tanksynth.docgen`` to rewrite the generated sections of `DOC_PAGES`
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
           "toml_type", "toml_literal", "toml_example", "python_example", "python_design_call", "api_reference_markdown",
           "plant_families", "plants_markdown", "plain_text", "plant_variants_markdown", "plant_markdown", "custom_plant_markdown",
           "gain_names_markdown", "GENERATED_SECTIONS", "DOC_PAGES", "generated_section", "update_readme",
           "API_SECTIONS", "write_pages", "main"]


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


#: TOML words of the Python type names of the options' docstrings (singular, plural).
_TOML_WORDS: dict[str, tuple[str, str]] = {
    "bool": ("boolean", "booleans"), "int": ("integer", "integers"), "float": ("number", "numbers"),
    "str": ("string", "strings"), "complex": ("number or [re, im] array", "numbers or [re, im] arrays"),
    "mapping": ("table", "tables"), "tuple": ("array", "arrays"),
    "ndarray": ("array of numbers or array of arrays of numbers (a matrix)",
                "arrays of numbers or matrices (arrays of arrays of numbers)"),
}


def _split_top(text: str, separator: str) -> list[str]:
    """``text`` split at ``separator`` outside parentheses and braces."""
    parts, depth, start, i = [], 0, 0, 0
    while i < len(text):
        if text[i] in "({[":
            depth += 1
        elif text[i] in ")}]":
            depth -= 1
        elif depth == 0 and text.startswith(separator, i):
            parts.append(text[start:i])
            start = i = i + len(separator)
            continue
        i += 1
    return parts + [text[start:]]


def _toml_term(term: str, plural: bool = False) -> str:
    """One alternative of a numpydoc type (``tuple of float``) in TOML words."""
    term = term.strip()
    if term.startswith("(") and term.endswith(")"):   # a fixed-length tuple: an array [a, b]
        inner = ", ".join(_toml_term(t) for t in _split_top(term[1:-1], ","))
        return f"[{inner}] array" + ("s" if plural else "")
    for outer, word in (("tuple of ", "array"), ("mapping of str to ", "table")):
        if term.startswith(outer):
            return f"{word}{'s' if plural else ''} of {_toml_term(term[len(outer):], plural=True)}"
    if term.startswith("table"):   # already a TOML word (``table {values, domain}``)
        return term
    words = _TOML_WORDS.get(term)
    return term if words is None else words[plural]


def toml_type(typ: str, choices: Sequence[str] = ()) -> str:
    """A Python type text of an option's docstring as a TOML user writes the value.

    ``tuple of float`` is ``array of numbers``, ``tuple of (str, float, float)``
    ``array of [string, number, number] arrays``, ``mapping of str to float`` ``table of
    numbers``, a choice ``string, one of "a", "b"``; ``None`` (omit the key: the default
    column says what then) is left out.

    Parameters
    ----------
    typ : str
        The numpydoc type (``tuple of complex, or table {values, domain}``).
    choices : sequence of str
        The allowed values of a choice option, as TOML literals (``'"auto"'``).

    Returns
    -------
    str
    """
    alternatives = [t for part in _split_top(typ, ", or ") for t in _split_top(part, " or ")
                    if t.strip() != "None"]
    words = [_toml_term(t) for t in alternatives]
    if choices:
        one_of = "one of " + ", ".join(choices)
        if words == ["string"]:
            return f"string, {one_of}"
        words.append(f"string, {one_of}")
    return " or ".join(dict.fromkeys(words))



def toml_literal(text: str) -> str:
    """A Python literal of a default (``'observer'``, ``False``, ``(30, 150)``) as TOML writes it
    (``"observer"``, ``false``, ``[30, 150]``); any other text as it is.

    Parameters
    ----------
    text : str
        The ``repr`` of a default value.

    Returns
    -------
    str
    """
    import ast
    import json

    def render(value: Any) -> str:
        if isinstance(value, bool):
            return "true" if value else "false"
        if isinstance(value, str):
            return json.dumps(value)
        if isinstance(value, (int, float)):
            return repr(value)
        if isinstance(value, (tuple, list)):
            return "[" + ", ".join(render(v) for v in value) + "]"
        if isinstance(value, dict):
            return "{" + ", ".join(f"{k} = {render(v)}" for k, v in value.items()) + "}"
        raise ValueError(value)

    try:
        return render(ast.literal_eval(text))
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
        return text


def option_cells(doc: dict[str, Any]) -> tuple[str, str]:
    """The type and default texts of one option of the catalogue (catalogue pages, ``tanksynth methods``).

    The type is written as a TOML user writes the value (`toml_type`: ``string, one of "auto",
    "lmi"``, ``array of numbers``); the default says what a None or computed default IS (``computed: ...``).

    Parameters
    ----------
    doc : dict
        One entry of `method_options`.

    Returns
    -------
    (str, str)
        The type text and the default text (``"required"`` for a required option).
    """
    typ = toml_type(doc["type"].replace("``", ""), doc["choices"])
    if doc["required"]:
        return typ, "required"
    default = toml_literal(doc["default"])
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


def _examples_dir() -> Path:
    """The repository's ``examples/`` (beside the package in a source tree)."""
    return Path(__file__).resolve().parents[1] / "examples"


def _example_of(name: str) -> tuple[Path, str, str] | None:
    """The first example spec designing with method ``name``: (path, design name, TOML text of
    its ``[[design]]`` table), or None without one."""
    import tomllib

    for path in sorted(_examples_dir().glob("*.toml")):
        text = path.read_text(encoding="utf-8")
        entries = tomllib.loads(text).get("design", [])
        design = next((e["name"] for e in entries if e.get("method") == name), None)
        if design is None:
            continue
        blocks = re.split(r"(?m)^(?=\[\[design\]\])", text)[1:]
        for block in blocks:
            block = re.split(r"(?m)^\[(?!\[design\]\]|design\.)", block)[0]   # up to the next other table
            if re.search(rf'(?m)^name\s*=\s*"{re.escape(design)}"', block):
                lines = block.rstrip().splitlines()
                while lines and (not lines[-1].strip() or lines[-1].lstrip().startswith("#")):
                    lines.pop()   # comments introducing the next table
                return path, design, "\n".join(lines)
    return None


def toml_example(name: str) -> str:
    """The Markdown of method ``name``'s TOML example: its ``[[design]]`` table in an example spec.

    Parameters
    ----------
    name : str
        A method of the table.

    Returns
    -------
    str
        A heading, where the table comes from and the table; empty when no example uses it.
    """
    found = _example_of(name)
    if found is None:
        return ""
    path, design, table = found
    return "\n".join([
        "## TOML example", "",
        f"The design `{design}` of `examples/{path.name}` (the file also states the plant, its "
        f"operating point and sampling period); `tanksynth run examples/{path.name}` designs, "
        "verifies and reports it:", "", "```toml", table, "```", ""])


#: The keyword arguments of `tanksynth.design` itself: an option of the same name cannot be
#: passed beside them (an estimator's ``x0``), so such a design keeps the spec-file form.
_DESIGN_KEYWORDS = frozenset({"plant", "method", "x0", "u0", "ts", "y0", "trim", "name", "directory",
                              "title", "state_bound", "input_bound"})


def _python_literal(value: Any) -> str:
    """A TOML value (as `tomllib` reads it) as Python source (``true`` -> ``True``)."""
    import json

    if isinstance(value, bool):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, list):
        return "[" + ", ".join(_python_literal(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(str(k))}: {_python_literal(v)}" for k, v in value.items()) + "}"
    raise ValueError(f"no Python literal for {value!r}")


def _design_keywords(spec_path: str, design: str) -> tuple[dict[str, Any], dict[str, Any]] | None:
    """The [plant] table and the keyword arguments of `tanksynth.design` that design ``design``
    of the spec file ``spec_path`` (relative to the repository root), or None when the spec
    needs more than one design's tables (data files, other tables, an option named as one of
    `tanksynth.design`'s own keywords)."""
    import keyword
    import tomllib

    path = _examples_dir().parent / spec_path
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError):
        return None
    if set(doc) - {"title", "plant", "operating_point", "sampling", "design"}:
        return None
    op, sampling = doc.get("operating_point", {}), doc.get("sampling", {})
    if set(op) - {"x", "u", "y", "trim"} or set(sampling) - {"ts"}:
        return None
    entry = next((e for e in doc.get("design", []) if e.get("name") == design), None)
    if entry is None:
        return None
    options = {k: v for k, v in entry.items() if k not in ("name", "method")}
    if "x0" in options:   # an estimator's initial estimate: tanksynth.design's x_hat0
        options = {("x_hat0" if k == "x0" else k): v for k, v in options.items()}
    if any(k in _DESIGN_KEYWORDS or not k.isidentifier() or keyword.iskeyword(k) for k in options):
        return None
    kwargs: dict[str, Any] = {"name": design}
    kwargs.update({f"{k}0": op[k] for k in ("x", "u", "y") if k in op})
    if "trim" in op:
        kwargs["trim"] = op["trim"]
    if "ts" in sampling:
        kwargs["ts"] = sampling["ts"]
    return doc["plant"], {**kwargs, "method": entry["method"], **options}


def python_design_call(spec_path: str, design: str, directory: str) -> list[str]:
    """THE call form of a design from Python on the method pages (one place to change).

    Lines of Python that design ``design`` of the spec file ``spec_path`` into the result
    directory ``directory`` and bind the name ``art`` to the `tanksynth.loading.Design` it
    returns: the public API, ``tanksynth.design(plant, method, x0=..., u0=..., ts=...,
    **options)``, with the spec's ``[plant]`` table, operating point, sampling period and the
    design's options written as Python values. A spec that needs more than these tables (a fit's
    ``[data]``) or an option named as one of ``tanksynth.design``'s keywords (an estimator's
    ``x0``) is designed from the file instead (`tanksynth.load_spec`, the method table's design
    step), with the same name ``art`` bound.

    Parameters
    ----------
    spec_path : str
        The spec file, relative to the repository root.
    design : str
        The name of one ``[[design]]`` table of the spec.
    directory : str
        The result directory to write (it must not exist, or be empty).

    Returns
    -------
    list of str
        The lines (no trailing newline).
    """
    found = _design_keywords(spec_path, design)
    if found is not None:
        plant, kwargs = found
        method = kwargs.pop("method")
        lines = ["import tanksynth", "",
                 f"plant = {_python_literal(plant)}  # the [plant] table of {spec_path}",
                 f'art = tanksynth.design(plant, "{method}",']
        lines += [f"                       {k}={_python_literal(v)}," for k, v in kwargs.items()]
        lines.append(f'                       directory="{directory}")  # {directory}/{design}.json, .npz')
        return lines
    return [
        "import tanksynth",
        "from tanksynth.artefacts import write_artefact, write_plant_record",
        "from tanksynth.methods import design",
        "",
        f'spec = tanksynth.load_spec("{spec_path}")  # options validated here',
        f'entry = next(d for d in spec.designs if d.name == "{design}")',
        f'write_plant_record(spec, "{directory}")  # {directory}/plant.json and {directory}/spec.toml',
        f'write_artefact(design(spec, entry), "{directory}", spec.sha256)  # {directory}/{design}.json, .npz',
        f'art = tanksynth.load("{directory}/{design}.json")',
    ]


def python_example(name: str) -> str:
    """The Markdown of method ``name``'s Python example: design, verify, load the artefact.

    Parameters
    ----------
    name : str
        A method of the table.

    Returns
    -------
    str
        A heading and a code block (from `python_design_call`); empty when no example uses
        the method.
    """
    found = _example_of(name)
    if found is None:
        return ""
    path, design, _ = found
    directory = "out"
    lines = [*python_design_call(f"examples/{path.name}", design, directory),
             "verdict = art.verify()  # the gain on the nonlinear plant, as tanksynth verify",
             "art.gains, verdict.passed, verdict.checks  # arrays by gain name; the verdict"]
    return "\n".join([
        "## Python example", "",
        "The same design from Python, run from the repository root (the gain names: "
        "{doc}`/artefacts`):", "", "```python", *lines, "```", ""])


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
                    "variants": _variants(builder, options, summary["parameters"]),
                    **{k: summary[k] for k in ("states", "inputs", "outputs", "parameters")}})
    return out


def _variants(builder: Callable[..., Any], options: Sequence[dict[str, Any]],
              defaults: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The parameter values that differ from the defaults, for each choice of an option whose
    type lists its choices (``{"a", "b"}``, e.g. ``parameter_set``).

    Returns
    -------
    list of dict
        ``{"option", "choice", "parameters": [{"name", "value", "unit"}]}``; a choice that
        changes no parameter value, or that the builder refuses with its other defaults, is
        left out.
    """
    base = {p["name"]: p["value"] for p in defaults}
    out = []
    for o in options:
        choices = re.findall(r'"([^"]+)"', o["type"]) if o["type"].lstrip().startswith("{") else []
        for choice in choices:
            if repr(choice) == o["default"]:
                continue
            try:
                params = builder(**{o["name"]: choice}).summary()["parameters"]
            except SpecError:
                continue
            changed = [{"name": p["name"], "value": p["value"], "unit": p["unit"]} for p in params
                       if base.get(p["name"]) != p["value"]]
            if changed:
                out.append({"option": o["name"], "choice": choice, "parameters": changed})
    return out


def plain_text(text: str) -> str:
    """Docstring or Markdown text for a terminal: without RST roles (``:math:`x```), double or
    single backticks, directives (``.. note::``) and code fences (their lines indented instead).

    Parameters
    ----------
    text : str
        The marked-up text.

    Returns
    -------
    str
    """
    lines, fenced = [], False
    for line in str(text).splitlines():
        if line.lstrip().startswith("```"):
            fenced = not fenced
            continue
        if fenced:
            lines.append("    " + line)
            continue
        if re.match(r"\s*\.\. ", line):
            continue
        line = re.sub(r":[a-z]+:`([^`]*)`", r"\1", line)
        line = re.sub(r"^#+ ", "", line)
        line = line.replace("``", "").replace("`", "")
        lines.append(line)
    return "\n".join(lines)


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
              "`[plant.parameters]`):", ""]
    lines += _table(("parameter", "value", "unit", "meaning"),
                    [(f"`{p['name']}`", f"{p['value']:.6g}", p["unit"], p["description"])
                     for p in family["parameters"]])
    for line in plant_variants_markdown(family):
        lines += ["", line]
    lines.append("")
    return "\n".join(lines)


def plant_variants_markdown(family: dict[str, Any]) -> list[str]:
    """One Markdown line per option choice that changes parameter values (``With
    `parameter_set = "johansson_min_phase"`: `k2` = 3.35 cm^3/(V s), ...``).

    Parameters
    ----------
    family : dict
        One entry of `plant_families`.

    Returns
    -------
    list of str
    """
    def value(p: dict[str, Any]) -> str:
        unit = "" if p["unit"] in ("", "1", "-") else " " + p["unit"]
        return f"`{p['name']}` = {p['value']:.6g}{unit}"

    return [f"With `{v['option']} = \"{v['choice']}\"`: " + ", ".join(value(p) for p in v["parameters"])
            + "." for v in family.get("variants", ())]


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
        "`{unit, min, max}`, parameters `{value, unit, min, max, fit}` (`fit = true`: estimated "
        "from measured data, min/max the search box), one equation `dx/dt` per state and each "
        "output an expression (or `{expr, unit, min, max}`, min/max: the sensor range, whose "
        "samples are censored in measured data). Equations are read by a "
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
    """The gain-naming table of the docs (artefacts page), from `tanksynth.analysis.statespace.GAIN_NAMES`.

    Returns
    -------
    str
        A Markdown table (name(s), meaning), one row per entry.
    """
    from tanksynth.analysis.statespace import GAIN_NAMES

    rows = [(", ".join(f"`{n}`" for n in names), meaning) for names, meaning in GAIN_NAMES.items()]
    return "\n".join(_table(("Name", "Meaning"), rows)) + "\n"


#: The sections of the curated API page: title -> the modules whose public names it lists (a
#: name of ``tanksynth.__all__`` from another module lands in "Other").
API_SECTIONS: dict[str, tuple[str, ...]] = {
    "Results: load designed artefacts, their verdicts": ("tanksynth.loading", "tanksynth.verify.runner",
                                                         "tanksynth.analysis.checks"),
    "Specs: read, design, verify, report": ("tanksynth.methods", "tanksynth.spec", "tanksynth.design.result",
                                            "tanksynth.artefacts.io"),
    "Plants": ("tanksynth.plants",),
    "Analysis": ("tanksynth.analysis",),
    "Errors": ("tanksynth.errors",),
    "Caches": ("tanksynth",),
}


def _api_entry(qualified: str, obj: Any) -> list[str]:
    """The autodoc directive documenting ``obj`` under the name ``qualified``."""
    if isinstance(obj, type) and issubclass(obj, BaseException):
        return [f".. autoexception:: {qualified}", ""]
    if isinstance(obj, type):
        return [f".. autoclass:: {qualified}", "   :members:", ""]
    return [f".. autofunction:: {qualified}", ""]


def api_reference_markdown() -> str:
    """The curated API page: every public name of ``tanksynth.__all__``, by topic.

    A summary table (name, first line of its docstring) per section of `API_SECTIONS`, then
    each name's full docstring (autodoc under its ``tanksynth.NAME``). The modules themselves
    (internals included) are documented on the developers' pages.

    Returns
    -------
    str
        A MyST page.
    """
    import tanksynth

    names = [n for n in tanksynth.__all__ if n != "__version__"]
    objects = {n: getattr(tanksynth, n) for n in names}
    sections: dict[str, list[str]] = {title: [] for title in API_SECTIONS}
    sections["Other"] = []
    for n in names:
        module = getattr(objects[n], "__module__", "tanksynth")
        home = next((title for title, mods in API_SECTIONS.items()
                     if any(module == m or module.startswith(m + ".") for m in mods if m != "tanksynth")
                     or module in mods), "Other")
        sections[home].append(n)
    lines = ["# API reference", "",
             "The public Python interface: every name `import tanksynth` offers "
             "(`tanksynth.__all__`; each loads its libraries on first use), by topic. "
             "`tanksynth.__version__` is the installed version. The modules behind them, internals "
             "included, are in the {doc}`developers' module reference </_generated/api/index>`.", ""]
    for title, members in sections.items():
        if not members:
            continue
        lines += [f"## {title}", "", *_table(("name", "what it is"), [
            (f"{{py:obj}}`~tanksynth.{n}`",
             (inspect.getdoc(objects[n]) or "").strip().split("\n\n")[0].replace("\n", " "))
            for n in members]), "", "```{eval-rst}"]
        for n in members:
            lines += _api_entry(f"tanksynth.{n}", objects[n])
        lines += ["```", ""]
    return "\n".join(lines).rstrip("\n") + "\n"


#: The generated sections of the documentation pages: marker name -> text.
GENERATED_SECTIONS: dict[str, Callable[[], str]] = {"plants": plants_markdown,
                                                    "methods": methods_markdown,
                                                    "gain_names": gain_names_markdown}


def _markers(name: str) -> tuple[str, str]:
    return (f"<!-- BEGIN GENERATED {name} (python -m tanksynth.docgen) -->",
            f"<!-- END GENERATED {name} -->")


def generated_section(text: str, name: str) -> str:
    """The text between the markers of section ``name`` in ``text`` (a page of `DOC_PAGES`).

    Parameters
    ----------
    text : str
        The page's text.
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
#: sections, and which: `main` rewrites them.
DOC_PAGES: dict[str, tuple[str, ...]] = {"docs/design_methods.md": ("methods",),
                                         "docs/plant_families.md": ("plants",),
                                         "docs/artefacts.md": ("gain_names",),
                                         "docs/gain_names.md": ("gain_names",)}


def update_readme(path: str | Path, check: bool = False,
                  sections: Sequence[str] | None = None) -> list[str]:
    """Rewrite the generated sections of a page (or, with ``check``, only compare).

    Parameters
    ----------
    path : str or Path
        A page of `DOC_PAGES` (or any Markdown file with generated sections).
    check : bool
        Do not write; only report what differs.
    sections : sequence of str, optional
        The sections the file holds (default every one of `GENERATED_SECTIONS` whose
        markers it has).

    Returns
    -------
    list of str
        The sections that were stale (rewritten unless ``check``).

    Raises
    ------
    SpecError
        A section named in ``sections`` has no markers, or (``sections`` omitted) the file
        holds none.
    """
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    if sections is None:
        sections = [name for name in GENERATED_SECTIONS if _markers(name)[0] in text]
        if not sections:
            raise SpecError(f"{path}: no generated section (expected the lines "
                            f"{_markers('NAME')[0]!r} ... {_markers('NAME')[1]!r})")
    stale = []
    for name in sections:
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
    """Write the generated Markdown pages of the Sphinx documentation (MyST).

    Parameters
    ----------
    directory : str or Path
        Gets ``methods/<name>.md``, ``plants/<name>.md``, the two index pages
        ``methods/index.md`` and ``plants/index.md``, and ``api_reference.md``
        (`api_reference_markdown`).

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
        text = "\n".join(filter(None, [method_markdown(m["name"], level=1), toml_example(m["name"]),
                                        python_example(m["name"])]))
        page(directory / "methods" / f"{m['name']}.md", text)
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
    page(directory / "api_reference.md", api_reference_markdown())
    return written


def main(argv: list[str] | None = None) -> int:
    """``python -m tanksynth.docgen [--check] [FILE]``: rewrite (or check) the generated sections
    of the pages of `DOC_PAGES` (run from the repository root) or, given, of FILE alone.

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
        (page, names) for page, names in DOC_PAGES.items() if Path(page).is_file()]
    any_stale = False
    for path, sections in files:
        stale = update_readme(path, check=check, sections=sections)
        any_stale = any_stale or bool(stale)
        for name in stale:
            sys.stdout.write(f"{path}: section {name!r} {'is stale' if check else 'rewritten'}\n")
    return 1 if check and any_stale else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
