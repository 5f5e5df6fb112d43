"""Hostile mappings and folders for ``texplorer ingest`` (docs/ingest.md): paths that leave the ingested
folder, names differing only in Unicode normalisation, and a seeded fuzz of the mapping parser."""

from __future__ import annotations

import datetime
import json
import math
import random
import re
import unicodedata
import wave
from pathlib import Path

import numpy as np
import pytest

from scanner.storage import ingest
from scanner.storage.ingest import IngestError
from taxonomy.errors import TexplorerError


def write_wav(path: Path, n: int = 800, seed: int = 0) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    samples = np.random.default_rng(seed).normal(0, 3000, n).astype("<i2")
    with wave.open(str(path), "wb") as out:
        out.setnchannels(1)
        out.setsampwidth(2)
        out.setframerate(8000)
        out.writeframes(samples.tobytes())


WAVS = '[[files]]\nglob = "{glob}"\n'


# -- paths outside the ingested folder ----------------------------------------------------------------

@pytest.fixture
def outside(tmp_path):
    """``lab/`` to ingest, with ``cork/a.wav`` inside and ``secret.wav`` beside the folder."""
    write_wav(tmp_path / "lab" / "cork" / "a.wav")
    write_wav(tmp_path / "secret.wav", seed=1)
    return tmp_path


@pytest.mark.parametrize("glob", ["../*.wav", "cork/../../*.wav", "**/../../secret.wav"])
def test_a_glob_climbing_out_of_the_folder_is_refused_naming_it(glob):
    with pytest.raises(IngestError) as info:
        ingest.parse_mapping(WAVS.format(glob=glob), "m", "MAP.toml")
    message = str(info.value)
    assert message.startswith("MAP.toml: files[0]: glob") and repr(glob) in message and "\n" not in message


def test_an_absolute_glob_or_label_table_is_refused_naming_it(outside):
    with pytest.raises(IngestError, match=r"MAP.toml: files\[0\]: glob '/.*/\*\.wav' .*inside the ingested"):
        ingest.parse_mapping(WAVS.format(glob=f"{outside}/*.wav"), "m", "MAP.toml")
    table = f'[labels]\nfrom = "csv"\ncsv = "{outside}/labels.csv"\n' + WAVS.format(glob="**/*.wav")
    with pytest.raises(IngestError, match=r"MAP.toml: labels: csv '/.*labels.csv' .*inside the ingested"):
        ingest.parse_mapping(table, "m", "MAP.toml")
    climbing = '[labels]\nfrom = "csv"\ncsv = "../labels.csv"\n' + WAVS.format(glob="**/*.wav")
    with pytest.raises(IngestError, match=r"labels: csv '../labels.csv'"):
        ingest.parse_mapping(climbing, "m", "MAP.toml")


def test_a_file_link_leading_out_of_the_folder_is_skipped_naming_it(outside):
    link = outside / "lab" / "cork" / "link.wav"
    link.symlink_to(outside / "secret.wav")
    report = ingest.ingest(outside / "lab", ingest.parse_mapping(WAVS.format(glob="**/*.wav"), "m"))
    assert [r.name for r in report.recordings] == ["a"]
    assert report.skipped == [f"{link}: a link to {outside / 'secret.wav'}, outside the ingested folder: not read"]


def test_a_folder_link_leading_out_of_the_folder_is_skipped_naming_the_file(outside):
    (outside / "elsewhere").mkdir()
    write_wav(outside / "elsewhere" / "b.wav", seed=2)
    (outside / "lab" / "foam").symlink_to(outside / "elsewhere")
    report = ingest.ingest(outside / "lab", ingest.parse_mapping(WAVS.format(glob="*/*.wav"), "m"))
    assert [r.name for r in report.recordings] == ["a"]
    assert len(report.skipped) == 1 and report.skipped[0].startswith(f"{outside / 'lab' / 'foam' / 'b.wav'}: a link")


def test_a_link_resolving_inside_the_folder_is_read(outside):
    (outside / "lab" / "cork" / "again.wav").symlink_to(outside / "lab" / "cork" / "a.wav")
    report = ingest.ingest(outside / "lab", ingest.parse_mapping(WAVS.format(glob="**/*.wav"), "m"))
    assert sorted(r.name for r in report.recordings) == ["a", "again"] and report.skipped == []


def test_a_label_table_linked_out_of_the_folder_is_refused(outside):
    (outside / "labels.csv").write_text("recording,label\na,secret\n")
    (outside / "lab" / "labels.csv").symlink_to(outside / "labels.csv")
    mapping = ingest.parse_mapping('[labels]\nfrom = "csv"\ncsv = "labels.csv"\n' + WAVS.format(glob="**/*.wav"),
                                   "m")
    with pytest.raises(IngestError, match="labels.csv: a link to .*, outside the ingested folder"):
        ingest.ingest(outside / "lab", mapping)


# -- names in NFC and NFD -----------------------------------------------------------------------------

NFC = unicodedata.normalize("NFC", "liège")
NFD = unicodedata.normalize("NFD", "liège")


def test_names_differing_only_in_unicode_normalisation_are_one_class_and_one_group(tmp_path):
    assert NFC != NFD
    write_wav(tmp_path / NFC / f"{NFC}-1_01.wav")
    write_wav(tmp_path / NFD / f"{NFD}-1_02.wav", seed=1)
    mapping = ingest.parse_mapping('[groups]\npattern = "^(?P<object>[^_]+)_(?P<trial>\\\\d+)$"\n'
                                   + WAVS.format(glob="**/*.wav"), "m")
    report = ingest.ingest(tmp_path, mapping)
    assert report.skipped == [] and len(report.recordings) == 2
    assert {r.label for r in report.recordings} == {NFC}
    assert {r.group["object"] for r in report.recordings} == {f"{NFC}-1"}


def test_a_label_table_and_a_pattern_match_names_in_either_normalisation(tmp_path):
    write_wav(tmp_path / f"{NFD}_1.wav")
    (tmp_path / "labels.csv").write_text(f"recording,label\n{NFC}_1,{NFD}\n", encoding="utf-8")
    by_table = ingest.ingest(tmp_path, ingest.parse_mapping(
        '[labels]\nfrom = "csv"\ncsv = "labels.csv"\n' + WAVS.format(glob="*.wav"), "m"))
    assert by_table.skipped == [] and [r.label for r in by_table.recordings] == [NFC]
    by_pattern = ingest.ingest(tmp_path, ingest.parse_mapping(
        f'[labels]\nfrom = "pattern"\n[groups]\npattern = "^(?P<label>{NFC})_"\n' + WAVS.format(glob="*.wav"), "m"))
    assert by_pattern.skipped == [] and [r.label for r in by_pattern.recordings] == [NFC]


def test_two_files_of_one_folder_named_alike_in_nfc_are_one_recording_read_once(tmp_path):
    write_wav(tmp_path / "cork" / f"{NFC}.wav")
    write_wav(tmp_path / "cork" / f"{NFD}.wav", seed=1)
    report = ingest.ingest(tmp_path, ingest.parse_mapping(WAVS.format(glob="**/*.wav"), "m"))
    first, second = sorted([tmp_path / "cork" / f"{NFC}.wav", tmp_path / "cork" / f"{NFD}.wav"])
    assert len(report.recordings) == 1 and report.recordings[0].meta["source"] == [f"cork/{first.name}"]
    assert report.skipped == [f"{second}: the same recording and files entry as {first.name} (the same name in "
                              "Unicode NFC): not read"]


def test_values_the_import_sets_or_cannot_store_are_refused_naming_the_key():
    for table, message in [('[meta]\nsplit = "train"\n', "MAP.toml: meta: split is set by the import"),
                           ("[meta]\nrun = nan\n", "MAP.toml: meta.run: nan is not a finite number"),
                           ('[labels]\nform = "csv"\n', "MAP.toml: labels: unknown key(s) form"),
                           ("[[files]]\nglob = '*.wav'\nrate = true\n", "files[0]: rate must be a number, got True")]:
        with pytest.raises(IngestError, match=re.escape(message)):
            ingest.parse_mapping(table + ("" if "files" in table else WAVS.format(glob="*.wav")), "m", "MAP.toml")


# -- a seeded fuzz of the mapping parser --------------------------------------------------------------

class Raw(str):
    """TOML text written as it is (a value nested deeper than a serialiser would recurse)."""


def toml_value(value) -> str:
    if isinstance(value, Raw):
        return str(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf") if math.isinf(value) else repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # JSON's escapes are TOML's basic-string escapes
    if isinstance(value, datetime.date | datetime.time):
        return value.isoformat()
    if isinstance(value, list):
        return "[" + ", ".join(map(toml_value, value)) + "]"
    return "{" + ", ".join(f"{json.dumps(k)} = {toml_value(v)}" for k, v in value.items()) + "}"


def toml_text(table: dict) -> str:
    return "".join(f"{json.dumps(k)} = {toml_value(v)}\n" for k, v in table.items())


BASE = {
    "name": "fz", "label_level": "material", "missing": "interpolate",
    "labels": {"from": "folder", "depth": 1},
    "groups": {"pattern": "^(?P<object>[a-z]+)(?P<trial>\\d*)$"},
    "split": {"from": "none", "train": ["train"], "test": ["test"]},
    "meta": {"sensor": "mic", "gain": 2, "axes": ["x", "y"]},
    "files": [
        {"glob": "**/*.csv", "suffix": ".csv", "format": "csv", "delimiter": ",", "header": True, "comment": "#",
         "skip_rows": 0, "time_column": "t", "time_unit": "s",
         "channels": [{"name": "v", "role": "vibration", "columns": ["v"], "unit": "V", "scale": 1.0,
                       "spread": False}]},
        {"glob": "**/*.wav", "channels": [{"name": "sound", "role": "audio", "columns": [0], "unit": "FS"}]},
        {"glob": "**/*.npz", "stem_pattern": "^(?P<stem>[a-z0-9]+)\\.npz$", "rate_variable": "fs",
         "channels": [{"name": "force", "role": "force_xyz", "variable": "f"}]},
        {"glob": "**/*.png", "grid": [2, 2], "format": "image"},
    ],
}

HOSTILE = [0, -1, 1, 10**30, -10**30, 10**400, 1e308, -1e-320, math.nan, math.inf, -math.inf, True, False,
           "", " ", "x" * 5000, "../x", "/etc/passwd", "**", "[", "a:b:c", "(?P<stem>", "(" * 3000 + ")" * 3000,
           "\x00", "é", [], [1, "a"], [[]], [True], [10**400], ["x"] * 3, {}, {"a": 1}, [{}], [{"glob": 1}],
           datetime.datetime(2020, 1, 2, 3, 4, 5), datetime.date(2020, 1, 2), datetime.time(3, 4),
           Raw("[" * 3000 + "]" * 3000), Raw("{a = " * 400 + "1" + "}" * 400), Raw("[" * 300 + "]" * 300),
           Raw("{a = " * 40 + "1" + "}" * 40)]
"""Values put at a key: wrong types, huge and non-finite numbers, long or nested text, deep nesting."""


def key_paths(value, path=()):
    """Every key path of a nested table (list items by index)."""
    if isinstance(value, dict):
        for key, item in value.items():
            yield (*path, key)
            yield from key_paths(item, (*path, key))
    elif isinstance(value, list):
        for k, item in enumerate(value):
            yield (*path, k)
            yield from key_paths(item, (*path, k))


def mutated(rng: random.Random) -> tuple[dict, str]:
    """A copy of BASE with one key changed (a hostile value, an unknown key, or a list for a table) and the
    name of the key the error should name."""
    table = json.loads(json.dumps(BASE))
    path = rng.choice(list(key_paths(table)))
    parent = table
    for part in path[:-1]:
        parent = parent[part]
    last = path[-1]
    how = rng.random()
    if how < 0.1 and isinstance(parent[last], dict):
        parent[last]["colour"] = "red"
        return table, "colour"
    if how < 0.2 and isinstance(parent[last], dict):
        parent[last] = [parent[last], parent[last]]
    else:
        parent[last] = rng.choice(HOSTILE)
    named = next(p for p in reversed(path) if isinstance(p, str))
    return table, named


@pytest.fixture(scope="module")
def fuzz_folder(tmp_path_factory):
    """Two classes with a CSV, a WAV, an NPZ and a PNG each: BASE imports them as two recordings."""
    import cv2

    root = tmp_path_factory.mktemp("fuzz")
    for k, label in enumerate(("cork", "foam")):
        folder = root / label
        folder.mkdir()
        t = np.arange(64) / 100.0
        rows = "\n".join(f"{a:.3f},{b:.4f}" for a, b in zip(t, np.sin(5 * t + k), strict=True))
        (folder / f"{label}1.csv").write_text("t,v\n" + rows + "\n")
        write_wav(folder / f"{label}1.wav", seed=k)
        np.savez(folder / f"{label}1.npz", f=np.ones((64, 3)) * k, fs=np.array(100.0))
        cv2.imwrite(str(folder / f"{label}1.png"), np.full((8, 8, 3), 40 * k, np.uint8))
    return root


def test_the_base_mapping_of_the_fuzz_imports_its_folder(fuzz_folder):
    report = ingest.ingest(fuzz_folder, ingest.parse_mapping(toml_text(BASE), "fz"))
    assert report.skipped == [] and len(report.made) == 2 * 4  # two recordings cut into 2 x 2 patches


RAW_ERRORS = ("TypeError", "RecursionError", "OverflowError", "AttributeError", "KeyError", "IndexError",
              "ValueError", "AssertionError", "NotImplementedError", "UnicodeEncodeError")
"""Exception names that, in a problem line, mean a mapping value reached code that does not expect it."""


def test_fuzzed_mappings_give_one_short_line_naming_the_key_and_nothing_else(fuzz_folder, tmp_path):
    """Seeded: 200 mappings, each BASE with one key changed. Parsing either accepts the mapping or raises
    an IngestError of one short line naming the file and the key; an accepted mapping imports and stores
    the folder with only the project's errors and problem lines naming no raw exception."""
    rng = random.Random(33)
    accepted = 0
    for case in range(200):
        table, key = mutated(rng)
        text = toml_text(table)
        try:
            mapping = ingest.parse_mapping(text, "fz", "MAP.toml")
        except IngestError as exc:
            message = str(exc)
            assert "\n" not in message and len(message) <= 300, (case, message)
            assert message.startswith("MAP.toml") and (key in message or "nested" in message), (case, key, message)
            continue
        accepted += 1
        try:
            report = ingest.ingest(fuzz_folder, mapping)
            ingest.store_recordings(tmp_path / f"db{case}", mapping.name, report.recordings)
        except TexplorerError as exc:
            assert "\n" not in str(exc) and len(str(exc)) <= 300, (case, str(exc))
            continue
        raw = [line for line in report.skipped if any(f"({name}" in line for name in RAW_ERRORS)]
        assert raw == [], (case, key, raw)
    assert 10 <= accepted <= 150  # the fuzz exercised both paths


def test_a_mapping_nested_beyond_the_parser_is_one_line(tmp_path):
    with pytest.raises(IngestError, match=r"^MAP.toml: not valid TOML \(nested more than") as info:
        ingest.parse_mapping("x = " + "[" * 100_000 + "]" * 100_000 + "\n", "m", "MAP.toml")
    assert "\n" not in str(info.value)


def test_a_csv_line_longer_than_the_budget_is_refused_before_it_is_held(tmp_path):
    import tracemalloc

    from scanner.storage.ingest.readers import MAX_LINE_CHARS, read_table

    path = tmp_path / "wide.csv"
    fields = 16 * MAX_LINE_CHARS // 2  # 64 MiB of "1," on one line: 33.5 million fields
    with path.open("w") as handle:
        handle.write("t,p\n0,1\n")
        for _ in range(16):
            handle.write("1," * (MAX_LINE_CHARS // 2))
        handle.write("\n")
    tracemalloc.start()
    try:
        with pytest.raises(IngestError, match=rf"wide.csv: line 3 is longer than {MAX_LINE_CHARS:,} characters"):
            read_table(path, ",", True)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    # At most one bounded line is held (4 MiB of text; the decoder's buffers as much again), never the
    # 64 MiB line or its 33.5 million fields as strings (about 1.9 GB).
    assert peak < 4 * MAX_LINE_CHARS, (peak, fields)
