"""What the operator types during a scan, read the same way by the web form (``gui.forms``) and the terminal
(``texplorer scan``): numbers with an optional unit and a decimal point or comma, the judged values on their
five-step scale, the ambient temperature, the volume method.

Each parser returns the value or raises ``ValueError`` with one line naming what is wrong and what is
expected, to be shown beside the field or under the prompt.

The judged values use the paper's wording (Strese et al. 2020, eq. 18 adhesive tack ATK and eq. 24
yielding CYD): five labelled choices on the scale {0, 0.25, 0.5, 0.75, 1}.
"""

from __future__ import annotations

import math
import re

from scanner.scan import JUDGED_SCALE, T_AMB_RANGE, VOLUME_METHODS
from taxonomy.errors import ParameterError

NUMBER = r"[+-]?(?:\d+(?:[.,]\d*)?|[.,]\d+)(?:[eE][+-]?\d+)?"
"""A decimal number as lab operators type it: ``12.5``, ``12,5``, ``.5``, ``2e3``."""

MASS_UNITS = ("g",)
VOLUME_UNITS = ("cm^3", "cm3", "cm³", "ml")
"""Units accepted after the number (the first is the one named in messages); 1 cm³ = 1 ml."""

TACK_CHOICES: tuple[tuple[float, str], ...] = tuple(zip(JUDGED_SCALE, (
    "not adhesive", "slightly adhesive", "uncertain", "adhesive", "strongly adhesive"), strict=True))
"""Adhesive tack ATK (paper eq. 18): value on the five-step scale and the paper's words for it."""

YIELDING_CHOICES: tuple[tuple[float, str], ...] = tuple(zip(JUDGED_SCALE, (
    "material recovers shape", "material likely recovers shape", "uncertain",
    "material unlikely recovers shape", "material stays deformed"), strict=True))
"""Yielding CYD (paper eq. 24): value on the five-step scale and the paper's words for it."""

VOLUME_METHOD_WORDS: dict[str, str] = {
    "water": "water displacement",
    "micro-pearls": "micro-pearl displacement",
    "known": "known volume (dimensions or supplier)",
}
"""Words shown for the volume methods a scan records (``scanner.scan.VOLUME_METHODS``)."""


def _typed_number(text: str, units: str) -> float | None:
    """The number of ``text`` followed by one of the ``units`` pattern (or none); None if it is not that."""
    match = re.fullmatch(rf"\s*({NUMBER})\s*(?:{units})?\s*", text or "", flags=re.IGNORECASE)
    return None if match is None else float(match.group(1).replace(",", "."))


def parse_quantity(text: str, units: tuple[str, ...], *, what: str) -> float:
    """A positive finite number typed by the operator, with an optional unit from ``units``.

    Accepts a decimal comma (``"12,5 g"``) since lab operators type either; refuses other units, signs,
    NaN and infinity with a one-line reason naming ``what`` and the expected unit.
    """
    if not text or not text.strip():
        raise ParameterError(f"enter the {what} in {units[0]}")
    value = _typed_number(text, "|".join(re.escape(u) for u in units))
    if value is None:
        raise ParameterError(f"{text.strip()[:40]!r} is not a number in {units[0]}")
    if not math.isfinite(value) or value <= 0:
        number = re.match(rf"\s*({NUMBER})", text).group(1)
        raise ParameterError(f"the {what} must be positive (in {units[0]}), got {number}")
    return value


def parse_judged(text: str, choices: tuple[tuple[float, str], ...], *, what: str) -> float:
    """One of the five judged values; anything else (missing, off the scale, not a number) is refused."""
    words = ", ".join(f'"{word}"' for _, word in choices)
    if not text or not text.strip():
        raise ParameterError(f"choose the {what}: one of {words}")
    try:
        value = float(text.strip().replace(",", "."))
    except ValueError:
        raise ParameterError(f"{text.strip()[:20]!r} is not one of the five {what} choices "
                         f"{', '.join(f'{v:g}' for v, _ in choices)}") from None
    if value not in {v for v, _ in choices}:
        raise ParameterError(f"{text.strip()[:20]} is not on the five-step scale 0, 0.25, 0.5, 0.75, 1 ({words})")
    return value


def parse_ambient(text: str) -> float:
    """The ambient temperature in degC, within the MLX90614's range (``scanner.scan.T_AMB_RANGE``)."""
    if not text or not text.strip():
        raise ParameterError("enter the ambient temperature in degC")
    value = _typed_number(text, "°?C|degC")
    if value is None:
        raise ParameterError(f"{text.strip()[:40]!r} is not a temperature in degC")
    low, high = T_AMB_RANGE
    if not low <= value <= high:
        raise ParameterError(f"{value:g} degC is outside the sensor's range {low:g} to {high:g} degC")
    return value


def parse_volume_method(text: str) -> str:
    """One of ``scanner.scan.VOLUME_METHODS``, or an unambiguous start of one (``w`` = water), any case."""
    typed = (text or "").strip().casefold()
    found = [method for method in VOLUME_METHODS if typed and method.startswith(typed)]
    if len(found) != 1:
        words = ", ".join(f"{method} ({VOLUME_METHOD_WORDS.get(method, method)})" for method in VOLUME_METHODS)
        raise ParameterError(f"choose how the volume was measured: {words}")
    return found[0]
