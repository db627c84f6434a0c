"""A sweep or ``--config`` file read as TOML within the declared limits, refused before it is parsed,
and its hyperparameters as dotted keys (``"ALGO.FIELD"``) and as nested tables, both ways.

``tomllib`` descends recursively into nested arrays and inline tables (a RecursionError deep down)
and slows down with the parts of a dotted key; :func:`read_toml` reads a regular file of at most
:data:`~rmac_mj.constraints.CONFIG_FILE_BYTES`, measures its nesting and its longest key in one pass
over the text (:func:`measure`), and parses it only within
:data:`~rmac_mj.constraints.CONFIG_NESTING` and :data:`~rmac_mj.constraints.CONFIG_KEY_LENGTH`.
:func:`nest`, :func:`flatten` and :func:`merge` turn dotted keys into tables and back (``--set`` and
sweep files alike); :func:`as_toml` writes a value back as the user wrote it, for messages.
"""

from __future__ import annotations

import dataclasses
import json
import pathlib
import sys
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

from rmac_mj import constraints
from rmac_mj.errors import UserInputError
from rmac_mj.results import files

_BARE_KEY = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-")


@dataclasses.dataclass
class Shape:
    """What :func:`measure` found: the deepest nesting of arrays and inline tables and the longest
    key in characters (a dotted key whole, quotes included; a table header's too), each with the
    line where it first occurs."""

    nesting: int = 0
    nesting_line: int = 0
    key_length: int = 0
    key_length_line: int = 0


class _Scanner:
    """One pass over TOML text: strings and comments skipped, keys told from values."""

    def __init__(self, text: str) -> None:
        self.text, self.i, self.line = text, 0, 1
        self.shape = Shape()

    def peek(self, ahead: int = 0) -> str:
        j = self.i + ahead
        return self.text[j] if j < len(self.text) else ""

    def advance(self, count: int = 1) -> None:
        self.line += self.text.count("\n", self.i, self.i + count)
        self.i += count

    def skip_blank(self, newlines: bool) -> None:
        while self.peek() in (" ", "\t", "\r") or (newlines and self.peek() == "\n"):
            self.advance()

    def skip_comment(self) -> None:
        end = self.text.find("\n", self.i)
        self.advance((len(self.text) if end < 0 else end) - self.i)

    def skip_string(self) -> None:
        """A basic, literal or multi-line string starting at the cursor."""
        quote = self.peek()
        multi = self.text.startswith(quote * 3, self.i)
        self.advance(3 if multi else 1)
        while self.i < len(self.text):
            char = self.peek()
            if char == "\\" and quote == '"':
                self.advance(2)
            elif multi and self.text.startswith(quote * 3, self.i):
                self.advance(3)
                while self.peek() == quote:  # up to two quotes may end the content
                    self.advance()
                return
            elif not multi and (char == quote or char == "\n"):
                self.advance(1 if char == quote else 0)
                return
            else:
                self.advance()

    def key(self) -> None:
        """A (dotted) key at the cursor, measured, up to '=' or a header's ']'."""
        start, end = self.i, self.i
        while True:
            self.skip_blank(newlines=False)
            if self.peek() in ('"', "'"):
                self.skip_string()
            elif self.peek() in _BARE_KEY:
                while self.peek() and self.peek() in _BARE_KEY:
                    self.advance()
            else:
                break
            end = self.i
            self.skip_blank(newlines=False)
            if self.peek() != ".":
                break
            self.advance()
        if end - start > self.shape.key_length:
            self.shape.key_length, self.shape.key_length_line = end - start, self.line

    def value(self) -> None:
        """Values up to the end of the line they end on: nesting counted, inline tables' keys read."""
        stack: list[str] = []
        while self.i < len(self.text):
            char = self.peek()
            if char == "\n" and not stack:
                return
            if char in ('"', "'"):
                self.skip_string()
            elif char == "#":
                self.skip_comment()
            elif char in "[{":
                stack.append(char)
                if len(stack) > self.shape.nesting:
                    self.shape.nesting, self.shape.nesting_line = len(stack), self.line
                self.advance()
                if char == "{":
                    self.skip_blank(newlines=True)
                    self.key()
            elif char in "]}":
                if stack:
                    stack.pop()
                self.advance()
            elif char == "," and stack and stack[-1] == "{":
                self.advance()
                self.skip_blank(newlines=True)
                self.key()
            else:
                self.advance()

    def document(self) -> Shape:
        while self.i < len(self.text):
            self.skip_blank(newlines=True)
            char = self.peek()
            if char == "#":
                self.skip_comment()
            elif char == "[":  # a table header, [name] or [[name]]
                self.advance(2 if self.peek(1) == "[" else 1)
                self.key()
                self.value()  # the rest of the line: its closing brackets, a comment
            elif char:
                self.key()
                self.value()
        return self.shape


def measure(text: str) -> Shape:
    """The nesting and the longest key of TOML ``text``, in one pass (not a parser: what is
    not TOML is left to ``tomllib`` to name)."""
    return _Scanner(text).document()


def read_toml(path: str | pathlib.Path, error: type[UserInputError]) -> dict[str, Any]:
    """The TOML document at ``path``, a sweep or ``--config`` file, read within the declared limits;
    anything else raises ``error`` (a :class:`~rmac_mj.errors.UserInputError`) naming the file
    before it is parsed, or :class:`~rmac_mj.errors.MissingInputError` when there is none."""
    path = pathlib.Path(path)
    try:
        data = files.read_bounded(path, constraints.CONFIG_FILE_BYTES, "a sweep or --config file")
    except UserInputError as refusal:
        if type(refusal) is UserInputError:  # one kind of error per file, whatever refused it
            raise error(str(refusal)) from None
        raise
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise error(f"{path}: not valid TOML: not UTF-8 text") from None
    shape = measure(text)
    for found, line, limit, what in (
        (
            shape.nesting,
            shape.nesting_line,
            constraints.CONFIG_NESTING,
            "the depth of nested arrays and inline tables",
        ),
        (
            shape.key_length,
            shape.key_length_line,
            constraints.CONFIG_KEY_LENGTH,
            "a key's length in characters",
        ),
    ):
        if found > limit.value:
            raise error(f"{path}: line {line}: " + limit.refusal(what, found))
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as failure:
        raise error(f"{path}: not valid TOML: {failure}") from None


# -- dotted keys and nested tables ------------------------------------------------------------------
def nest(flat: dict[str, Any]) -> dict[str, dict]:
    """``{"rmac.exploration.sigma": 0.5}`` -> ``{"rmac": {"exploration": {"sigma": 0.5}}}``."""
    nested: dict[str, Any] = {}
    for key, value in flat.items():
        *parents, last = key.split(".")
        node = nested
        for part in parents:
            node = node.setdefault(part, {})
        node[last] = merge(node[last], value) if isinstance(node.get(last), dict) else value
    return nested


def merge(base: dict, overrides: dict) -> dict:
    """A deep copy of ``base`` with ``overrides`` applied (nested dicts merged, other values replaced)."""
    merged = json.loads(json.dumps(base))
    for key, value in overrides.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict):
            merged[key] = merge(merged[key], value)
        else:
            merged[key] = json.loads(json.dumps(value))
    return merged


def flatten(table: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """TOML dotted keys nest (``rmac.alpha_r = 1`` is ``{"rmac": {"alpha_r": 1}}``): back to
    ``"rmac.alpha_r"``, so a quoted and a bare key mean the same. Inline tables flatten the same way
    (an override of some fields of a nested config)."""
    flat = {}
    for key, value in table.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            flat.update(flatten(value, f"{name}."))
        else:
            flat[name] = value
    return flat


def as_toml(value: Any) -> str:
    """A value as the user wrote it (TOML-like), for messages and names."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(as_toml(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {as_toml(v)}" for k, v in value.items()) + "}"
    return repr(value)
