"""Command settings declared once: :class:`Option`, the metadata of a settings dataclass's field.

A command's settings are the fields of its settings dataclass (:func:`setting`) and a few options beside
them; each carries an :class:`Option` — flag, help, check, the front ends' defaults. From these come the
argparse options (:func:`add_options`: ASCII integers, choices shown in the usage), a Python API's signature
(:func:`api_signature`) and the checks both front ends run (:meth:`Option.check_value`: one message, the
setting named as each front end spells it). ``electroloc bench`` (``bench/config.py``) and ``electroloc
dataset`` (``dataset/request.py``) declare theirs with it; docs/design.md says why it is not a library.
"""

from __future__ import annotations

import argparse
import inspect
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import MISSING, dataclass, field, fields, replace
from typing import Any

import numpy as np

from electroloc_gym.utils.agentspec import parse_options

__all__ = [
    "SettingError",
    "Check",
    "Option",
    "setting",
    "options_of",
    "ascii_int",
    "add_options",
    "api_signature",
    "pairs_value",
    "message_names",
    "message_words",
    "int_in",
    "one_of",
    "is_bool",
]


class SettingError(ValueError):
    """A setting out of its range: ``setting`` names it, ``allowed`` the range, ``got`` the value.

    ``str()`` names the field as Python spells it; a front end names it its own way (``--max-observations``)
    from the same three parts, so the check and its words live here once.
    """

    def __init__(self, setting: str, allowed: str, got: Any) -> None:
        super().__init__(f"{setting} must be {allowed}, got {got!r}")
        self.setting, self.allowed, self.got = setting, allowed, got

    def __reduce__(self) -> tuple[Any, ...]:
        return (SettingError, (self.setting, self.allowed, self.got))


Check = Callable[[str, Any], None]
"""``check(name, value)``: raises a one-line ValueError naming the setting as ``name`` (each front end's spelling)."""


class _Same:
    def __repr__(self) -> str:
        return "the command line's"


_SAME: Any = _Same()


@dataclass(frozen=True)
class Option:
    """One setting of a command as both of its front ends see it (the command line and Python).

    Attributes:
        name: the Python keyword (a field's name: set by :func:`options_of`).
        help: the ``--help`` text (a callable: read from the live tables when the parser is built).
        check: :data:`Check` (None: any value). A None value passes where a default is None (it means
            "derived": the env's own, all cores, …).
        default: what both front ends take when the setting is left out (``dataclasses.MISSING``: required).
        kind: ``"int"`` (ASCII digits on the command line), ``"text"``, ``"switch"`` (a flag: True when given),
            ``"negated"`` (a ``--no-…`` flag: False when given) or ``"pairs"`` (``KEY=VALUE`` words on the command
            line, :func:`pairs_value` makes them the mapping Python takes).
        flag: the command line's flag (default ``--`` and the name with dashes).
        choices: the valid values shown in the usage (``{a,b}``; the check refuses the others).
        from_env: env id → the value a None default stands for (the env table's).
        python_default: the Python API's default where it differs from the command line's (an output
            folder, a progress bar: what a library call must not assume).
        bad: values the check refuses (the parity test's table: every checked setting names some).
    """

    name: str = ""
    help: str | Callable[[], str] = ""
    check: Check | None = None
    default: Any = None
    kind: str = "text"
    flag: str = ""
    choices: Callable[[], Iterable[str]] | None = None
    from_env: Callable[[str], Any] | None = None
    python_default: Any = _SAME
    bad: tuple[Any, ...] = ()

    @property
    def option(self) -> str:
        """The command line's flag."""
        return self.flag or "--" + self.name.replace("_", "-")

    @property
    def api_default(self) -> Any:
        """The Python API's default."""
        return self.default if self.python_default is _SAME else self.python_default

    def check_value(self, name: str, value: Any) -> Any:
        """Refuse ``value`` (one line naming the setting as ``name``) unless the declaration allows it; return it as
        the run stores it (an ``"int"`` setting's numpy integer as a Python ``int``, which every record holds).
        """
        if value is None and (self.default is None or self.python_default is None):
            return value
        if self.check is not None:
            self.check(name, value)
        return int(value) if self.kind == "int" and value is not None else value


def setting(field_default: Any, /, **option: Any) -> Any:
    """A dataclass field that is a command's setting: ``field_default`` is the field's, ``option`` its
    :class:`Option` (whose front-end ``default`` is the field's unless given).
    """
    option.setdefault("default", field_default)
    return field(default=field_default, metadata={"option": Option(**option)})


def options_of(cls: Any) -> tuple[Option, ...]:
    """The :class:`Option` of every field of the dataclass ``cls`` that declares one, named by its field."""
    return tuple(replace(f.metadata["option"], name=f.name) for f in fields(cls) if "option" in f.metadata)


_ASCII_INT = re.compile(r"-?[0-9]+")


def ascii_int(text: str) -> int:
    """An integer written in ASCII digits (``int`` also takes other scripts' digits, ``_`` and spaces)."""
    if not isinstance(text, str) or not _ASCII_INT.fullmatch(text) or len(text) > 40:
        raise argparse.ArgumentTypeError(f"must be an integer in ASCII digits, got {text!r}")
    return int(text)


def add_options(parser: argparse.ArgumentParser, options: Iterable[Option]) -> None:
    """Add ``options`` to ``parser`` (each under its flag; its value under its Python name)."""
    for opt in options:
        text = opt.help() if callable(opt.help) else opt.help
        if opt.kind in ("switch", "negated"):
            action = "store_true" if opt.kind == "switch" else "store_false"
            parser.add_argument(opt.option, dest=opt.name, action=action, help=text)
            continue
        if opt.kind == "pairs":
            parser.add_argument(
                opt.option, dest=opt.name, nargs="*", metavar="KEY=VALUE", default=opt.default, help=text
            )
            continue
        kwargs: dict[str, Any] = {"dest": opt.name, "help": text}
        kwargs.update({"required": True} if opt.default is MISSING else {"default": opt.default})
        if opt.kind == "int":
            kwargs["type"] = ascii_int
        if opt.choices is not None:
            kwargs["metavar"] = "{" + ",".join(opt.choices()) + "}"
        parser.add_argument(opt.option, **kwargs)


def message_names(options: Iterable[Option], spell: Callable[[Option], str]) -> dict[str, str]:
    """How a run's messages name each of ``options`` in the words of the front end ``spell`` spells: a setting
    by its name (``--out`` / ``out``), a switch as it is turned on (``--resume`` / ``resume=True``).
    """
    names = {}
    for opt in options:
        spelled = spell(opt)
        names[opt.name] = f"{spelled}=True" if opt.kind == "switch" and not spelled.startswith("-") else spelled
    return names


def message_words(defaults: Mapping[str, str], names: Any) -> dict[str, str]:
    """The words a function's messages name its settings with: ``names`` (a front end's, e.g. ``{"out": "--out"}``)
    over ``defaults`` (the Python API's).

    Raises:
        ValueError: ``names`` neither None nor a mapping of some of ``defaults``' settings to text (one line).
    """
    if names is None:
        return dict(defaults)
    if (
        not isinstance(names, Mapping)
        or not set(names) <= set(defaults)
        or not all(isinstance(v, str) and v for v in names.values())
    ):
        raise ValueError(f"names must be None or a mapping of settings {sorted(defaults)} to text, got {names!r}")
    return {**defaults, **names}


def pairs_value(opt: Option, words: Sequence[str] | None) -> dict[str, Any] | None:
    """A ``"pairs"`` option's command-line words as the mapping Python takes (None: the option was not given).

    Raises:
        ValueError: a word that is not ``KEY=VALUE`` (one line naming the flag).
    """
    return None if words is None else parse_options(list(words), opt.option)


def api_signature(options: Iterable[Option], *first: inspect.Parameter, last: Sequence[inspect.Parameter] = ()) -> Any:
    """The Python API's signature: ``first``, then every option as a keyword with its Python default, then ``last``."""
    empty = inspect.Parameter.empty
    keywords = [
        inspect.Parameter(
            o.name, inspect.Parameter.KEYWORD_ONLY, default=empty if o.api_default is MISSING else o.api_default
        )
        for o in options
    ]
    return inspect.Signature([*first, *keywords, *last])


def int_in(low: int, high: int, why: str = "") -> Check:
    """An integer (not a bool) in [low, high] (``why``: words after the range)."""

    def check(name: str, value: Any) -> None:
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or not low <= value <= high:
            raise SettingError(name, f"an integer in [{low}, {high}]{why}", value)

    return check


def one_of(choices: Callable[[], Iterable[str]]) -> Check:
    """One of ``choices()`` (read when checked: the tables are live)."""

    def check(name: str, value: Any) -> None:
        allowed = list(choices())
        if not isinstance(value, str) or value not in allowed:
            raise SettingError(name, f"one of {allowed}", value)

    return check


def is_bool(name: str, value: Any) -> None:
    """True or False."""
    if not isinstance(value, bool):
        raise SettingError(name, "True or False", value)
