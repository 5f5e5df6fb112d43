"""Labels, the shipped taxonomy table and lab extensions (docs/taxonomy.md)."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
import pytest

import taxonomy
from taxonomy import (
    ENV_VAR,
    LEVELS,
    SHIPPED_TABLE,
    Entry,
    Label,
    LabelError,
    Taxonomy,
    TaxonomyError,
    UnknownLabelError,
    load_taxonomy,
    parse_code,
    read_table,
)

SIMULATOR_LABELS = [
    "C1S1M1P4X1", "C1S1M2P4X2", "C1S1M3P4X1", "C1S2M1P4X1", "C1S3M1P4X1",
    "C2S1M1P1X1", "C2S2M1P1X1", "C2S2M2P6X1", "C2S3M1P1X1", "C2S4M1P1X1", "C2S4M2P1X1",
    "C3S1M1P2X1", "C3S1M2P1X1", "C3S2M1P7X1", "C3S2M2P7X1", "C3S3M1P1X1", "C3S4M2P1X1",
    "C4S1M1P2X1", "C4S3M1P1X1", "C5S1M1P2X1", "C5S1M1P9X1",
    "C6S1M1P2X1", "C6S1M1P3X1", "C6S2M1P1X1", "C6S3M1P2X1",
    "C7S1M1P8X1", "C7S1M1P5X1", "C7S2M1P1X1", "C7S3M1P2X1",
    "C8S1M1P6X1", "C8S2M1P1X3", "C8S2M1P1X4",
]
"""The default library of the simulator, agreed with the taxonomy table."""

EXPECTED = "(expected C<c>S<s>M<m>P<p>X<x>, e.g. C6S1M1P2X1)"


@pytest.fixture(autouse=True)
def _no_lab_extension(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(ENV_VAR, raising=False)


@pytest.fixture(scope="module")
def shipped() -> Taxonomy:
    return Taxonomy.from_csv(SHIPPED_TABLE)


def write(path: Path, *lines: str) -> Path:
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


# ---------------------------------------------------------------- labels


@pytest.mark.parametrize(("text", "numbers"), [
    ("C6S1M1P2X1", (6, 1, 1, 2, 1)),
    ("C1S1M1P1X1", (1, 1, 1, 1, 1)),
    ("C3S4M2P5X1", (3, 4, 2, 5, 1)),
    ("C12S3M45P6X7", (12, 3, 45, 6, 7)),
    ("C1S10M100P11X2", (1, 10, 100, 11, 2)),
    ("C999S999M999P999X999", (999, 999, 999, 999, 999)),
    ("C8S2M1P1X3", (8, 2, 1, 1, 3)),
    ("C10S20M30P40X50", (10, 20, 30, 40, 50)),
])
def test_parse_and_format_round_trip(text: str, numbers: tuple[int, ...]) -> None:
    label = Label.parse(text)
    assert label == Label(*numbers)
    assert (label.c, label.s, label.m, label.p, label.x) == numbers
    assert label.format() == text
    assert str(label) == text
    assert Label.parse(str(label)) == label


@pytest.mark.parametrize("text", [" C6S1M1P2X1", "C6S1M1P2X1\n", "\tc6s1m1p2x1  ", "c6S1m1P2x1"])
def test_parse_strips_whitespace_and_normalises_lower_case(text: str) -> None:
    label = Label.parse(text)
    assert label == Label(6, 1, 1, 2, 1)
    assert str(label) == "C6S1M1P2X1"


def test_parse_returns_a_label_unchanged() -> None:
    label = Label(6, 1, 1, 2, 1)
    assert Label.parse(label) is label


def test_missing_part_message_is_exactly_as_documented() -> None:
    with pytest.raises(LabelError) as caught:
        Label.parse("C6S1M1P2")
    assert str(caught.value) == f"'C6S1M1P2' is not a label: missing X<number> {EXPECTED}"


@pytest.mark.parametrize(("text", "reason"), [
    ("", "empty"),
    ("   ", "empty"),
    ("C6S1M1P2", "missing X<number>"),
    ("C6", "missing S<number>"),
    ("C6S1M1", "missing P<number>"),
    ("S1M1P2X1", "S<number> where C<number> was expected, parts come in the order C, S, M, P, X"),
    ("C6S1M1X1", "X<number> where P<number> was expected, parts come in the order C, S, M, P, X"),
    ("C6M1S1P2X1", "M<number> where S<number> was expected, parts come in the order C, S, M, P, X"),
    ("X1P2M1S1C6", "X<number> where C<number> was expected, parts come in the order C, S, M, P, X"),
    ("C6S1M1P2X1junk", "trailing 'junk' after the X code"),
    ("C6S1M1P2X1X1", "trailing 'X1' after the X code"),
    ("C6S1M1P2X1.5", "trailing '.5' after the X code"),
    ("C6SAM1P2X1", "S has no number, found 'A'"),
    ("C6S1M1P2X", "X has no number"),
    ("CxS1M1P2X1", "C has no number, found 'x'"),
    ("Q6S1M1P2X1", "unexpected 'Q' at character 1 where C<number> was expected"),
    ("6S1M1P2X1", "unexpected '6' at character 1 where C<number> was expected"),
    ("C6.0S1M1P2X1", "unexpected '.' at character 3 where S<number> was expected"),
    ("C6 S1 M1 P2 X1", "whitespace at character 3"),
    ("C0S1M1P1X1", "zero code C0, codes start at 1"),
    ("C6S1M0P2X1", "zero code M0, codes start at 1"),
    ("C6S1M1P2X00", "zero code X00, codes start at 1"),
    ("C-1S1M1P1X1", "negative code C-1, codes are positive integers"),
    ("C6S1M1P-2X1", "negative code P-2, codes are positive integers"),
    ("C+6S1M1P2X1", "signed code C+6, write C6"),
    ("C06S1M1P2X1", "leading zero in C06, write C6"),
    ("C1000S1M1P1X1", "code C has 4 digits, at most 3 are allowed"),
])
def test_malformed_text_names_the_text_and_the_reason(text: str, reason: str) -> None:
    with pytest.raises(LabelError) as caught:
        Label.parse(text)
    message = str(caught.value)
    assert message == f"{text!r} is not a label: {reason} {EXPECTED}"
    assert isinstance(caught.value, ValueError)


@pytest.mark.parametrize(("value", "shown", "type_name"), [
    (None, "None", "NoneType"), (61121, "61121", "int"), (6.0, "6.0", "float"),
    (b"C6S1M1P2X1", "b'C6S1M1P2X1'", "bytes"),
])
def test_non_text_is_not_a_label(value: object, shown: str, type_name: str) -> None:
    with pytest.raises(LabelError) as caught:
        Label.parse(value)  # type: ignore[arg-type]
    assert str(caught.value) == f"{shown} is not a label: got {type_name} instead of text {EXPECTED}"


def test_hostile_long_input_gives_a_short_one_line_message() -> None:
    text = "C1" + "2" * 5000 + "S1M1P1X1\n" * 3
    with pytest.raises(LabelError) as caught:
        Label.parse(text)
    message = str(caught.value)
    assert "\n" not in message
    assert len(message) < 250
    assert "code C has 5001 digits, at most 3 are allowed" in message


@pytest.mark.parametrize("numbers", [(0, 1, 1, 1, 1), (1, 1, 1, 1, -3), (1000, 1, 1, 1, 1)])
def test_constructor_rejects_codes_out_of_range(numbers: tuple[int, ...]) -> None:
    with pytest.raises(LabelError, match="out of range"):
        Label(*numbers)


@pytest.mark.parametrize("value", [True, 1.0, "1", None])
def test_constructor_rejects_non_integers(value: object) -> None:
    with pytest.raises(LabelError, match="label code S must be an integer"):
        Label(6, value, 1, 2, 1)  # type: ignore[arg-type]


def test_constructor_accepts_numpy_integers_and_stores_python_ints() -> None:
    label = Label(*np.array([6, 1, 1, 2, 1], dtype=np.int64))
    assert label == Label(6, 1, 1, 2, 1)
    assert all(type(number) is int for number in label.numbers())


def test_labels_are_frozen_and_hashable() -> None:
    label = Label(6, 1, 1, 2, 1)
    with pytest.raises(dataclasses.FrozenInstanceError):
        label.c = 7  # type: ignore[misc]
    assert {label: "granite"}[Label.parse("C6S1M1P2X1")] == "granite"


def test_labels_sort_by_the_integer_tuple_not_the_text() -> None:
    texts = ["C10S1M1P1X1", "C2S1M1P1X10", "C2S1M1P1X2", "C2S10M1P1X1", "C2S9M1P1X1", "C1S1M1P1X1"]
    ordered = [str(label) for label in sorted(Label.parse(text) for text in texts)]
    assert ordered == ["C1S1M1P1X1", "C2S1M1P1X2", "C2S1M1P1X10", "C2S9M1P1X1", "C2S10M1P1X1", "C10S1M1P1X1"]


@pytest.mark.parametrize(("text", "coarse", "medium"), [
    ("C6S1M1P2X1", "C6", "C6S1"),
    ("C12S3M45P6X7", "C12", "C12S3"),
    ("C1S10M2P1X1", "C1", "C1S10"),
])
def test_at_every_level(text: str, coarse: str, medium: str) -> None:
    label = Label.parse(text)
    assert LEVELS == ("coarse", "medium", "fine")
    assert [label.at(level) for level in LEVELS] == [coarse, medium, text]


@pytest.mark.parametrize("level", ["C", "Fine", "", None])
def test_at_rejects_unknown_levels_naming_the_allowed_ones(level: object) -> None:
    with pytest.raises(ValueError, match="expected one of coarse, medium, fine"):
        Label(6, 1, 1, 2, 1).at(level)  # type: ignore[arg-type]


def test_codes_are_the_five_table_codes() -> None:
    assert Label(12, 3, 45, 6, 7).codes() == ("C12", "C12S3", "C12S3M45", "P6", "X7")


def test_parse_code_for_partial_codes() -> None:
    assert parse_code("C6S1", "CS") == (6, 1)
    assert parse_code("p12", "P") == (12,)
    with pytest.raises(LabelError, match=r"^'C6' is not a C<c>S<s> code: missing S<number> \(expected C<c>S<s>"):
        parse_code("C6", "CS")


# ---------------------------------------------------------------- the shipped table


@pytest.mark.parametrize("text", SIMULATOR_LABELS)
def test_every_simulator_label_is_known(shipped: Taxonomy, text: str) -> None:
    assert shipped.check(text) == Label.parse(text)
    assert text in shipped


def test_eight_major_classes_with_agreed_names(shipped: Taxonomy) -> None:
    names = {entry.code: entry.name for entry in shipped.entries("C")}
    assert names == {"C1": "wood", "C2": "biodegradable organic", "C3": "plastic", "C4": "ceramic",
                     "C5": "glass", "C6": "stone", "C7": "metal", "C8": "composite"}


def test_every_class_has_sub_classes_and_every_sub_class_has_materials(shipped: Taxonomy) -> None:
    parents_of_s = {entry.parent for entry in shipped.entries("S")}
    parents_of_m = {entry.parent for entry in shipped.entries("M")}
    assert parents_of_s == {entry.code for entry in shipped.entries("C")}
    assert parents_of_m == {entry.code for entry in shipped.entries("S")}


def test_at_least_forty_materials(shipped: Taxonomy) -> None:
    assert len(shipped.materials()) >= 40
    assert len({material.name for material in shipped.materials()}) >= 40


def test_agreed_global_codes(shipped: Taxonomy) -> None:
    p = {entry.code: entry.name for entry in shipped.entries("P")}
    x = {entry.code: entry.name for entry in shipped.entries("X")}
    assert [p[f"P{i}"] for i in range(1, 10)] == ["natural", "polished", "pointed", "planed", "perforated",
                                                  "woven", "foamed", "brushed", "sandblasted"]
    assert [x[f"X{i}"] for i in range(1, 7)] == ["plain", "varnished", "coarse grain", "fine grain", "printed",
                                                 "painted"]


@pytest.mark.parametrize(("code", "name"), [
    ("C6S1", "igneous stone"), ("C6S1M1", "granite"), ("C3S4M2", "epoxy"), ("C1S1", "hardwood"),
    ("C1S2", "softwood"), ("C1S1M1", "oak"), ("C1S2M1", "pine"), ("C1S1M3", "balsa"), ("C7S2M1", "aluminium"),
    ("C7S3M1", "copper"), ("C8S2M1", "sandpaper"), ("P2", "polished"), ("P3", "pointed"),
])
def test_names_from_the_paper_and_the_agreed_list(shipped: Taxonomy, code: str, name: str) -> None:
    assert shipped.name(code) == name


def test_describe_and_names(shipped: Taxonomy) -> None:
    assert shipped.describe("C6S1M1P2X1") == "granite (igneous stone, stone), polished, plain"
    assert shipped.describe(Label(6, 1, 1, 3, 1)) == "granite (igneous stone, stone), pointed, plain"
    assert shipped.names("C8S2M1P1X3") == ("composite", "abrasive", "sandpaper", "natural", "coarse grain")
    assert shipped.names("C8S2M1P1X4").x == "fine grain"


@pytest.mark.parametrize(("text", "message"), [
    ("C9S1M1P1X1", "C9S1M1P1X1: there is no major class C9"),
    ("C6S9M1P2X1", "C6S9M1P2X1: stone has no sub-class S9"),
    ("C6S1M99P2X1", "C6S1M99P2X1: igneous stone has no material M99"),
    ("C6S1M1P99X1", "C6S1M1P99X1: there is no processing shape P99"),
    ("C6S1M1P2X99", "C6S1M1P2X99: there is no extra attribute X99"),
    ("C6S9M99P99X99", "C6S9M99P99X99: stone has no sub-class S9"),
])
def test_unknown_codes_at_each_level(shipped: Taxonomy, text: str, message: str) -> None:
    with pytest.raises(UnknownLabelError) as caught:
        shipped.check(text)
    assert str(caught.value) == message
    assert isinstance(caught.value, ValueError)
    assert text not in shipped


def test_check_reports_malformed_labels_as_label_errors(shipped: Taxonomy) -> None:
    with pytest.raises(LabelError, match="missing X<number>"):
        shipped.check("C6S1M1P2")
    assert "C6S1M1P2" not in shipped
    assert None not in shipped


def test_name_of_level_codes(shipped: Taxonomy) -> None:
    label = Label.parse("C6S1M1P2X1")
    assert [shipped.name(label.at(level)) for level in LEVELS] == [
        "stone", "igneous stone", "granite (igneous stone, stone), polished, plain"]
    with pytest.raises(UnknownLabelError, match="^C6S9: stone has no sub-class S9$"):
        shipped.name("C6S9")
    with pytest.raises(UnknownLabelError, match="^C9S1: there is no major class C9$"):
        shipped.name("C9S1")


def test_shipped_file_is_in_canonical_form(tmp_path: Path, shipped: Taxonomy) -> None:
    written = shipped.to_csv(tmp_path / "taxonomy.csv")
    assert written.read_text(encoding="utf-8") == SHIPPED_TABLE.read_text(encoding="utf-8")


def test_the_table_is_read_only(shipped: Taxonomy) -> None:
    entry = shipped.entries()[0]
    with pytest.raises(dataclasses.FrozenInstanceError):
        entry.name = "timber"  # type: ignore[misc]
    with pytest.raises(TypeError):
        shipped._entries["C1"] = entry  # type: ignore[index]
    assert isinstance(shipped.entries(), tuple)


# ---------------------------------------------------------------- a small table with known answers


@pytest.fixture
def small(tmp_path: Path) -> Taxonomy:
    path = write(tmp_path / "small.csv",
                 "kind,code,name,description",
                 "C,C10,lab class,",
                 "S,C10S1,lab boards,",
                 "M,C10S1M1,oak veneer board,",
                 "C,C2,organic,",
                 "S,C2S1,leather,",
                 "M,C2S1M1,suede,",
                 "C,C1,wood,",
                 "S,C1S1,hardwood,",
                 "M,C1S1M10,teak,",
                 "M,C1S1M1,oak,",
                 "M,C1S1M2,beech,\"planed, then oiled\"",
                 "P,P1,natural,",
                 "X,X1,plain,")
    return Taxonomy.from_csv(path)


def codes(materials: list[taxonomy.MaterialChoice]) -> list[str]:
    return [material.code for material in materials]


def test_materials_in_natural_order(small: Taxonomy) -> None:
    assert codes(small.materials()) == ["C1S1M1", "C1S1M2", "C1S1M10", "C2S1M1", "C10S1M1"]
    first = small.materials()[0]
    assert (first.name, first.subclass, first.major) == ("oak", "hardwood", "wood")
    assert str(first) == "C1S1M1 oak (hardwood, wood)"
    assert first.label() == Label(1, 1, 1, 1, 1)
    assert first.label(p=4, x=2) == Label(1, 1, 1, 4, 2)


@pytest.mark.parametrize(("query", "expected"), [
    ("C1", ["C1S1M1", "C1S1M2", "C1S1M10"]),
    ("c1s1", ["C1S1M1", "C1S1M2", "C1S1M10"]),
    ("C1S1M1", ["C1S1M1"]),
    ("C1S1M1P4X2", ["C1S1M1"]),
    ("C1S1M1P", ["C1S1M1"]),
    ("C10", ["C10S1M1"]),
    ("C1S", ["C1S1M1", "C1S1M2", "C1S1M10"]),
    ("C", ["C1S1M1", "C1S1M2", "C1S1M10", "C2S1M1", "C10S1M1"]),
    ("C3", []),
    ("oak", ["C1S1M1", "C10S1M1"]),
    (" OAK ", ["C1S1M1", "C10S1M1"]),
    ("wood", ["C1S1M1", "C1S1M2", "C1S1M10"]),
    ("leather", ["C2S1M1"]),
    ("board", ["C10S1M1"]),
    ("", ["C1S1M1", "C1S1M2", "C1S1M10", "C2S1M1", "C10S1M1"]),
    ("marble", []),
])
def test_search(small: Taxonomy, query: str, expected: list[str]) -> None:
    assert codes(small.search(query)) == expected


def test_search_rejects_non_text(small: Taxonomy) -> None:
    with pytest.raises(TypeError, match="search text must be a string"):
        small.search(None)  # type: ignore[arg-type]


def test_descriptions_with_commas_survive(small: Taxonomy) -> None:
    assert small.entries("M")[1].description == "planed, then oiled"


# ---------------------------------------------------------------- lab extensions


def test_extension_adds_codes(tmp_path: Path, shipped: Taxonomy) -> None:
    extension = write(tmp_path / "lab.csv",
                      "kind,code,name,description",
                      "C,C9,lab material,materials only this lab has",
                      "S,C9S1,mycelium,",
                      "M,C9S1M1,mycelium leather,grown",
                      "M,C6S1M7,diorite,",
                      "P,P17,laser engraved,",
                      "X,X12,waxed twice,",
                      "C,C6, Stone ,same name in other case and spacing")
    merged = load_taxonomy(extension)
    assert len(merged) == len(shipped) + 6
    assert merged.describe("C9S1M1P17X12") == "mycelium leather (mycelium, lab material), laser engraved, waxed twice"
    assert merged.describe("C6S1M7P2X1") == "diorite (igneous stone, stone), polished, plain"
    assert merged.name("C6") == "stone"
    assert all(text in merged for text in SIMULATOR_LABELS)
    assert "C9S1M1P17X12" not in shipped


def test_extensions_may_come_in_any_order(tmp_path: Path) -> None:
    materials = write(tmp_path / "a.csv", "kind,code,name,description", "M,C9S1M1,mycelium leather,")
    classes = write(tmp_path / "b.csv", "kind,code,name,description", "C,C9,lab material,", "S,C9S1,mycelium,")
    merged = load_taxonomy([materials, classes])
    assert merged.name("C9S1M1") == "mycelium leather"


def test_conflicting_extension_names_both_files_and_the_code(tmp_path: Path) -> None:
    extension = write(tmp_path / "lab.csv", "kind,code,name,description", "X,X12,rusty,", "M,C6S1M1,basalt,")
    with pytest.raises(TaxonomyError) as caught:
        load_taxonomy(extension)
    message = str(caught.value)
    assert "C6S1M1" in message and "'granite'" in message and "'basalt'" in message
    assert str(SHIPPED_TABLE) in message
    assert f"{extension} line 3" in message


def test_conflict_between_two_extensions(tmp_path: Path) -> None:
    first = write(tmp_path / "one.csv", "kind,code,name,description", "P,P20,etched,")
    second = write(tmp_path / "two.csv", "kind,code,name,description", "P,P20,engraved,")
    with pytest.raises(TaxonomyError) as caught:
        load_taxonomy([first, second])
    assert str(caught.value) == (f"taxonomy code P20 is 'etched' in {first} line 2 "
                                 f"but 'engraved' in {second} line 2")


@pytest.mark.parametrize(("row", "missing"), [("M,C9S1M1,mycelium leather,", "C9S1"),
                                              ("S,C9S1,mycelium,", "C9"),
                                              ("M,C6S9M1,andesite,", "C6S9")])
def test_extension_code_without_parent(tmp_path: Path, row: str, missing: str) -> None:
    extension = write(tmp_path / "lab.csv", "kind,code,name,description", row)
    with pytest.raises(TaxonomyError) as caught:
        load_taxonomy(extension)
    code = row.split(",")[1]
    assert str(caught.value).startswith(f"{extension} line 2: ")
    assert f"{code} (" in str(caught.value)
    assert str(caught.value).endswith(f"has no parent {missing} in any taxonomy file")


@pytest.mark.parametrize(("lines", "line", "reason"), [
    (["kind,code,name,description", "M,C6S1M7,diorite"], 2, "expected 4 fields (kind,code,name,description), found 3"),
    (["kind,code,name,description", "M,C6S1M7,diorite,,"], 2, "expected 4 fields"),
    (["kind,code,name,description", "Q,Q1,diorite,"], 2, "kind 'Q' is not one of C, S, M, P, X"),
    (["kind,code,name,description", "S,C6,andesite,"], 2, "'C6' is not a C<c>S<s> code: missing S<number>"),
    (["kind,code,name,description", "P,X3,etched,"], 2, "X<number> where P<number> was expected"),
    (["kind,code,name,description", "M,C6S1M0,andesite,"], 2, "zero code M0"),
    (["kind,code,name,description", "M,C6S1M7, ,"], 2, "material C6S1M7 has no name"),
    (["kind,code,name,description", "", "P,P20,etched,", "", "P,P21"], 5, "expected 4 fields"),
    (["kind,code,name,description", 'P,P20,etched,"two', 'lines"', "P,P21,x"], 4, "expected 4 fields"),
    (["kind,code,name,description", 'P,P20,etched,"unclosed'], 2, "broken CSV"),
    (["kind,code,name,description", 'P,P20,etched,"a"b'], 2, "broken CSV"),
    (["code,kind,name,description", "P,P20,etched,"], 1, "header must be kind,code,name,description"),
    (["", "P,P20,etched,"], 2, "header must be kind,code,name,description, found P,P20,etched,"),
])
def test_broken_csv_line_names_file_and_line(tmp_path: Path, lines: list[str], line: int, reason: str) -> None:
    extension = write(tmp_path / "lab.csv", *lines)
    with pytest.raises(TaxonomyError) as caught:
        load_taxonomy(extension)
    message = str(caught.value)
    assert message.startswith(f"{extension} line {line}: ")
    assert reason in message
    assert "\n" not in message


def test_empty_missing_and_non_utf8_files(tmp_path: Path) -> None:
    empty = tmp_path / "empty.csv"
    empty.write_text("", encoding="utf-8")
    with pytest.raises(TaxonomyError, match="empty, expected the header kind,code,name,description"):
        read_table(empty)
    with pytest.raises(TaxonomyError, match="does not exist"):
        load_taxonomy(tmp_path / "nowhere.csv")
    latin = tmp_path / "latin.csv"
    latin.write_bytes("kind,code,name,description\nM,C6S1M7,diorite,pr\u00e9cis\n".encode("latin-1"))
    with pytest.raises(TaxonomyError, match=r"latin\.csv: not UTF-8 text \(byte 46\)"):
        read_table(latin)


def test_byte_order_mark_lower_case_and_empty_rows_are_accepted(tmp_path: Path) -> None:
    extension = tmp_path / "excel.csv"
    extension.write_bytes("\ufeffKind,Code,Name,Description\r\n,,,\r\nm , c6s1m7 , diorite ,\r\n,,,\r\n"
                          .encode("utf-8"))
    (entry,) = read_table(extension)
    assert (entry.kind, entry.code, entry.name, entry.description) == ("M", "C6S1M7", "diorite", "")
    assert entry.source == f"{extension} line 3"


def test_environment_variable_names_an_extension(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from_env = write(tmp_path / "env.csv", "kind,code,name,description", "X,X20,lab attribute,")
    from_argument = write(tmp_path / "arg.csv", "kind,code,name,description", "P,P20,etched,")
    monkeypatch.setenv(ENV_VAR, str(from_env))
    merged = load_taxonomy(from_argument)
    assert merged.describe("C6S1M1P20X20") == "granite (igneous stone, stone), etched, lab attribute"
    assert "C6S1M1P2X20" in load_taxonomy()
    monkeypatch.setenv(ENV_VAR, "")
    assert "C6S1M1P2X20" not in load_taxonomy()


def test_environment_variable_naming_a_missing_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(ENV_VAR, str(tmp_path / "gone.csv"))
    with pytest.raises(TaxonomyError, match=f"^{ENV_VAR} names .*gone.csv, which is not a file$"):
        load_taxonomy()


def test_entry_validates_and_normalises_its_code() -> None:
    assert Entry("S", " c6s1 ", "igneous stone").code == "C6S1"
    assert Entry("M", "C6S1M1", "granite").parent == "C6S1"
    assert Entry("S", "C6S1", "igneous stone").parent == "C6"
    assert Entry("P", "P2", "polished").parent is None
    with pytest.raises(TaxonomyError, match="kind 'Y' is not one of C, S, M, P, X"):
        Entry("Y", "Y1", "why")


# ---------------------------------------------------------------- writing the merged table


def test_to_csv_round_trip(tmp_path: Path) -> None:
    extension = write(tmp_path / "lab.csv", "kind,code,name,description",
                      "C,C9,lab material,\"with, comma and \"\"quotes\"\"\"", "S,C9S1,mycelium,", "M,C9S1M1,mycel,")
    merged = load_taxonomy(extension)
    out = merged.to_csv(tmp_path / "merged.csv")
    assert out == tmp_path / "merged.csv"
    assert out.read_text(encoding="utf-8").splitlines()[0] == "kind,code,name,description"
    reread = Taxonomy.from_csv(out)
    assert reread == merged
    assert reread.entries("C")[-1].description == 'with, comma and "quotes"'
    assert sorted(os.listdir(tmp_path)) == ["lab.csv", "merged.csv"]


@pytest.mark.skipif(os.name != "posix", reason="file modes are POSIX")
def test_to_csv_writes_a_readable_file_and_keeps_an_existing_mode(tmp_path: Path, shipped: Taxonomy) -> None:
    fresh = shipped.to_csv(tmp_path / "fresh.csv")
    assert fresh.stat().st_mode & 0o777 == 0o644
    kept = write(tmp_path / "kept.csv", "old")
    kept.chmod(0o664)
    shipped.to_csv(kept)
    assert kept.stat().st_mode & 0o777 == 0o664


def test_to_csv_leaves_the_old_file_when_the_write_fails(tmp_path: Path, shipped: Taxonomy,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    target = write(tmp_path / "taxonomy.csv", "old content")

    def fail(source: str, destination: str) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(OSError, match="disk full"):
        shipped.to_csv(target)
    assert target.read_text(encoding="utf-8") == "old content\n"
    assert os.listdir(tmp_path) == ["taxonomy.csv"]


def test_class_names_for_figures(shipped: Taxonomy) -> None:
    assert shipped.class_name("C6") == "stone"
    assert shipped.class_name(" c6s1 ") == "igneous stone"
    assert shipped.class_name("C6S1M1P2X1") == "granite, polished"  # X1 is "no extra attribute"
    assert shipped.class_name("C1S1M1P4X2") == "oak, planed, varnished"
    with pytest.raises(ValueError, match="stone has no sub-class S9"):
        shipped.class_name("C6S9M1P1X1")
