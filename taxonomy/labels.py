"""Material labels of the C/S/M/P/X taxonomy (docs/taxonomy.md; Strese et al. 2020, section II-A).

A label such as ``C6S1M1P2X1`` names a major class ``C`` (C6 stone), a sub-class ``S`` of that class
(S1 igneous), a material ``M`` of that sub-class (M1 granite), a processing shape ``P`` (P2 polished) and an
extra attribute ``X`` (X1 plain). C, S and M are hierarchical: S1 means something different under every C,
M1 under every C/S. P and X are global code lists. The names behind the codes live in the taxonomy table
(:mod:`taxonomy.table`); this module only knows the syntax.

Classification happens at three levels (paper section V-C): coarse = C, medium = C+S, fine = the full label.
"""

from __future__ import annotations

import functools
import operator
import re
import reprlib
from dataclasses import dataclass
from typing import Any, NoReturn

from taxonomy.errors import TexplorerError

LEVELS = ("coarse", "medium", "fine")
"""Classification levels, from the major class alone to the full material label."""

LABEL_PARTS = "CSMPX"
"""The letters of a label, in the order they are written."""

MAX_DIGITS = 3
"""Longest number a code may carry; the ``.mat`` schema (``scanner.scan``) accepts labels up to C999..X999."""

_EXAMPLE = {"C": 6, "S": 1, "M": 1, "P": 2, "X": 1}
_NUMBER = re.compile(r"[+-]?[0-9]*")
_UPPER = str.maketrans("csmpx", "CSMPX")
_MAJOR = re.compile(r"C[1-9][0-9]*")
_REPR = reprlib.Repr()
_REPR.maxstring = _REPR.maxother = 60
_shown = _REPR.repr
"""``repr`` cut short, so that even a hostile input gives a one-line message."""


class LabelError(TexplorerError, ValueError):
    """Text or numbers that do not form a C/S/M/P/X label or code; the message says what is wrong."""


class _Malformed(TexplorerError):
    """The reason a code is malformed, before it is phrased as a :class:`LabelError`."""


def _pattern(letters: str) -> str:
    return "".join(f"{letter}<{letter.lower()}>" for letter in letters)


def _example(letters: str) -> str:
    return "".join(f"{letter}{_EXAMPLE[letter]}" for letter in letters)


def _misplaced(found: str, written: str, letter: str, position: int) -> str:
    if found.isspace():
        return f"whitespace at character {position + 1}"
    if found in LABEL_PARTS:
        return (f"{found}<number> where {letter}<number> was expected, "
                f"parts come in the order {', '.join(LABEL_PARTS)}")
    return f"unexpected {written!r} at character {position + 1} where {letter}<number> was expected"


def _check_number(letter: str, number: str, after: str) -> int:
    digits = number.lstrip("+-")
    if not digits:
        return _fail(f"{letter} has no number" + (f", found {after[:1]!r}" if after else ""))
    if number.startswith("-"):
        return _fail(f"negative code {letter}{number}, codes are positive integers")
    if number.startswith("+"):
        return _fail(f"signed code {letter}{number}, write {letter}{digits}")
    if not digits.strip("0"):
        return _fail(f"zero code {letter}{digits}, codes start at 1")
    if digits.startswith("0"):
        return _fail(f"leading zero in {letter}{digits}, write {letter}{digits.lstrip('0')}")
    if len(digits) > MAX_DIGITS:
        return _fail(f"code {letter} has {len(digits)} digits, at most {MAX_DIGITS} are allowed")
    return int(digits)


def _fail(reason: str) -> NoReturn:
    raise _Malformed(reason)


def _read_numbers(text: str, letters: str) -> tuple[int, ...]:
    """Walk ``text`` letter by letter; the first deviation from ``letters`` is the reported reason."""
    upper = text.translate(_UPPER)
    numbers = []
    position = 0
    for letter in letters:
        if position == len(text):
            raise _Malformed(f"missing {letter}<number>")
        if upper[position] != letter:
            raise _Malformed(_misplaced(upper[position], text[position], letter, position))
        number = _NUMBER.match(text, position + 1)
        numbers.append(_check_number(letter, number.group(), text[number.end():]))
        position = number.end()
    if position < len(text):
        raise _Malformed(f"trailing {_shown(text[position:])} after the {letters[-1]} code")
    return tuple(numbers)


def parse_code(text: Any, letters: str = LABEL_PARTS) -> tuple[int, ...]:
    """Numbers of a code written with ``letters``: ``parse_code("C6S1", "CS") == (6, 1)``.

    Surrounding whitespace is ignored and the letters C, S, M, P, X may be lower case (operators type
    labels into forms; the numbers, not the case, carry the meaning). Codes are positive integers of at
    most :data:`MAX_DIGITS` digits without sign or leading zero, so every code has exactly one spelling.

    Raises
    ------
    LabelError
        One line naming the text and the first thing wrong with it.
    """
    noun = "label" if letters == LABEL_PARTS else f"{_pattern(letters)} code"
    expected = f"(expected {_pattern(letters)}, e.g. {_example(letters)})"
    if not isinstance(text, str):
        raise LabelError(f"{_shown(text)} is not a {noun}: got {type(text).__name__} instead of text {expected}")
    stripped = text.strip()
    if not stripped:
        raise LabelError(f"{_shown(text)} is not a {noun}: empty {expected}")
    try:
        return _read_numbers(stripped, letters)
    except _Malformed as reason:
        raise LabelError(f"{_shown(text)} is not a {noun}: {reason} {expected}") from None


def parse_prefix(text: Any) -> str:
    """Canonical text of a label or class prefix used as a filter: ``"c6" -> "C6"``, ``" C6s1 " -> "C6S1"``.

    A prefix is the first one to five parts of a label (C, CS, CSM, CSMP or CSMPX), written as
    :func:`parse_code` reads codes (lower-case letters allowed, numbers without sign or leading zero).

    Raises
    ------
    LabelError
        One line naming the text, what is wrong and the valid forms.
    """
    stripped = text.strip() if isinstance(text, str) else text
    parts = sum(ch.isalpha() for ch in stripped) if isinstance(stripped, str) else 0
    letters = LABEL_PARTS[:min(max(parts, 1), len(LABEL_PARTS))]
    try:
        return format_code(letters, parse_code(stripped, letters))
    except LabelError as exc:
        reason = str(exc).split(": ", 1)[-1].rsplit(" (expected", 1)[0]
        raise LabelError(f"{_shown(text)} is not a label or class prefix: {reason} (expected C<n>, C<n>S<n>, "
                         f"... up to a full label, e.g. C6, C6S1 or {_example(LABEL_PARTS)})") from None


def major_class(code: str) -> str:
    """The major class C of a class code at any level: ``"C6S1M1P2X1"`` and ``"C6S1"`` give ``"C6"``.

    Raises
    ------
    LabelError
        ``code`` does not start with a major class code C<c>.
    """
    match = _MAJOR.match(code) if isinstance(code, str) else None
    if match is None:
        raise LabelError(f"class {_shown(code)} does not start with a major class code C<c>")
    return match.group()


def format_code(letters: str, numbers: tuple[int, ...]) -> str:
    """Canonical text of a code: ``format_code("CS", (6, 1)) == "C6S1"``."""
    return "".join(f"{letter}{number}" for letter, number in zip(letters, numbers, strict=True))


def check_level(level: Any) -> str:
    """Return ``level`` if it is one of :data:`LEVELS`, else raise :class:`LabelError` (a ValueError) naming
    the allowed ones."""
    if level not in LEVELS:
        raise LabelError(f"unknown classification level {level!r} (expected one of {', '.join(LEVELS)})")
    return level


def _positive_code(letter: str, value: Any) -> int:
    if isinstance(value, bool):
        raise LabelError(f"label code {letter} must be an integer, got {value!r}")
    try:
        number = operator.index(value)
    except TypeError:
        raise LabelError(f"label code {letter} must be an integer, got {value!r}") from None
    if not 1 <= number < 10**MAX_DIGITS:
        raise LabelError(f"label code {letter}{number} is out of range (1 to {10**MAX_DIGITS - 1})")
    return number


@dataclass(frozen=True, order=True)
class Label:
    """One material label ``C<c>S<s>M<m>P<p>X<x>``; labels sort by the integer tuple (c, s, m, p, x).

    Parameters
    ----------
    c, s, m, p, x : int
        Major class, sub-class, material, processing shape and extra attribute, each 1 to 999.

    Examples
    --------
    >>> label = Label.parse("C6S1M1P2X1")
    >>> label.at("medium"), str(label)
    ('C6S1', 'C6S1M1P2X1')
    """

    c: int
    s: int
    m: int
    p: int
    x: int

    def __post_init__(self) -> None:
        for letter in LABEL_PARTS:
            name = letter.lower()
            object.__setattr__(self, name, _positive_code(letter, getattr(self, name)))

    @classmethod
    def parse(cls, text: str | Label) -> Label:
        """The label written in ``text`` (a :class:`Label` is returned as is); see :func:`parse_code`."""
        if isinstance(text, Label):
            return text
        return _parse_label(text) if cls is Label and isinstance(text, str) else cls(*parse_code(text, LABEL_PARTS))

    def numbers(self) -> tuple[int, int, int, int, int]:
        """The integer tuple (c, s, m, p, x)."""
        return (self.c, self.s, self.m, self.p, self.x)

    def format(self) -> str:
        """Canonical text, e.g. ``"C6S1M1P2X1"``."""
        return format_code(LABEL_PARTS, self.numbers())

    def __str__(self) -> str:
        return self.format()

    def codes(self) -> tuple[str, str, str, str, str]:
        """The five table codes of the label: ``("C6", "C6S1", "C6S1M1", "P2", "X1")``."""
        return (f"C{self.c}", f"C{self.c}S{self.s}", f"C{self.c}S{self.s}M{self.m}", f"P{self.p}", f"X{self.x}")

    def at(self, level: str) -> str:
        """Class code at a classification level: coarse ``"C6"``, medium ``"C6S1"``, fine the full label."""
        check_level(level)
        if level == "coarse":
            return f"C{self.c}"
        if level == "medium":
            return f"C{self.c}S{self.s}"
        return self.format()


@functools.lru_cache(maxsize=4096)
def _parse_label(text: str) -> Label:
    """:meth:`Label.parse` of a string, remembered: labels are immutable, and an evaluation's reports parse
    the same few class codes thousands of times."""
    return Label(*parse_code(text, LABEL_PARTS))
