"""Reading ntdda's two file formats: format detection, the whitespace-separated tokens of Shi's
original format, and a small parser of the XML "DDAML" format with line numbers (docs/ntdda.md
§4)."""

from __future__ import annotations

import math
import re
import warnings

import numpy as np

from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional
from .records import Format, NtddaFormatError

# ============================================================================ small helpers
def _warn(log: list, category, message: str) -> None:
    """Record the message and warn, attributing the warning to the first caller outside
    ddatai (the user's ``read_ntdda`` line)."""
    import sys

    log.append(message)
    package = str(Path(__file__).resolve().parent)
    frame, level = sys._getframe(1), 2
    while frame is not None and str(Path(frame.f_code.co_filename).resolve()).startswith(package):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, category, stacklevel=level)


_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")
_INTEGER = re.compile(r"^[+-]?\d+$")


def _to_float(token: str) -> Optional[float]:
    if not _NUMBER.match(token):
        return None
    return float(token)


def _detect_format(path: Path, text: str) -> Format:
    """ntdda sniffs the first token (docs/ntdda.md §4.1): ``<?`` is DDAML. We take the first
    non-blank characters, so a leading blank line (an error for ntdda) is accepted."""
    head = text.lstrip()
    if not head:
        raise NtddaFormatError(f"{path}: the file is empty")
    if head.startswith("<"):
        return "ddaml"
    if head.split(None, 1)[0] == "#!0xDDA-v1.5":
        raise NtddaFormatError(f"{path}, line 1: the obsolete 'extended' format #!0xDDA-v1.5 is not "
                               "supported (ntdda cannot read it either); convert it to DDAML")
    return "original"


def _read_text(path) -> tuple[Path, str]:
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise NtddaFormatError(f"{p}: cannot read the file ({exc.strerror or exc})") from None
    try:
        return p, raw.decode("utf-8")
    except UnicodeDecodeError:
        return p, raw.decode("latin-1")


# ---------------------------------------------------------------------------- text tokens
class _Tokens:
    """Whitespace-separated tokens of an original-format file, with their line numbers
    (ntdda reads these files with scanf, so line breaks carry no meaning)."""

    def __init__(self, path: Path, text: str):
        self.path = path
        self.items = [(tok, n) for n, line in enumerate(text.splitlines(), start=1) for tok in line.split()]
        self.pos = 0
        self.last_line = len(text.splitlines())

    def where(self) -> str:
        return f"line {self.items[self.pos][1]}" if self.pos < len(self.items) else f"line {self.last_line}"

    def _next(self, what: str) -> tuple[str, int]:
        if self.pos >= len(self.items):
            raise NtddaFormatError(f"{self.path}, line {self.last_line}: the file ends early "
                                   f"(truncated, or a count in the header is too large): expected {what}")
        item = self.items[self.pos]
        self.pos += 1
        return item

    def real(self, what: str) -> float:
        tok, line = self._next(what)
        x = _to_float(tok)
        if x is None:
            raise NtddaFormatError(f"{self.path}, line {line}: expected {what} (a number), got {tok!r}")
        return x

    def integer(self, what: str, minimum: int = 0) -> int:
        tok, line = self._next(what)
        if not _INTEGER.match(tok):
            raise NtddaFormatError(f"{self.path}, line {line}: expected {what} (a whole number), got {tok!r}")
        k = int(tok)
        if k < minimum:
            raise NtddaFormatError(f"{self.path}, line {line}: expected {what} >= {minimum}, got {k}")
        return k

    def index(self, what: str) -> int:
        """A 1-based type index; ntdda reads it as a real and truncates, we accept whole values."""
        tok, line = self._next(what)
        x = _to_float(tok)
        if x is None or x != math.floor(x) or x < 1:
            raise NtddaFormatError(f"{self.path}, line {line}: expected {what} (a whole number >= 1), "
                                   f"got {tok!r}")
        return int(x)

    def records(self, count: int, width: int, what: str) -> tuple[np.ndarray, tuple]:
        rows, where = [], []
        for k in range(count):
            where.append(self.where())
            rows.append([self.real(f"{what} {k + 1}: {name}") for name in _FIELDS[width]])
        return np.array(rows, dtype=float).reshape(count, width), tuple(where)

    def finish(self, what: str) -> None:
        if self.pos < len(self.items):
            tok, line = self.items[self.pos]
            raise NtddaFormatError(f"{self.path}, line {line}: unexpected extra data {tok!r} after {what} "
                                   "(does a count in the header not match the records?)")


_FIELDS = {2: ("x", "y"), 4: ("x1", "y1", "x2", "y2")}


# ---------------------------------------------------------------------------- DDAML
@dataclass(eq=False)
class _Element:
    name: str
    attrs: dict
    line: int
    children: list = field(default_factory=list)
    text_parts: list = field(default_factory=list)

    @property
    def text(self) -> str:
        return "".join(self.text_parts)

    def where(self) -> str:
        return f"line {self.line}, <{self.name}>"


def _parse_xml(path: Path, text: str) -> _Element:
    """Parse DDAML with expat, keeping line numbers. Names are matched by local name (the
    ``Berkeley:`` prefix is optional, as in ntdda); DTDs are neither fetched nor validated."""
    import xml.parsers.expat as expat

    parser = expat.ParserCreate()
    roots: list[_Element] = []
    stack: list[_Element] = []

    def start(name, attrs):
        el = _Element(name=name.split(":")[-1], attrs={k.split(":")[-1]: v for k, v in attrs.items()},
                      line=parser.CurrentLineNumber)
        (stack[-1].children if stack else roots).append(el)
        stack.append(el)

    def end(name):
        stack.pop()

    def chars(data):
        if stack:
            stack[-1].text_parts.append(data)

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = chars
    try:
        parser.Parse(text.encode("utf-8"), True)
    except expat.ExpatError as exc:
        raise NtddaFormatError(f"{path}, line {exc.lineno}: not well-formed XML "
                               f"({expat.ErrorString(exc.code)}; truncated file?)") from None
    return roots[0]


class _Xml:
    """Typed access to DDAML elements with errors that name file, line and element."""

    def __init__(self, path: Path):
        self.path = path

    def fail(self, el: _Element, what: str):
        raise NtddaFormatError(f"{self.path}, {el.where()}: {what}")

    def numbers(self, el: _Element, count: int, what: str) -> list[float]:
        toks = el.text.split()
        if len(toks) != count:
            self.fail(el, f"expected {count} numbers ({what}), got {len(toks)}: {el.text.strip()!r}")
        out = []
        for tok in toks:
            x = _to_float(tok)
            if x is None:
                self.fail(el, f"expected {count} numbers ({what}), got {tok!r}")
            out.append(x)
        return out

    def attr_real(self, el: _Element, name: str, default=None, *, minimum=None, positive=False) -> float:
        if name not in el.attrs:
            if default is None:
                self.fail(el, f"missing attribute {name}=\"...\" (a number)")
            return default
        x = _to_float(el.attrs[name].strip())
        if x is None:
            self.fail(el, f"attribute {name} must be a number, got {el.attrs[name]!r}")
        if positive and not x > 0:
            self.fail(el, f"attribute {name} must be > 0, got {el.attrs[name]!r}")
        if minimum is not None and x < minimum:
            self.fail(el, f"attribute {name} must be >= {minimum:g}, got {el.attrs[name]!r}")
        return x

    def attr_int(self, el: _Element, name: str, *, minimum: int) -> int:
        if name not in el.attrs:
            self.fail(el, f"missing attribute {name}=\"...\" (a whole number >= {minimum})")
        tok = el.attrs[name].strip()
        if not _INTEGER.match(tok) or int(tok) < minimum:
            self.fail(el, f"attribute {name} must be a whole number >= {minimum}, got {el.attrs[name]!r}")
        return int(tok)

    def attr_flag(self, el: _Element, name: str = "flag") -> bool:
        value = el.attrs.get(name)
        if value is None or value.strip().lower() not in ("yes", "no"):
            self.fail(el, f"attribute {name} must be \"yes\" or \"no\", got {value!r}")
        return value.strip().lower() == "yes"

    def value(self, el: _Element, what: str) -> float:
        return self.numbers(el, 1, what)[0]


def _section(xml: _Xml, root: _Element, name: str, other: str) -> _Element:
    """The first ``name`` element: the root itself or a child of it (ntdda looks for the
    first child of that name)."""
    if root.name == name:
        return root
    for child in root.children:
        if child.name == name:
            return child
    found = root.name if root.name == other else next((c.name for c in root.children if c.name == other), None)
    hint = (f" (found <{other}>: are the geometry and analysis files swapped?)" if found else "")
    xml.fail(root, f"expected a <{name}> element{hint}")


