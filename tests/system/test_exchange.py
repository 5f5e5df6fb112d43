"""The standard metadata of an export bundle (docs/export.md), checked by the standards' own tools:
mlcroissant (Croissant 1.1), frictionless (Data Package and Table Schema) and roc-validator (RO-Crate 1.2,
in its own environment, .venv/tools/rocrate); and import against metadata that disagree with the files."""

from __future__ import annotations

import csv
import hashlib
import io
import json
import logging
import shutil
import subprocess
import warnings
import zipfile
from pathlib import Path

import frictionless
import mlcroissant
import numpy as np
import pytest
from conftest import make_scan

from scanner.cli import main
from scanner.scan import CHANNELS
from scanner.storage.bundle import MANIFEST, MANIFEST_SUM, BundleError, import_bundle
from scanner.storage.database import Database
from scanner.storage.metadata import CROISSANT, DATAPACKAGE, RO_CRATE, SCANS_CSV
from scanner.storage.settings import write_settings
from scanner.workflows.exchange import export_database

ROOT = Path(__file__).resolve().parents[2]
ROCRATE_PYTHON = ROOT / ".venv" / "tools" / "rocrate" / "bin" / "python"
VALIDATE_ROCRATE = ROOT / "tests" / "tools" / "validate_rocrate.py"
NEW_FILES = ("scans.csv", "ro-crate-metadata.json", "croissant.json", "datapackage.json")


@pytest.fixture(scope="module")
def source(tmp_path_factory) -> Database:
    db = Database(tmp_path_factory.mktemp("source") / "db")
    db.add(make_scan(0, sample_id="granite-01", scan_index=1, session_id="s-1", started="2026-11-21T08:00:00+00:00"))
    db.add(make_scan(1, sample_id="granite-01", scan_index=2, session_id="s-2", operator="cd",
                     started="2026-11-21T08:10:00+00:00"))
    db.add(make_scan(2, label="C7S1M1P8X1", sample_id="steel-01", session_id="s-2", operator="cd", rigid=True,
                     drop=("f_fold", "alpha_f"), started="2026-11-21T08:20:00+00:00"))
    db.add(make_scan(3, label="C1S1M1P4X1", sample_id="oak-01", session_id="s-3", images=False,
                     started="2026-11-21T08:30:00+00:00"))
    write_settings(db.root, license="CC-BY-4.0", creator="https://orcid.org/0000-0002-1825-0097")
    return db


@pytest.fixture(scope="module")
def bundle(source, tmp_path_factory) -> Path:
    return export_database(source, tmp_path_factory.mktemp("bundles") / "bundle", workers=1).path


def _manifest(bundle: Path) -> dict:
    return json.loads((bundle / MANIFEST).read_text())


def _rows(path: Path, delimiter: str = ",") -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle, delimiter=delimiter))


# -- Croissant -----------------------------------------------------------------------------------------

def test_croissant_validates_and_loads_every_scan_feature_taxonomy_channel_and_photo_record(bundle, caplog):
    manifest = _manifest(bundle)
    with caplog.at_level(logging.WARNING), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # pandas' fragmentation warnings inside mlcroissant's reader
        dataset = mlcroissant.Dataset(jsonld=bundle / CROISSANT)
        records = {name: list(dataset.records(record_set=name))
                   for name in ("scans", "features", "taxonomy", "channels", "photos")}
    assert not [r for r in caplog.records if "validation" in r.getMessage()], caplog.text  # no warnings either
    assert dataset.metadata.ctx.issues.errors == set() and dataset.metadata.ctx.issues.warnings == set()
    counts = manifest["counts"]
    assert len(records["scans"]) == counts["scans"] == 4
    assert len(records["features"]) == counts["feature_rows"] == 4
    assert len(records["taxonomy"]) == len(_rows(bundle / "taxonomy.csv"))
    photos = [name for name in manifest["files"] if name.endswith(".png")]
    assert len(records["photos"]) == len(photos) == 9
    assert len(records["channels"]) == sum(spec.axes or 1 for spec in CHANNELS.values())
    # Typed fields, equal to the files they come from; the .mat file and the photos reachable from a scan.
    table = {row["scan_id"]: row for row in _rows(bundle / "features.csv")}
    for record in records["features"]:
        row = table[record["features/scan_id"].decode()]
        value = record["features/other.density"]
        assert isinstance(record["features/C"], int | np.integer)
        np.testing.assert_equal(value, float(row["other.density"]))  # the same double, NaN as NaN
    for record in records["scans"]:
        assert (bundle / record["scans/mat_file"].decode()).is_file()
        assert record["scans/material_code"].decode() in {r["code"] for r in _rows(bundle / "taxonomy.csv")}
    photo_scans = sorted(r["photos/scan_id"].decode() for r in records["photos"])
    assert photo_scans == sorted(["granite-01-001", "granite-01-002", "steel-01-001"] * 3)
    first = next(r for r in records["photos"] if r["photos/kind"] == b"disp")
    assert first["photos/image"].size == (320, 240)  # PIL: width x height of the 240 x 320 photo


# -- Frictionless ------------------------------------------------------------------------------------

def test_frictionless_validates_every_table_with_its_keys_and_row_counts(bundle, tmp_path):
    report = frictionless.validate(bundle / DATAPACKAGE)
    assert report.valid, report.flatten(["type", "note"])
    assert [task.name for task in report.tasks] == ["scans", "features", "taxonomy"]
    schema = json.loads((bundle / "schemas/features.schema.json").read_text())
    fields = {field["name"]: field for field in schema["fields"]}
    assert schema["primaryKey"] == ["scan_id"]
    assert fields["other.density"]["unit"] == "g/cm^3" and fields["tactum.mico"]["unit"] == "Hz"
    assert "unit" not in fields["tactum.fst"] and fields["C"]["type"] == "integer"

    def broken(change) -> list[tuple[str, str]]:
        copy = tmp_path / f"copy-{len(list(tmp_path.iterdir()))}"
        shutil.copytree(bundle, copy)
        change(copy)
        result = frictionless.validate(copy / DATAPACKAGE)
        return [(error.type, error.note) for task in result.tasks for error in task.errors]

    def unknown_material(copy: Path) -> None:
        (copy / SCANS_CSV).write_text((copy / SCANS_CSV).read_text().replace(",C6S1M1,", ",C6S1M9,", 1))

    def twice(copy: Path) -> None:
        lines = (copy / "features.csv").read_text().splitlines(keepends=True)
        (copy / "features.csv").write_text("".join([*lines, lines[1]]))

    assert [t for t, _ in broken(unknown_material)] == ["foreign-key"]
    assert "primary-key" in [t for t, _ in broken(twice)]


# -- RO-Crate ------------------------------------------------------------------------------------------

def _validate_crate(folder: Path, cache: Path, severity: str = "REQUIRED") -> dict:
    if not ROCRATE_PYTHON.exists():
        pytest.skip(f"roc-validator is not installed in {ROCRATE_PYTHON.parent.parent} (make install puts it there)")
    done = subprocess.run([str(ROCRATE_PYTHON), str(VALIDATE_ROCRATE), str(folder), str(cache), severity],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout)


def test_rocrate_validator_passes_the_crate_at_its_required_level(bundle, tmp_path):
    report = _validate_crate(bundle, tmp_path / "cache")
    assert report["passed"] and report["issues"] == [], report["issues"]
    assert report["statistics"]["total_failed_checks"] == 0 and report["statistics"]["total_passed_checks"] > 50
    crate = json.loads((bundle / RO_CRATE).read_text())
    entities = {entity["@id"]: entity for entity in crate["@graph"]}
    root = entities["./"]
    assert root["license"] == {"@id": "https://spdx.org/licenses/CC-BY-4.0"}
    assert root["creator"] == {"@id": "https://orcid.org/0000-0002-1825-0097"}
    mat = "scans/C7S1M1P8X1/steel-01/steel-01-001.mat"
    data = (bundle / mat).read_bytes()
    assert entities[mat] | {"description": ""} == {
        "@id": mat, "@type": "File", "name": "steel-01-001.mat", "encodingFormat": "application/x-matlab-data",
        "contentSize": str(len(data)), "sha256": hashlib.sha256(data).hexdigest(), "description": ""}
    session = entities["#session-s-2"]
    assert session["agent"] == {"@id": "#operator-cd"} and {"@id": "#TU2"} in session["instrument"]
    assert {"@id": mat} in session["result"] and entities["#operator-cd"]["name"] == "cd"
    # Every recommendation the exporter can meet is met: what is left needs the lab's own contact details.
    recommended = _validate_crate(bundle, tmp_path / "cache", "RECOMMENDED")
    assert {issue["message"] for issue in recommended["issues"]} <= {
        "A Person entity SHOULD have an ORCID identifier as its @id (e.g., https://orcid.org/0000-0001-2345-6789)",
        "At least one author or publisher Person/Organization SHOULD have a contactPoint property"}


def test_rocrate_validator_fails_a_crate_without_its_publication_date(bundle, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(bundle, copy)
    crate = json.loads((copy / RO_CRATE).read_text())
    del next(e for e in crate["@graph"] if e["@id"] == "./")["datePublished"]
    (copy / RO_CRATE).write_text(json.dumps(crate))
    report = _validate_crate(copy, tmp_path / "cache")
    assert not report["passed"] and any("datePublished" in issue["message"] for issue in report["issues"])


# -- import ------------------------------------------------------------------------------------------

def _resum(bundle: Path, *names: str) -> None:
    """Put the changed files' sizes and SHA-256 into the manifest, so only the metadata disagree."""
    manifest = _manifest(bundle)
    for name in names:
        data = (bundle / name).read_bytes()
        manifest["files"][name] = {"sha256": hashlib.sha256(data).hexdigest(), "size": len(data)}
    text = json.dumps(manifest, indent=1).encode() + b"\n"
    (bundle / MANIFEST).write_bytes(text)
    (bundle / MANIFEST_SUM).write_text(f"{hashlib.sha256(text).hexdigest()}  manifest.json\n")


def _refused(db: Database, bundle: Path) -> list[str]:
    before = sorted(p.relative_to(db.root) for p in db.root.rglob("*"))
    with pytest.raises(BundleError) as caught:
        import_bundle(db, bundle)
    assert sorted(p.relative_to(db.root) for p in db.root.rglob("*")) == before and len(db) == 0
    return caught.value.problems


def test_import_refuses_metadata_that_disagree_with_the_files_and_lists_why(bundle, tmp_path):
    db = Database(tmp_path / "db")
    unit = tmp_path / "unit"
    shutil.copytree(bundle, unit)
    table = unit / "channels/magnetic_channels.tsv"
    table.write_text(table.read_text().replace("\tuT\t", "\tmT\t"))
    _resum(unit, "channels/magnetic_channels.tsv")
    problems = _refused(db, unit)
    assert "channels/magnetic_channels.tsv: channel dB in 'mT', but the scans store dB in 'uT'" in problems
    assert any(p.startswith("ro-crate-metadata.json: SHA-256 of channels/magnetic_channels.tsv is") for p in problems)

    count = tmp_path / "count"
    shutil.copytree(bundle, count)
    lines = (count / SCANS_CSV).read_text().splitlines(keepends=True)
    (count / SCANS_CSV).write_text("".join(lines[:-1]))
    package = json.loads((count / DATAPACKAGE).read_text())
    _resum(count, SCANS_CSV)
    problems = _refused(db, count)
    assert "scans.csv: 3 scans, the manifest lists 4" in problems
    assert f"datapackage.json: scans.csv has 3 rows, the package says {package['resources'][0]['stats']['rows']}" \
        in problems

    checksum = tmp_path / "checksum"
    shutil.copytree(bundle, checksum)
    described = json.loads((checksum / CROISSANT).read_text())
    described["distribution"][1]["sha256"] = "0" * 64
    (checksum / CROISSANT).write_text(json.dumps(described))
    _resum(checksum, CROISSANT)
    assert any(p.startswith("croissant.json: SHA-256 of features.csv is 0000000000000000...")
               for p in _refused(db, checksum))


def test_import_takes_a_bundle_written_before_the_standard_metadata(bundle, tmp_path):
    old = tmp_path / "old"
    shutil.copytree(bundle, old)
    manifest = _manifest(old)
    for name in [n for n in manifest["files"] if n in NEW_FILES or n.startswith(("channels/", "schemas/"))]:
        (old / name).unlink()
        del manifest["files"][name]
    for folder in ("channels", "schemas"):
        (old / folder).rmdir()
    manifest.pop("license"), manifest.pop("creator")
    text = json.dumps(manifest, indent=1).encode() + b"\n"
    (old / MANIFEST).write_bytes(text)
    (old / MANIFEST_SUM).write_text(f"{hashlib.sha256(text).hexdigest()}  manifest.json\n")
    db = Database(tmp_path / "db")
    assert import_bundle(db, old).added == ["granite-01-001", "granite-01-002", "steel-01-001", "oak-01-001"]


# -- licenses, creators, settings ----------------------------------------------------------------------

def test_export_needs_a_license_and_says_when_there_is_none(tmp_path, capsys):
    db = Database(tmp_path / "db")
    db.add(make_scan(0, images=False))
    root = str(db.root)
    assert main(["export", str(tmp_path / "a"), "--db", root, "--workers", "1"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no license for the bundle: give --license" in err
    assert not (tmp_path / "a").exists()
    assert main(["export", str(tmp_path / "a"), "--db", root, "--license", "CC BY 4.0"]) == 1
    assert "license 'CC BY 4.0' is neither an SPDX identifier" in capsys.readouterr().err

    assert main(["export", str(tmp_path / "none.zip"), "--db", root, "--license", "none", "--workers", "1"]) == 0
    assert "exported 1 scan(s), 32 files" in capsys.readouterr().out
    with zipfile.ZipFile(tmp_path / "none.zip") as archive:
        crate = json.loads(archive.read(RO_CRATE))
        described = json.loads(archive.read(CROISSANT))
        package = json.loads(archive.read(DATAPACKAGE))
    root_entity = next(e for e in crate["@graph"] if e["@id"] == "./")
    assert root_entity["license"] == "no license given by the exporting lab" and "creator" not in root_entity
    assert described["license"] == "no license given" and "licenses" not in package

    assert main(["db", "settings", "--db", root, "--license", "CC0-1.0", "--creator", "Haptics Lab"]) == 0
    assert capsys.readouterr().out == "license  CC0-1.0\ncreator  Haptics Lab\n"
    assert main(["export", str(tmp_path / "set.zip"), "--db", root, "--workers", "1"]) == 0
    with zipfile.ZipFile(tmp_path / "set.zip") as archive:
        crate = json.loads(archive.read(RO_CRATE))
        manifest = json.loads(archive.read(MANIFEST))
    entities = {e["@id"]: e for e in crate["@graph"]}
    assert entities["./"]["license"] == {"@id": "https://spdx.org/licenses/CC0-1.0"}
    assert entities["#creator"] == {"@id": "#creator", "@type": "Person", "name": "Haptics Lab"}
    assert manifest["license"] == "https://spdx.org/licenses/CC0-1.0" and manifest["creator"] == "Haptics Lab"
    # Given on the command line, they win over the settings.
    assert main(["export", str(tmp_path / "given"), "--db", root, "--license", "https://example.org/terms",
                 "--creator", "Another Lab", "--workers", "1"]) == 0
    crate = json.loads((tmp_path / "given" / RO_CRATE).read_text())
    assert {"@id": "https://example.org/terms"} == next(e for e in crate["@graph"] if e["@id"] == "./")["license"]

    assert main(["db", "settings", "--db", root, "--license", "a b"]) == 1
    assert "license 'a b' is neither" in capsys.readouterr().err
    assert json.loads((db.root / "settings.json").read_text())["license"] == "CC0-1.0"  # unchanged
    (db.root / "settings.json").write_text("{not json")
    assert main(["export", str(tmp_path / "b"), "--db", root]) == 1
    assert "settings.json: not valid JSON" in capsys.readouterr().err
    assert main(["db", "settings", "--db", root, "--unset", "license"]) == 1  # still unreadable: said, not replaced
    (db.root / "settings.json").write_text(json.dumps({"license": "CC0-1.0"}))
    assert main(["db", "settings", "--db", root, "--unset", "license"]) == 0
    assert "license  (not set)" in capsys.readouterr().out


def test_the_bundle_readme_and_channel_tables_read_without_texplorer(bundle):
    rows = _rows(bundle / "channels/vibration_channels.tsv", "\t")
    assert [row["name"] for row in rows[:3]] == ["v_ft_x", "v_ft_y", "v_ft_z"]
    assert {row["units"] for row in rows} == {"g"} and {row["sampling_frequency"] for row in rows} == {"3000"}
    sidecar = json.loads((bundle / "channels/vibration_channels.json").read_text())
    assert sidecar["units"]["Levels"] == {"g": "standard gravity, 9.80665 m/s^2"}
    with io.StringIO((bundle / SCANS_CSV).read_text()) as handle:
        scans = list(csv.DictReader(handle))
    assert [s["material_code"] for s in scans] == ["C6S1M1", "C6S1M1", "C7S1M1", "C1S1M1"]
    assert scans[3]["photo_disp"] == "" and scans[2]["rigid"] == "true"


# -- recording sets ------------------------------------------------------------------------------------

FIXTURES = ROOT / "tests" / "fixtures" / "ingest"
BOREALTC = ROOT.parent / "shared" / "realdata" / "borealtc"


def _croissant_counts(folder: Path, names: tuple[str, ...]) -> dict[str, int]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dataset = mlcroissant.Dataset(jsonld=folder / CROISSANT)
        return {name: sum(1 for _ in dataset.records(record_set=name)) for name in names}


def test_a_recording_set_goes_out_as_it_came_in_and_imports_back(tmp_path, capsys):
    db, other = tmp_path / "lab", tmp_path / "other"
    assert main(["ingest", str(FIXTURES / "lab-a"), "--mapping", str(FIXTURES / "lab-a.toml"), "--db", str(db)]) == 3
    assert main(["features", "set:lab-a", "--db", str(db)]) == 0
    capsys.readouterr()
    assert main(["export", str(tmp_path / "b"), "--set", "lab-a", "--db", str(db), "--license", "CC-BY-4.0"]) == 0
    assert "exported set lab-a: 2 recording(s), 22 files" in capsys.readouterr().out
    bundle = tmp_path / "b"
    assert (bundle / "mapping.toml").read_bytes() == (FIXTURES / "lab-a.toml").read_bytes()
    manifest = _manifest(bundle)
    assert manifest["kind"] == "recordings" and manifest["set"] == "lab-a"
    assert manifest["recordings"][0]["roles"] == {"vibration": "pac", "pressure_dc": "pdc", "electrodes": "electrodes",
                                                  "temperature": "tdc"}
    tables = {name.removeprefix("channels/").removesuffix("_channels.tsv"): _rows(bundle / name, "\t")
              for name in manifest["files"] if name.endswith("_channels.tsv")}
    assert sorted(tables) == ["electrodes", "pressure_dc", "temperature", "vibration"]
    assert [(r["name"], r["units"], r["sampling_frequency"]) for r in tables["temperature"]] == [("tdc", "degC", "50")]
    assert frictionless.validate(bundle / DATAPACKAGE).valid
    assert _croissant_counts(bundle, ("recordings", "features", "channels")) == {
        "recordings": 2, "features": 2, "channels": sum(len(rows) for rows in tables.values())}
    report = _validate_crate(bundle, tmp_path / "cache")
    assert report["passed"] and report["issues"] == []

    assert main(["import", str(bundle), "--db", str(other)]) == 0
    assert "set lab-a, 2 recording(s)" in capsys.readouterr().out
    for path in (db / "recordings/lab-a").iterdir():
        assert (other / "recordings/lab-a" / path.name).read_bytes() == path.read_bytes(), path.name
    assert main(["import", str(bundle), "--db", str(other)]) == 1
    assert "the set 'lab-a' exists in" in capsys.readouterr().err
    assert main(["import", str(bundle), "--db", str(other), "--name", "lab-a2"]) == 0
    assert sorted(p.name for p in (other / "recordings").iterdir() if p.name[0] != ".") == ["lab-a", "lab-a2"]
    with pytest.raises(SystemExit):  # import has no --label: argparse's usage error
        main(["import", str(bundle), "--db", str(other), "--name", "x", "--label", "C6"])
    assert "unrecognized arguments: --label C6" in capsys.readouterr().err

    # A unit changed and re-summed: refused with the list, nothing stored.
    table = bundle / "channels/temperature_channels.tsv"
    table.write_text(table.read_text().replace("\tdegC\t", "\tK\t"))
    _resum(bundle, "channels/temperature_channels.tsv")
    assert main(["import", str(bundle), "--db", str(other), "--name", "lab-a3"]) == 1
    err = capsys.readouterr().err
    assert ("problem  channels/temperature_channels.tsv: channel tdc in 'K', but the recordings store tdc in "
            "'degC'") in err
    assert not (other / "recordings/lab-a3").exists()
    # A recording file the manifest lists but no recording entry owns would be dropped silently: refused.
    (bundle / "channels/temperature_channels.tsv").write_text(table.read_text().replace("\tK\t", "\tdegC\t"))
    manifest = _manifest(bundle)
    dropped = manifest["recordings"].pop()
    manifest["counts"]["recordings"] -= 1
    text = json.dumps(manifest, indent=1).encode() + b"\n"
    (bundle / MANIFEST).write_bytes(text)
    (bundle / MANIFEST_SUM).write_text(f"{hashlib.sha256(text).hexdigest()}  manifest.json\n")
    _resum(bundle, "channels/temperature_channels.tsv")
    assert main(["import", str(bundle), "--db", str(other), "--name", "lab-a4"]) == 1
    assert f"problem  {dropped['file']}: belongs to no recording of the manifest" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "c"), "--set", "nope", "--db", str(db), "--license", "none"]) == 1
    assert "no recording set 'nope' to export" in capsys.readouterr().err


@pytest.mark.skipif(not BOREALTC.is_dir(), reason=f"the real recordings are not at {BOREALTC} (a clone outside "
                    "the project's workspace); CI has them there")
def test_the_borealtc_set_exports_with_its_features_validates_and_evaluates_after_import(tmp_path, capsys):
    from system.test_realdata import docs_mapping

    mapping, db, other = tmp_path / "borealtc.toml", tmp_path / "lab", tmp_path / "other"
    mapping.write_text(docs_mapping())
    assert main(["ingest", str(BOREALTC), "--mapping", str(mapping), "--db", str(db)]) == 3
    options = ["--window", "5", "--combine", "rows"]
    assert main(["features", "set:borealtc", "--db", str(db), *options]) == 0
    capsys.readouterr()
    out = tmp_path / "borealtc.zip"
    assert main(["export", str(out), "--set", "set:borealtc", "--db", str(db), "--license", "CC0-1.0",
                 "--creator", "BorealTC authors (re-exported)"]) == 0
    assert "exported set borealtc: 68 recording(s)" in capsys.readouterr().out
    folder = tmp_path / "unzipped"
    with zipfile.ZipFile(out) as archive:
        archive.extractall(folder)
    signal = {row["variable"]: row for row in _rows(folder / "channels/signal_channels.tsv", "\t")}
    assert (signal["current"]["units"], signal["current"]["sampling_frequency"]) == ("A", "6.5")
    assert (signal["gyro"]["units"], signal["gyro"]["sampling_frequency"]) == ("rad/s", "100")
    assert frictionless.validate(folder / DATAPACKAGE).valid
    assert _croissant_counts(folder, ("recordings", "features")) == {"recordings": 68, "features": 896}
    assert _validate_crate(folder, tmp_path / "cache")["passed"]

    assert main(["import", str(out), "--db", str(other)]) == 0
    capsys.readouterr()
    assert main(["evaluate", "set:borealtc", "--db", str(other), *options, "--classifier", "rf",
                 "--no-calibration"]) == 0
    assert f"using {other / 'recordings/borealtc/features.csv'}" in capsys.readouterr().out


def _set_bundle(tmp_path: Path) -> Path:
    db = tmp_path / "lab"
    assert main(["ingest", str(FIXTURES / "lab-a"), "--mapping", str(FIXTURES / "lab-a.toml"), "--db", str(db)]) == 3
    assert main(["features", "set:lab-a", "--db", str(db)]) == 0
    assert main(["export", str(tmp_path / "b"), "--set", "lab-a", "--db", str(db), "--license", "none"]) == 0
    return tmp_path / "b"


def _rewrite(bundle: Path, change) -> None:
    manifest = _manifest(bundle)
    change(manifest)
    text = json.dumps(manifest, indent=1).encode() + b"\n"
    (bundle / MANIFEST).write_bytes(text)
    (bundle / MANIFEST_SUM).write_text(f"{hashlib.sha256(text).hexdigest()}  manifest.json\n")


def test_a_hostile_set_bundle_is_refused_with_its_problems_and_leaves_no_database(tmp_path, capsys):
    bundle = _set_bundle(tmp_path)
    capsys.readouterr()

    def refused(change, expected: str) -> None:
        copy = tmp_path / f"copy-{len(list(tmp_path.glob('copy-*')))}"
        shutil.copytree(bundle, copy)
        change(copy)
        target = tmp_path / "new-db"
        assert main(["import", str(copy), "--db", str(target)]) == 1
        err = capsys.readouterr().err
        assert expected in err, err
        assert err.splitlines()[-1].startswith("texplorer: error: ") and "Traceback" not in err
        assert not target.exists()  # a refused import made no database folder

    first = "recordings/lab-a/metal-1_t01_static.mat"
    refused(lambda b: _rewrite(b, lambda m: m["recordings"].append(dict(m["recordings"][0])) or
                               m["counts"].update(recordings=3)), f"{first} is named by two recording entries")
    refused(lambda b: _rewrite(b, lambda m: m["recordings"][0].update(file="recordings/lab-a/ghost.mat")),
            "recording file recordings/lab-a/ghost.mat is not in its 'files'")
    refused(lambda b: _rewrite(b, lambda m: m.update(counts=[1])), "manifest.json: 'counts' must be an object")
    refused(lambda b: _rewrite(b, lambda m: m["recordings"][0].update(file=["x"])), "does not name a file of")

    def options(copy: Path) -> None:
        (copy / "features.json").write_text("[]")
        _resum(copy, "features.json")
    refused(options, "features.json: not the options of a feature table")

    # An existing set is refused before the bundle is read; with --replace it is replaced.
    other = tmp_path / "other"
    assert main(["import", str(bundle), "--db", str(other)]) == 0
    capsys.readouterr()
    assert main(["import", str(bundle), "--db", str(other), "--name", "lab-a"]) == 1
    assert "the set 'lab-a' exists in" in capsys.readouterr().err
    assert main(["import", str(bundle), "--db", str(other), "--replace"]) == 0


def test_an_encrypted_member_is_one_line_naming_it(bundle, tmp_path, capsys):
    archive = tmp_path / "bundle.zip"
    with zipfile.ZipFile(archive, "w") as out:
        for path in sorted(p for p in bundle.rglob("*") if p.is_file()):
            out.write(path, path.relative_to(bundle).as_posix())
    data = bytearray(archive.read_bytes())
    with zipfile.ZipFile(archive) as listing:
        info = listing.getinfo(MANIFEST)
    central = data.find(b"PK\x01\x02")  # the central directory's entries, until manifest.json's
    while data[central + 46:central + 46 + len(MANIFEST)] != MANIFEST.encode():
        central = data.find(b"PK\x01\x02", central + 4)
    data[central + 8] |= 0x01  # the general-purpose flag's "encrypted" bit of manifest.json's central entry
    archive.write_bytes(bytes(data))
    assert info.filename == MANIFEST
    assert main(["import", str(archive), "--db", str(tmp_path / "db")]) == 1
    err = capsys.readouterr().err
    assert "manifest.json: cannot be read (File 'manifest.json' is encrypted, password required" in err
    assert "Traceback" not in err and not (tmp_path / "db").exists()
