"""The base of every method's Options and the reader of one ``[[design]]`` table.

A method's options are a frozen dataclass (a `MethodOptions` subclass):
its fields are the options, their defaults are the field defaults (written
once, there), and its ``from_table`` classmethod reads the raw ``[[design]]``
table with `OptionReader` and the readers of `tanksynth.spec.options`,
doing every check that needs no design computation.
"""

from __future__ import annotations

import dataclasses
import inspect
import re
from dataclasses import MISSING, dataclass
from typing import TYPE_CHECKING, Any, Callable, ClassVar, Mapping

import numpy as np

from tanksynth.errors import SpecError
from tanksynth.spec.memory import MEMORY_BUDGET, memory_budget
from tanksynth.spec.options import unknown_word_hint

if TYPE_CHECKING:  # the plant's module loads sympy; only its type is needed here
    from tanksynth.plants.base import Plant
    from tanksynth.spec.memory import ConicSize

__all__ = ["MethodOptions", "OptionReader", "OptionDoc", "option", "numpydoc_section", "time_domain_of",
           "MEMORY_BUDGET", "memory_budget", "TIME_DOMAIN_TEXT"]


def option(default: Any = MISSING, *, unit: str, doc: str = "", default_text: str = "",
           choices: tuple[Any, ...] = (), required_when: str = "") -> Any:
    """A field of an Options dataclass that declares its unit (and, optionally, its meaning).

    Use it as the field's default: ``margin: float = option(1e-6, unit="-")``;
    a required option omits the default: ``poles: tuple = option(unit="1/s")`` (such a
    field is keyword-only in the constructor, so it may follow inherited fields with defaults).

    Parameters
    ----------
    default : object, optional
        The option's default (immutable); omitted for a required option.
    unit : str
        The unit of the value as a user writes it (``"s"``, ``"m^2"``, ``"1/s"``,
        ``"(state units)^2"``); ``"-"`` for a dimensionless number, a name, a
        flag or a count.
    doc : str, optional
        One line of meaning; default the first sentence of the option's entry
        in the class docstring's ``Attributes`` section.
    default_text : str, optional
        What a default of None (or a computed default) IS, in a few words
        (``"the operating point"``); default the ``default ...`` clause of the
        option's docstring entry.
    choices : tuple, optional
        The allowed values of a choice option (the tuple its reader passes to
        `tanksynth.spec.options.parse_choice`).
    required_when : str, optional
        For an option with a default that the plant can make necessary: when it is
        (``"the plant has not as many outputs as inputs"``); the catalogue prints it.

    Returns
    -------
    dataclasses.Field
        The field, its ``metadata`` holding ``unit``, ``doc``, ``default_text``,
        ``choices`` and ``required_when``.
    """
    if not isinstance(unit, str) or not unit:
        raise TypeError("option(): unit must be a non-empty string ('-' when dimensionless)")
    return dataclasses.field(default=default, kw_only=default is MISSING,
                             metadata={"unit": unit, "doc": doc, "default_text": default_text,
                                       "choices": tuple(choices), "required_when": required_when})


@dataclass(frozen=True)
class OptionDoc:
    """What the documentation says of one option (see `MethodOptions.describe`).

    Attributes
    ----------
    name : str
        The option's key in a ``[[design]]`` table.
    type : str
        Its type, as the class docstring gives it (else the annotation).
    default : str
        The default as written in Python (``repr``), or ``"required"``.
    required : bool
        The option has no default: a table without it is refused.
    unit : str
        Its unit (``"-"`` dimensionless); ``""`` when the field declares none.
    meaning : str
        One line (the field's ``doc``, else the first sentence of its docstring entry).
    description : str
        The whole docstring entry (one paragraph), ``""`` if undocumented.
    default_text : str
        What the default IS when it is None or computed (``"computed: the
        operating point"``), ``""`` for a plain default.
    choices : tuple of str
        The allowed values of a choice option (``repr`` of each), ``()`` otherwise.
    one_of : tuple of str
        The group of options of which a table gives exactly one (this option among
        them, see `MethodOptions.one_of`), ``()`` for an option outside such a group.
    required_when : str
        When the plant makes this option (which has a default) necessary, ``""`` if never.
    """

    name: str
    type: str
    default: str
    required: bool
    unit: str
    meaning: str
    description: str
    default_text: str = ""
    choices: tuple[str, ...] = ()
    one_of: tuple[str, ...] = ()
    required_when: str = ""

    def as_dict(self) -> dict[str, Any]:
        """JSON-friendly fields."""
        return dataclasses.asdict(self)


def numpydoc_section(doc: str | None, section: str) -> dict[str, tuple[str, str]]:
    """The entries of one numpydoc section (``Parameters``, ``Attributes``...) of a docstring.

    Parameters
    ----------
    doc : str or None
        The docstring (raw or cleaned; it is dedented here).
    section : str
        The section title.

    Returns
    -------
    dict of str to (str, str)
        ``name -> (type, description)``, the description's lines joined by
        single spaces; ``a, b : float`` gives two entries and ``**kwargs``
        the name ``kwargs``.
    """
    text = inspect.cleandoc(doc or "")
    match = re.search(rf"^{re.escape(section)}\n-+\n(.*?)(?=^\S[^\n]*\n-+\n|\Z)", text, re.S | re.M)
    if not match:
        return {}
    out: dict[str, tuple[str, str]] = {}
    names: list[str] = []
    typ = ""
    lines: list[str] = []

    def flush() -> None:
        for name in names:
            out[name] = (typ, " ".join(" ".join(lines).split()))

    for line in match.group(1).splitlines():
        if line and not line[0].isspace():
            flush()
            head, _, typ = line.partition(" : ")
            names = [n.strip().lstrip("*") for n in head.split(",") if n.strip()]
            typ, lines = typ.strip(), []
        elif names:
            lines.append(line.strip())
    flush()
    return out


def _first_sentence(text: str) -> str:
    """Up to the first ``.`` or ``;`` outside brackets and quotes (``e.g.`` does not end it)."""
    text = re.sub(r"^Required\.\s*", "", text)
    depth, quoted = 0, False
    for i, ch in enumerate(text):
        if ch == "`":
            quoted = not quoted
        elif quoted:
            continue
        elif ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth = max(depth - 1, 0)
        elif ch in ".;" and depth == 0 and (i + 1 == len(text) or text[i + 1] == " "):
            if not re.search(r"(\be\.g|\bi\.e|\bcf|\bvs|\bet al)$", text[:i]):
                return text[:i]
    return text.rstrip(".;")


def _default_clause(text: str) -> str:
    """The ``default ...`` clause of a docstring entry, without a leading ``None``.

    ``"...; default None: the operating point."`` gives ``"the operating point"``;
    ``""`` when the entry has no such clause (or says only ``default None``).
    """
    match = re.search(r"(?:^|[.;,]\s+|\(|\s)[Dd]efault(?:s)?(?::)?\s+(?!when\b|with\b|without\b)(.*)",
                      text)
    if not match:
        return ""
    clause = _first_sentence(match.group(1)).replace("``", "")
    clause = re.sub(r"^None\b\s*[:,]?\s*", "", clause).strip()
    if clause.startswith("(") and clause.endswith(")"):
        clause = clause[1:-1].strip()
    return clause


#: The computed default of a linear design's ``time_domain`` (its `option` ``default_text``).
TIME_DOMAIN_TEXT = '"discrete" with [sampling] ts, else "continuous"'

@dataclass(frozen=True, eq=False)
class MethodOptions:
    """Base of the Options dataclass of a design method.

    Subclasses declare one field per option (the default is the field's
    default; a field without one is a required option), document each in
    their docstring (numpydoc ``Attributes``, with units) and implement
    `from_table`. Instances are immutable; arrays in them are read-only.

    Attributes
    ----------
    method_name : str
        (class attribute) The spec's ``method`` value.
    needs_sampling : bool
        (class attribute) The method needs ``[sampling] ts``.
    one_of : tuple of tuple of str
        (class attribute) Groups of options of which a table gives exactly one
        (``(("L", "poles"),)``): `OptionReader` refuses a table giving none or
        several, and `describe` says so of each member (one source for both).
    """

    method_name: ClassVar[str] = ""
    needs_sampling: ClassVar[bool] = False
    one_of: ClassVar[tuple[tuple[str, ...], ...]] = ()

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "MethodOptions":
        """Validate a ``[[design]]`` table's options (without ``name`` and ``method``).

        Parameters
        ----------
        options : mapping
            The raw options.
        key : str
            Where the table is in the spec (``design[i]``).
        plant : Plant
            The spec's plant (sizes, state and output names, region).
        ts : float or None
            Sampling period (s).

        Returns
        -------
        MethodOptions
            The options with their defaults.

        Raises
        ------
        SpecError
            Naming the option (``design[i].<option>``) and what was expected.
        """
        raise NotImplementedError(f"{cls.__name__}.from_table")

    @classmethod
    def validated(cls, options: Mapping[str, Any], key: str, plant: Plant,
                  ts: float | None) -> "MethodOptions":
        """`from_table`, remembering the table the options were read from (`source`).

        Also refuses a design whose estimated memory (`memory_estimate`)
        exceeds `memory_budget`.

        Parameters
        ----------
        options : mapping
            The raw options (without ``name`` and ``method``).
        key : str
            Where the table is in the spec (``design[i]``).
        plant : Plant
            The spec's plant.
        ts : float or None
            Sampling period (s).

        Returns
        -------
        MethodOptions
        """
        out = cls.from_table(options, key, plant, ts)
        estimate = out.memory_estimate(plant, ts)
        budget = memory_budget()  # read (and a bad value refused) whatever the method
        if estimate is not None:
            need, option = estimate
            if need > budget:
                raise SpecError(f"this design would need about {need / 1024 ** 3:.3g} GiB of memory "
                                f"(budget {budget / 1024 ** 3:.3g} GiB, TANKSYNTH_MEMORY_BUDGET_MB); "
                                f"reduce {option!r}", key=f"{key}.{option}")
        object.__setattr__(out, "_source", dict(options))
        return out

    def memory_estimate(self, plant: Plant, ts: float | None) -> tuple[float, str] | None:
        """Estimated peak memory of the design (bytes) and the option that drives it.

        Subclasses whose sizes come from options (samples, windows, network
        sizes) override it; the estimate counts the largest arrays the
        design allocates (8 bytes per float). None: no size option.

        Parameters
        ----------
        plant : Plant
        ts : float or None
            Sampling period (s).
        """
        return None

    def conic_size(self, plant: Plant, ts: float | None) -> ConicSize | None:
        """The size of the design's conic (LMI) problem, from the plant's sizes and the options.

        The LMI families override it; `tanksynth.spec.memory.conic_refusal`
        refuses the design (exit 3) before it runs when `conic_bytes` of it
        exceeds the budget. None: no conic problem (the default).

        Parameters
        ----------
        plant : Plant
        ts : float or None
            Sampling period (s).
        """
        return None

    def read_from(self, options: Mapping[str, Any]) -> bool:
        """True if these options were validated from exactly the table ``options``.

        False for options built otherwise, or when the table has changed
        since (e.g. a `DesignSpec` copied with other options).

        Parameters
        ----------
        options : mapping
            A raw ``[[design]]`` table's options.
        """
        source = self.__dict__.get("_source")
        if source is None or not isinstance(options, Mapping):
            return False
        try:
            return bool(source == dict(options))
        except (TypeError, ValueError):  # arrays inside: compare as JSON-like values
            return _same(_jsonable(source), _jsonable(dict(options)))

    @classmethod
    def option_names(cls) -> tuple[str, ...]:
        """The options the method accepts, in declaration order."""
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def describe(cls) -> tuple[OptionDoc, ...]:
        """Every option's type, default, unit and meaning, in declaration order.

        Read from the fields (defaults, `option` metadata) and the class
        docstring's ``Attributes`` section: nothing is written twice.

        Returns
        -------
        tuple of OptionDoc
        """
        documented = numpydoc_section(cls.__doc__, "Attributes")
        groups = {name: group for group in cls.one_of for name in group}
        out = []
        for f in dataclasses.fields(cls):
            typ, text = documented.get(f.name, ("", ""))
            required = f.default is MISSING and f.default_factory is MISSING
            default = "required" if required else repr(cls.default(f.name))
            meaning = f.metadata.get("doc") or _first_sentence(text)
            typ = typ or str(f.type)
            computed = ""
            if not required and cls.default(f.name) is None:
                if "None" not in typ:  # the key may be left out: say so in the type
                    typ += " or None"
                computed = f.metadata.get("default_text") or _default_clause(text)
            elif not required:
                computed = f.metadata.get("default_text", "")
            group = groups.get(f.name, ())
            required_when = f.metadata.get("required_when", "")
            if group:
                computed = f"unset: give exactly one of {_names_text(group)}"
            elif required_when:
                computed = f"{computed}; required when {required_when}" if computed \
                    else f"unset: required when {required_when}"
            if computed and not computed.startswith(("computed:", "unset:")):
                computed = f"computed: {computed}"
            choices = tuple(repr(c).replace("'", '"') if isinstance(c, str) else repr(c)
                            for c in f.metadata.get("choices", ()))
            out.append(OptionDoc(f.name, typ, default, required, f.metadata.get("unit", ""),
                                 meaning, text, computed, choices, group, required_when))
        return tuple(out)

    @classmethod
    def default(cls, name: str) -> Any:
        """The default of option ``name``; `SpecError` if the option is required.

        Parameters
        ----------
        name : str
            The option's name (a field of the Options class).
        """
        f = cls.__dataclass_fields__[name]
        if f.default is not MISSING:
            return f.default
        if f.default_factory is not MISSING:
            return f.default_factory()
        raise SpecError(f"option {name!r} of method '{cls.method_name}' has no default (required)",
                        key=name)

    @classmethod
    def required(cls) -> tuple[str, ...]:
        """The options without a default."""
        return tuple(f.name for f in dataclasses.fields(cls)
                     if f.default is MISSING and f.default_factory is MISSING)

    def as_dict(self) -> dict[str, Any]:
        """JSON-friendly values (arrays as nested lists, complex poles as ``[re, im]``)."""
        return {f.name: _jsonable(getattr(self, f.name)) for f in dataclasses.fields(self)}

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return all(_same(getattr(self, f.name), getattr(other, f.name))
                   for f in dataclasses.fields(self))

    __hash__ = None  # type: ignore[assignment]  # arrays inside


def _names_text(names: tuple[str, ...]) -> str:
    """``L and poles`` (``a, b and c`` for three)."""
    return ", ".join(names[:-1]) + f" and {names[-1]}" if len(names) > 1 else "".join(names)


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return bool(np.array_equal(np.asarray(a), np.asarray(b)))
    if isinstance(a, (tuple, list)) and isinstance(b, (tuple, list)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return bool(a == b)


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, complex):
        return [value.real, value.imag]
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (tuple, list)):
        return [_jsonable(v) for v in value]
    return value


def time_domain_of(ts: float | None) -> str:
    """Default time domain of a linear design: ``"discrete"`` with a sampling period.

    Parameters
    ----------
    ts : float or None
        Sampling period (s); None for a continuous-time spec.

    Returns
    -------
    {"discrete", "continuous"}
    """
    return "discrete" if ts is not None else "continuous"


class OptionReader:
    """Reads the options of one ``[[design]]`` table for an Options class.

    On construction it refuses a non-table, an unknown option (with a "did
    you mean") and a missing sampling period when the method needs one.

    Parameters
    ----------
    cls : type of MethodOptions
    options : mapping
        The raw options (without ``name`` and ``method``).
    key : str
        Where the table is (``design[i]``).
    ts : float or None
        Sampling period (s).
    """

    def __init__(self, cls: type[MethodOptions], options: Any, key: str, ts: float | None):
        if not isinstance(options, Mapping):
            raise SpecError(f"expected a table of options, got {type(options).__name__}", key=key)
        allowed = cls.option_names()
        for opt in options:
            if opt not in allowed:
                raise SpecError(f"unknown option {opt!r} for method '{cls.method_name}'"
                                + (unknown_word_hint(opt, allowed) if allowed
                                   else "; the method takes no options"), key=f"{key}.{opt}")
        if cls.needs_sampling and ts is None:
            raise SpecError(f"method '{cls.method_name}' needs a sampling period: add [sampling] ts = ...",
                            key="sampling.ts")
        for group in cls.one_of:
            given = [name for name in group if name in options]
            if len(given) != 1:
                raise SpecError(f"give exactly one of {_names_text(group)} ("
                                + ("neither is given)" if not given else "not both)" if len(group) == 2
                                   else f"not {_names_text(tuple(given))})"),
                                key=f"{key}.{group[0]}")
        fields = cls.__dataclass_fields__
        missing = [name for name in allowed if name not in options and name in fields
                   and fields[name].default is MISSING and fields[name].default_factory is MISSING]
        if len(missing) > 1:   # all at once: one run tells every required option left out
            choices = [f"{name}: one of {list(fields[name].metadata['choices'])}" for name in missing
                       if fields[name].metadata.get("choices")]
            raise SpecError(f"missing options {_names_text(tuple(repr(n) for n in missing))} for method '{cls.method_name}'"
                            + (f" ({'; '.join(choices)})" if choices else ""), key=f"{key}.{missing[0]}")
        self.cls = cls
        self.options = options
        self.base = key

    def key(self, name: str) -> str:
        """The spec key of option ``name`` (``design[i].name``).

        Parameters
        ----------
        name : str
            The option's name (a field of the Options class).
        """
        return f"{self.base}.{name}"

    def given(self, name: str) -> bool:
        """True if the table sets option ``name``.

        Parameters
        ----------
        name : str
            The option's name (a field of the Options class).
        """
        return name in self.options

    def read(self, name: str, reader: Callable[..., Any], *args: Any, parse_default: bool = False,
             **kwargs: Any) -> Any:
        """``reader(value, key, *args, **kwargs)`` of the given value, else the option's default.

        With ``parse_default`` the default goes through the reader too (a
        default written in the spec's own form, e.g. one number for a vector).

        Parameters
        ----------
        name : str
            The option's name (a field of the Options class).
        reader : callable
            A reader of `tanksynth.spec.options` (or one of its form),
            ``reader(value, key, *args, **kwargs)``.
        *args
            Further positional arguments of the reader.
        parse_default : bool, optional
            Pass the default through the reader too (default False).
        **kwargs
            Further keyword arguments of the reader.

        Raises
        ------
        SpecError
            The reader refused the value, or a required option is missing.
        """
        if name in self.options:
            return reader(self.options[name], self.key(name), *args, **kwargs)
        f = self.cls.__dataclass_fields__[name]
        if f.default is MISSING and f.default_factory is MISSING:
            choices = f.metadata.get("choices", ())
            raise SpecError(f"missing option {name!r} for method '{self.cls.method_name}'"
                            + (f"; expected one of {list(choices)}" if choices else ""),
                            key=self.key(name))
        value = self.cls.default(name)
        return reader(value, self.key(name), *args, **kwargs) if parse_default else value

    def fail(self, name: str, message: str) -> SpecError:
        """A `SpecError` about option ``name`` (to raise).

        Parameters
        ----------
        name : str
            The option's name (a field of the Options class).
        message : str
            What is wrong and what was expected.

        Returns
        -------
        SpecError
        """
        return SpecError(message, key=self.key(name))
