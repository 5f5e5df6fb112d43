"""Server-side validation of the operator's input (docs/operator.md): the start form and the TU4 form.

Every field is checked and every problem is reported at once, as ``{field: reason}``, so the page can show
each reason next to its field. The rules are those of the data model where it has them (label: the
taxonomy; sample id, operator: :class:`scanner.scan.ScanMeta`; judged values: ``JUDGED_SCALE``); the form
adds only what a text field needs on top (numbers with an optional unit, required fields, lengths).

Numbers, units, judged values and the ambient temperature are read by :mod:`scanner.acquisition.entries`,
as the terminal scan reads them.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from scanner.acquisition.entries import (
    MASS_UNITS,
    TACK_CHOICES,
    VOLUME_METHOD_WORDS,
    VOLUME_UNITS,
    YIELDING_CHOICES,
    parse_ambient,
    parse_judged,
    parse_quantity,
    parse_volume_method,
)
from scanner.scan import ScanError, ScanMeta, check_sample_id
from taxonomy.errors import ParameterError, TexplorerError
from taxonomy.labels import LabelError
from taxonomy.table import Taxonomy, UnknownLabelError

__all__ = ["MASS_UNITS", "TACK_CHOICES", "VOLUME_METHOD_WORDS", "VOLUME_UNITS", "YIELDING_CHOICES", "FormErrors",
           "OperatorValues", "StartValues", "parse_ambient", "parse_judged", "parse_quantity",
           "validate_operator", "validate_start"]

NOTES_MAX_CHARS = 2000

_CONTROL = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")
_VALID_META = {"label": "C1S1M1P1X1", "operator": "operator", "sample_id": "sample", "scan_index": 1,
               "session_id": "session", "started": "2000-01-01T00:00:00+00:00"}
"""A meta that passes every check; one field at a time is replaced to ask the data model about it."""


@dataclass(frozen=True)
class StartValues:
    """The validated start form: who scans which sample of which material."""

    operator: str
    label: str
    sample_id: str


@dataclass(frozen=True)
class OperatorValues:
    """The validated TU4 form: judged tack and yielding, mass, volume and how it was measured, notes."""

    atk: float
    cyd: float
    mass_g: float
    volume_cm3: float
    volume_method: str
    notes: str


class FormErrors(TexplorerError, ValueError):
    """The form has invalid fields; ``errors`` maps each field name to the reason shown beside it."""

    def __init__(self, errors: Mapping[str, str]) -> None:
        self.errors = dict(errors)
        super().__init__("; ".join(f"{name}: {reason}" for name, reason in self.errors.items()))


def meta_field_error(field: str, value: object) -> str | None:
    """The data model's reason for refusing ``value`` as ``ScanMeta.<field>``, or None if it is accepted."""
    try:
        ScanMeta(**{**_VALID_META, field: value})
    except ScanError as exc:
        return exc.reason
    return None


def _label(taxonomy: Taxonomy, text: str) -> str:
    if not text or not text.strip():
        raise ParameterError("enter a material label such as C6S1M1P2X1, or pick one with the search")
    try:
        return taxonomy.check(text).format()
    except (LabelError, UnknownLabelError) as exc:
        raise ParameterError(str(exc)) from None


def _operator(text: str) -> str:
    text = (text or "").strip()
    if not text:
        raise ParameterError("enter the operator's name or initials")
    reason = meta_field_error("operator", text)
    if reason:
        raise ParameterError("1-64 printable characters without quotes, slashes or angle brackets")
    return text


def _sample_id(text: str, owner: Callable[[str], str | None], label: str | None) -> str:
    text = (text or "").strip()
    if not text:
        raise ParameterError("enter the sample id, e.g. granite-01")
    try:
        check_sample_id(text)
    except ScanError as exc:
        raise ParameterError(exc.reason) from None
    stored = owner(text)
    if stored is not None and label is not None and stored != label:
        raise ParameterError(f"sample {text} is {stored} in the database, not {label}")
    return text


def _notes(text: str) -> str:
    text = (text or "").replace("\r\n", "\n").strip()
    if len(text) > NOTES_MAX_CHARS:
        raise ParameterError(f"notes are {len(text)} characters long; at most {NOTES_MAX_CHARS} are kept")
    if _CONTROL.search(text):
        raise ParameterError("notes contain control characters; type plain text")
    return text


def _collect(checks: Mapping[str, Callable[[dict[str, object]], object]]) -> dict[str, object]:
    """Run every field check in order (a check sees the values accepted before it); raise FormErrors with
    all reasons if any fails."""
    values: dict[str, object] = {}
    errors = {}
    for name, check in checks.items():
        try:
            values[name] = check(values)
        except ValueError as exc:
            errors[name] = str(exc)
    if errors:
        raise FormErrors(errors)
    return values


def validate_start(form: Mapping[str, str], taxonomy: Taxonomy,
                   sample_owner: Callable[[str], str | None]) -> StartValues:
    """The start form (operator, label, sample id) or FormErrors naming every bad field.

    ``sample_owner(sample_id)`` returns the label the database already stores for that sample, or None;
    a sample cannot change its material.
    """
    values = _collect({
        "operator": lambda _: _operator(form.get("operator", "")),
        "label": lambda _: _label(taxonomy, form.get("label", "")),
        "sample_id": lambda accepted: _sample_id(form.get("sample_id", ""), sample_owner,
                                                 accepted.get("label")),
    })
    return StartValues(**values)


def validate_operator(form: Mapping[str, str]) -> OperatorValues:
    """The TU4 form (tack, yielding, mass, volume, method, notes) or FormErrors naming every bad field."""
    values = _collect({
        "atk": lambda _: parse_judged(form.get("atk", ""), TACK_CHOICES, what="adhesive tack"),
        "cyd": lambda _: parse_judged(form.get("cyd", ""), YIELDING_CHOICES, what="yielding"),
        "mass_g": lambda _: parse_quantity(form.get("mass_g", ""), MASS_UNITS, what="mass"),
        "volume_cm3": lambda _: parse_quantity(form.get("volume_cm3", ""), VOLUME_UNITS, what="volume"),
        "volume_method": lambda _: parse_volume_method(form.get("volume_method", "")),
        "notes": lambda _: _notes(form.get("notes", "")),
    })
    return OperatorValues(**values)


