"""The standard metadata of export bundles as pure functions (scanner/storage/metadata.py), and a
database's settings file (scanner/storage/settings.py)."""

from __future__ import annotations

import csv
import io
import json
import math
from datetime import UTC, datetime

import numpy as np
import pytest

from scanner.scan import CHANNELS, Recording, Trace
from scanner.storage.database import ScanRecord
from scanner.storage.metadata import (
    CHANNEL_COLUMNS,
    MetadataError,
    Provenance,
    Table,
    channel_tables,
    checked_creator,
    croissant,
    features_schema,
    license_url,
    metadata_problems,
    recording_channels,
    ro_crate,
    scan_channels,
    scans_schema,
    scans_table,
    sessions_of,
)
from scanner.storage.settings import read_settings, write_settings

WHEN = datetime(2026, 11, 29, 9, 0, tzinfo=UTC)


def _record(scan_id: str, session: str, operator: str, started: str, label: str = "C6S1M1P2X1") -> ScanRecord:
    return ScanRecord(scan_id=scan_id, label=label, sample_id=scan_id[:-4], session_id=session, operator=operator,
                      scan_index=int(scan_id[-3:]), started=started, rigid=False, path=f"scans/{scan_id}.mat",
                      content_hash="0" * 64, added="")


def test_licenses_are_spdx_identifiers_or_urls_and_none_is_explicit():
    assert license_url("CC-BY-4.0") == "https://spdx.org/licenses/CC-BY-4.0"
    assert license_url(" CC0-1.0 ") == "https://spdx.org/licenses/CC0-1.0"
    assert license_url("https://example.org/terms?v=2") == "https://example.org/terms?v=2"
    assert license_url("none") is None and license_url("NONE") is None
    for bad in ("", "CC BY", "javascript:alert(1)", "x" * 65, "ftp://example.org/l"):
        with pytest.raises(MetadataError, match="neither an SPDX identifier"):
            license_url(bad)


def test_a_creator_is_one_printable_line():
    assert checked_creator("  Haptics Lab ") == "Haptics Lab" and checked_creator("") is None
    for bad in ("a\nb", "x" * 201, "tab\there", "\x7f"):
        with pytest.raises(MetadataError, match="one line of at most 200 printable characters"):
            checked_creator(bad)


def test_scan_channels_give_one_row_per_axis_with_the_scan_format_unit_and_rate():
    rows = scan_channels()
    assert len(rows) == sum(spec.axes or 1 for spec in CHANNELS.values()) == 24
    by_name = {row.name: row for row in rows}
    assert by_name["v_ts_z"].variable == "v_ts" and by_name["v_ts_z"].column == 3
    assert (by_name["v_ts_z"].type, by_name["v_ts_z"].units, by_name["v_ts_z"].sampling_frequency) == ("ACCEL", "g",
                                                                                                      3000.0)
    assert (by_name["dB"].type, by_name["dB"].units, by_name["dB"].sampling_frequency) == ("MAGN", "uT", 80.0)
    assert by_name["t_cool"].column == 0 and "MLX90614" in by_name["t_cool"].device
    for row in rows:
        assert row.units == CHANNELS[row.variable].unit and row.sampling_frequency == CHANNELS[row.variable].fs

    tables = channel_tables(rows)
    modalities = ("audio", "flex", "force", "magnetic", "metal", "reflectance", "thermal", "vibration")
    assert sorted(tables) == sorted(f"channels/{m}_channels.{ext}" for m in modalities for ext in ("tsv", "json"))
    force = list(csv.reader(io.StringIO(tables["channels/force_channels.tsv"].decode()), delimiter="\t"))
    assert force[0] == list(CHANNEL_COLUMNS) and [r[0] for r in force[1:]] == ["f_frn", "f_frt", "f_press", "f_fold"]
    assert force[1][6] == "n/a"  # a 1-D variable has no column


def test_recording_channels_follow_roles_and_say_when_rates_differ():
    def recording(name: str, fs: float) -> Recording:
        return Recording(name, {"acc": Trace(np.zeros((10, 3)), 100.0, "m/s^2"),
                                "cur": Trace(np.zeros(10), fs, "A"), "spare": Trace(np.zeros(10), 5.0, "V")},
                         {"vibration": "acc", "signal_cur": "cur"}, "grass")

    rows = recording_channels([recording("r1", 6.5), recording("r2", 7.0)])
    names = {row.name: row for row in rows}
    assert [names[f"acc_{i}"].column for i in (1, 2, 3)] == [1, 2, 3]
    assert names["acc_1"].modality == "vibration" and names["acc_1"].type == "ACCEL"
    assert names["cur"].modality == "signal" and math.isnan(names["cur"].sampling_frequency)
    assert "2 rates across recordings, 6.5 to 7 Hz" in names["cur"].description
    # Clocks fitted per recording differ in the last digits: one rate, the median, with the range said.
    close = {r.name: r for r in recording_channels([recording(f"r{i}", 6.5 + 0.001 * i) for i in range(3)])}
    assert close["cur"].sampling_frequency == 6.501 and "6.5 to 6.502 Hz" in close["cur"].description
    assert names["spare"].modality == "unmapped" and names["spare"].sampling_frequency == 5.0
    table = channel_tables(rows)["channels/signal_channels.tsv"].decode()
    assert "\tn/a\t" in table  # BIDS's n/a for a rate that differs between recordings


def test_scans_table_names_the_labels_taxonomy_codes_and_the_files():
    records = [_record("granite-01-001", "s-1", "ab", "2026-11-21T08:00:00+00:00")]
    files = {"granite-01-001": {"mat": "scans/g.mat", "I_disp": "scans/g_disp.png"}}
    rows = list(csv.DictReader(io.StringIO(scans_table(records, files).decode())))
    assert rows[0]["class_code"] == "C6" and rows[0]["material_code"] == "C6S1M1" and rows[0]["process_code"] == "P2"
    assert rows[0]["mat_file"] == "scans/g.mat" and rows[0]["photo_disp"] == "scans/g_disp.png"
    assert rows[0]["photo_macro"] == "" and rows[0]["rigid"] == "false"


def test_features_schema_types_units_and_keys():
    header = ["scan_id", "sample_id", "label", "C", "S", "M", "P", "X", "tactum.mico", "tactum.fst"]
    schema = features_schema(header, {"tactum.mico": "Hz"})
    fields = {f["name"]: f for f in schema["fields"]}
    assert [f["type"] for f in schema["fields"]] == ["string"] * 3 + ["integer"] * 5 + ["number"] * 2
    assert fields["tactum.mico"]["unit"] == "Hz" and "unit" not in fields["tactum.fst"]
    assert schema["primaryKey"] == ["scan_id"]
    assert schema["foreignKeys"] == [{"fields": ["scan_id", "label"],
                                      "reference": {"resource": "scans", "fields": ["scan_id", "label"]}}]


def _provenance(**change) -> Provenance:
    return Provenance(**{"license": "https://spdx.org/licenses/CC-BY-4.0", "creator": "Haptics Lab", "created": WHEN,
                         "software_version": "0.1.0", "feature_code_version": "abc"} | change)


def test_ro_crate_describes_files_instruments_sessions_and_provenance():
    records = [_record("g-01-001", "s-1", "ab", "2026-11-21T08:00:00+00:00"),
               _record("g-01-002", "s-1", "cd", "2026-11-21T08:05:00+00:00"),
               _record("g-01-003", "s/2", "ab", "2026-11-22T08:00:00+00:00")]
    files = {r.scan_id: {"mat": f"scans/{r.scan_id}.mat"} for r in records}
    sessions = sessions_of(records, files)
    assert [(s.session_id, s.operators, s.started, s.ended) for s in sessions] == [
        ("s-1", ("ab", "cd"), "2026-11-21T08:00:00+00:00", "2026-11-21T08:05:00+00:00"),
        ("s/2", ("ab",), "2026-11-22T08:00:00+00:00", "2026-11-22T08:00:00+00:00")]
    checksums = {path: {"sha256": "a" * 64, "size": 10} for roles in files.values() for path in roles.values()}
    crate = ro_crate(checksums, _provenance(), sessions, "scans", {})
    assert crate["@context"] == "https://w3id.org/ro/crate/1.2/context"
    entities = {e["@id"]: e for e in crate["@graph"]}
    assert entities["ro-crate-metadata.json"]["conformsTo"] == {"@id": "https://w3id.org/ro/crate/1.2"}
    assert entities["./"]["hasPart"] == [{"@id": p} for p in sorted(checksums)]
    assert entities["scans/g-01-001.mat"]["contentSize"] == "10"
    assert entities["#session-s-1"]["agent"] == [{"@id": "#operator-ab"}, {"@id": "#operator-cd"}]
    assert entities["#session-s/2"]["result"] == {"@id": "scans/g-01-003.mat"}
    assert entities["#texplorer2"]["hasPart"] == [{"@id": f"#TU{i}"} for i in (1, 2, 3, 4)]
    assert entities["#creator"]["name"] == "Haptics Lab" and entities["./"]["publisher"] == {"@id": "#creator"}
    # An operator id with characters a fragment cannot hold is escaped, never dropped.
    odd = ro_crate({}, _provenance(license=None, creator=None),
                   sessions_of([_record("g-01-001", "s", "Dr. Ö #1", "t")], {"g-01-001": {}}), "x", {})
    assert any(e["@id"] == "#operator-Dr.%20%D6%20%231" and e["name"] == "Dr. Ö #1" for e in odd["@graph"])
    assert next(e for e in odd["@graph"] if e["@id"] == "./")["license"] == "no license given by the exporting lab"


def test_croissant_lists_tables_with_checksums_and_typed_fields():
    table = Table("scans", "scans.csv", scans_schema(), "the scans")
    body = croissant([table], {"scans.csv": {"sha256": "b" * 64, "size": 5}}, _provenance(),
                     [("mat-files", "scans/**/*.mat", "application/x-matlab-data", "scans")], ["disp"])
    assert body["conformsTo"] == "http://mlcommons.org/croissant/1.1"
    assert body["distribution"][0] | {"description": ""} == {
        "@type": "cr:FileObject", "@id": "scans.csv", "name": "scans.csv", "contentUrl": "scans.csv",
        "encodingFormat": "text/csv", "sha256": "b" * 64, "contentSize": "5 B", "description": ""}
    fields = {f["name"]: f["dataType"] for f in body["recordSet"][0]["field"]}
    assert fields["scan_index"] == "sc:Integer" and fields["started"] == "sc:DateTime"
    assert fields["rigid"] == "sc:Boolean"
    assert [r["@id"] for r in body["recordSet"]] == ["scans", "channels", "photos"]
    assert body["license"] == "https://spdx.org/licenses/CC-BY-4.0" and body["creator"]["name"] == "Haptics Lab"
    assert json.dumps(body)  # plain JSON, no NaN


def test_metadata_problems_compare_descriptions_with_the_files():
    listed = {"a.csv": {"sha256": "1" * 64, "size": 3}, "b.mat": {"sha256": "2" * 64, "size": 4}}
    crate = {"@graph": [{"@id": "a.csv", "@type": "File", "sha256": "1" * 64, "contentSize": "3"},
                        {"@id": "c.png", "@type": "File", "sha256": "3" * 64}]}
    files = {"ro-crate-metadata.json": json.dumps(crate).encode(), "channels/x_channels.tsv":
             b"name\ttype\tunits\tsampling_frequency\tdevice\tvariable\tcolumn\tdescription\n"
             b"dB\tMAGN\tmT\t80\tn/a\tdB\tn/a\t\nq\tMISC\tV\t1\tn/a\tq\tn/a\t\n"}
    problems = metadata_problems(set(files), {"files": listed, "scans": []}, files.__getitem__, {"dB": "uT"})
    assert problems == [
        "ro-crate-metadata.json: describes c.png, which the bundle does not hold",
        "ro-crate-metadata.json: does not describe b.mat",
        "channels/x_channels.tsv: channel dB in 'mT', but the scans store dB in 'uT'",
        "channels/x_channels.tsv: channel 'q' names variable 'q', which the scans do not hold"]
    assert metadata_problems({"ro-crate-metadata.json"}, {"files": listed, "scans": []},
                             lambda name: b"{", None)[0].startswith("ro-crate-metadata.json: not valid JSON")
    assert metadata_problems(set(), {"files": listed, "scans": []}, None) == []  # a bundle from before


def test_settings_round_trip_refuse_bad_values_and_bound_their_file(tmp_path):
    assert read_settings(tmp_path) == {}
    assert write_settings(tmp_path, license="CC-BY-4.0", creator="Lab") == {"license": "CC-BY-4.0", "creator": "Lab"}
    before = (tmp_path / "settings.json").read_bytes()
    with pytest.raises(MetadataError, match="neither an SPDX identifier"):
        write_settings(tmp_path, license="C C")
    with pytest.raises(MetadataError, match="unknown setting"):
        write_settings(tmp_path, colour="red")
    assert (tmp_path / "settings.json").read_bytes() == before  # a refused change writes nothing
    assert write_settings(tmp_path, creator=None) == {"license": "CC-BY-4.0"}
    for text, match in (("[1]", "must be a JSON object of strings"), ("{", "not valid JSON"),
                        (json.dumps({"license": "a b"}), "neither an SPDX"), (" " * (65 << 10), "larger than")):
        (tmp_path / "settings.json").write_text(text)
        with pytest.raises(MetadataError, match=match):
            read_settings(tmp_path)


@pytest.mark.parametrize(("name", "content", "expected"), [
    ("ro-crate-metadata.json", b'{"@graph": [{"@id": ["a"], "@type": "File"}]}', "a File entity without a text @id"),
    ("ro-crate-metadata.json", b'{"@graph": [{"@id": "a.csv", "@type": "File", "contentSize": Infinity}]}',
     "not valid JSON (Infinity is not a JSON number)"),
    ("ro-crate-metadata.json", b'{"@graph": 3}', "no @graph of entities"),
    ("ro-crate-metadata.json", b"[" * 100_000, "not valid JSON"),
    ("datapackage.json", b'{"resources": [{"path": "a.csv", "stats": [1]}]}', "is not a table of the bundle"),
    ("datapackage.json", b'{"resources": [{"path": "features.mat"}]}', "'features.mat' is not a table"),
    ("datapackage.json", b'{"resources": [{"path": "scans.csv", "stats": [1]}, {"path": "scans.csv"}]}',
     "is listed twice"),
    ("croissant.json", b'{"distribution": [{"@type": "cr:FileObject", "contentUrl": "a.csv", '
                       b'"contentSize": "1e999 B"}]}', "size of a.csv is '1e999 B'"),
    ("scans.csv", b'scan_id\n"' + b"x" * 2_000 + b'"\n', "scans.csv: not a readable table"),
    ("scans.csv", b"scan_id\n" + b"y" * 900 + b"\n", "not in the manifest: " + "y" * 64 + ")"),
])
def test_metadata_of_the_wrong_shape_are_problems_never_exceptions(name, content, expected):
    files = {name: content, "features.mat": b"\x00\xff", "a.csv": b"x\n1\n"}
    listed = {n: {"sha256": "0" * 64, "size": len(data)} for n, data in files.items()}
    limit = csv.field_size_limit(1_000)  # a field over the csv module's limit (set here: others may raise it)
    try:
        problems = metadata_problems(set(files), {"files": listed, "scans": [{"scan_id": "a"}]}, files.__getitem__)
    finally:
        csv.field_size_limit(limit)
    assert any(expected in p for p in problems), problems
    assert all("\n" not in p and len(p) < 400 for p in problems)


def test_a_recording_set_manifest_has_no_scans_and_huge_metadata_are_not_read():
    listed = {"scans.csv": {"sha256": "0" * 64, "size": 10}, "ro-crate-metadata.json": {"sha256": "", "size": 1 << 40}}

    def read(name):
        assert name != "ro-crate-metadata.json", "a file listed as 1 TiB is not read"
        return b"scan_id\na\n"

    problems = metadata_problems(set(listed), {"files": listed}, read)  # a set bundle's manifest: no 'scans'
    assert problems == ["ro-crate-metadata.json: larger than 268435456 bytes (not read)"]
