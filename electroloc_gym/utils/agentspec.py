"""Agent specs: the one parser of what ``--agents`` takes and what every trial record's ``agent`` holds.

Grammar (whitespace around names, keys and values is ignored)::

    spec     := target | target "[" options "]"
    target   := NAME                      a registered agent:      min-var, lookahead
              | MODULE ":" FACTORY        a user's factory:        mypkg.agents:make_policy
    options  := key "=" value ("," key "=" value)*

A value is a Python literal (``ast.literal_eval``) or else a bare word kept as a string (``vote=expected``).
Commas, brackets and quotes nest: ``lookahead[objective=(a,b)]``, ``x[weights=[1,2,3],name='a,b']`` split
where a reader expects. No library parses this small grammar (argparse and ``ast`` see only parts of it),
hence a hand-written scanner. A policy path is not a spec; :func:`is_path_like` tells them apart.
"""

from __future__ import annotations

import ast
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = [
    "AgentSpec",
    "parse_agent_spec",
    "split_specs",
    "is_path_like",
    "path_agent_name",
    "parse_options",
    "MAX_SPEC_CHARS",
]

#: Longest spec accepted (characters): a spec is a name and a few options, not a data file.
MAX_SPEC_CHARS = 2000
_NAME_RE = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_\-]*")
_FACTORY_RE = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*:[A-Za-z_]\w*")
_KEY_RE = re.compile(r"[A-Za-z_]\w*")
_OPEN, _CLOSE = "([{", ")]}"


@dataclass(frozen=True)
class AgentSpec:
    """A parsed agent spec: ``text`` as written (stripped, the key of trial records), ``name`` (an agent's
    name or ``module:factory``) and the ``options`` in the order given.
    """

    text: str
    name: str
    options: dict[str, Any] = field(default_factory=dict)

    @property
    def is_factory(self) -> bool:
        """``module:factory`` (a user's code) rather than a registered name."""
        return ":" in self.name

    @property
    def module(self) -> str:
        """The module of a ``module:factory`` spec."""
        return self.name.split(":", 1)[0]

    @property
    def factory(self) -> str:
        """The factory's name in a ``module:factory`` spec."""
        return self.name.split(":", 1)[1]

    @classmethod
    def parse(cls, text: str) -> AgentSpec:
        """:func:`parse_agent_spec`."""
        return parse_agent_spec(text)


def is_path_like(text: str) -> bool:
    """True when ``text`` is written as a path: a slash or backslash before any ``[`` (an option's value may hold
    one: ``pkg.mod:make[log='runs/a']`` is a spec), a leading ``.`` or ``~``, or a ``.zip`` end.
    """
    head = text.split("[", 1)[0]
    return "/" in head or "\\" in head or text.startswith((".", "~")) or text.endswith(".zip")


def path_agent_name(path: str | os.PathLike[str]) -> str:
    """The name a policy path runs under: the folder of its ``model.zip`` or ``policy.json``, a ``.zip``'s stem, or
    the folder's name (the progress line, the log and the table all use it).
    """
    p = Path(os.fspath(path).rstrip("/\\"))
    if p.name in ("model.zip", "policy.json") and p.parent.name:
        return p.parent.name
    return p.stem if p.suffix == ".zip" else p.name


def _scan(text: str, what: str) -> list[tuple[int, int]]:
    """Spans of ``text`` split at commas outside brackets and quotes (a ValueError when they do not close)."""
    spans, stack, start, quote, i = [], [], 0, "", 0
    while i < len(text):
        ch = text[i]
        if quote:
            if ch == "\\":
                i += 1
            elif ch == quote:
                quote = ""
        elif ch in "'\"":
            quote = ch
        elif ch in _OPEN:
            stack.append(_CLOSE[_OPEN.index(ch)])
        elif ch in _CLOSE:
            if not stack or stack.pop() != ch:
                raise ValueError(f"{what} {text!r}: unbalanced {ch!r} at character {i + 1}")
        elif ch == "," and not stack:
            spans.append((start, i))
            start = i + 1
        i += 1
    if quote:
        raise ValueError(f"{what} {text!r}: unclosed quote {quote}")
    if stack:
        raise ValueError(f"{what} {text!r}: {stack[-1]!r} missing")
    spans.append((start, len(text)))
    return spans


def split_specs(text: str) -> list[str]:
    """A comma-separated list of specs split at the commas outside brackets and quotes (items stripped)."""
    if not isinstance(text, str):
        raise ValueError(f"agents must be a string of comma-separated specs, got {text!r}")
    return [text[a:b].strip() for a, b in _scan(text, "agents")]


def _value(raw: str) -> Any:
    """A Python literal; else a bare word (a string); else a bracketed sequence of such values."""
    try:
        return ast.literal_eval(raw)
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
        pass
    if re.fullmatch(r"[\w.\-+]+", raw):
        return raw  # a bare word: vote=expected
    if len(raw) >= 2 and raw[0] in "([" and raw[-1] == _CLOSE[_OPEN.index(raw[0])]:
        inner = raw[1:-1]
        items = [] if not inner.strip() else [_value(inner[a:b].strip()) for a, b in _scan(inner, "value")]
        return tuple(items) if raw[0] == "(" else items  # (a,b) → ("a", "b")
    raise ValueError(f"value {raw!r} is neither a Python literal nor a bare word")


def _option(item: str, where: str, options: dict[str, Any]) -> None:
    """One ``key=value`` into ``options`` (the value by :func:`_value`); ``where`` names it in errors."""
    if "=" not in item:
        raise ValueError(f"{where}: {item.strip()!r} must be key=value")
    key, raw = (s.strip() for s in item.split("=", 1))
    if not _KEY_RE.fullmatch(key):
        raise ValueError(f"{where}: key {key!r} must be a Python identifier")
    if key in options:
        raise ValueError(f"{where}: {key!r} given twice")
    try:
        options[key] = _value(raw)
    except ValueError as exc:
        raise ValueError(f"{where}: {key!r}: {exc}") from None


def parse_options(items: Sequence[str], where: str) -> dict[str, Any]:
    """``["key=value", ...]`` → a dict, each value read as an agent spec's option; the one KEY=VALUE syntax of
    the command lines (``electroloc train --env-kwargs/--hyperparams``). A refusal is one line starting with
    ``where``.
    """
    options: dict[str, Any] = {}
    for item in items:
        _option(item, where, options)
    return options


def parse_agent_spec(text: str) -> AgentSpec:
    """Parse an agent spec (the module docstring); a malformed one is a ValueError quoting it."""
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"agent spec must be a non-empty string, got {text!r}")
    spec = text.strip()
    if len(spec) > MAX_SPEC_CHARS:
        raise ValueError(f"agent spec is {len(spec)} characters long; at most {MAX_SPEC_CHARS} are accepted")
    head, body = spec, None
    if "[" in spec:
        head, rest = spec.split("[", 1)
        if not rest.endswith("]"):
            raise ValueError(f"agent spec {spec!r} is malformed: options go in one trailing [key=value,...]")
        body = rest[:-1]
    head = head.strip()
    if not (_NAME_RE.fullmatch(head) or _FACTORY_RE.fullmatch(head)):
        raise ValueError(
            f"agent spec {spec!r} is malformed; expected NAME, NAME[key=value,...] or "
            f"package.module:factory[key=value,...]"
        )
    options: dict[str, Any] = {}
    if body is not None and body.strip():
        for a, b in _scan(body, f"options of agent spec {spec!r}:"):
            _option(body[a:b], f"agent option in {spec!r}", options)
    return AgentSpec(text=spec, name=head, options=options)
