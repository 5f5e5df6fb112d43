"""Export bundles and their import (docs/export.md): round trip, damage, hostile bundles, merging, crashes."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import random
import shutil
import signal
import sqlite3
import stat
import subprocess
import sys
import textwrap
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
from conftest import make_scan, png_bomb

from features import FeatureSpace, extract
from scanner.cli import EXIT_PROBLEMS, main
from scanner.storage.bundle import (
    MANIFEST,
    MANIFEST_SUM,
    BundleError,
    import_bundle,
    parse_manifest,
    unsafe_name,
)
from scanner.storage.database import Database, DatabaseError
from scanner.storage.matfile import save_scan
from scanner.storage.metadata import CHANNEL_COLUMNS
from scanner.storage.settings import write_settings
from scanner.workflows.exchange import export_database
from taxonomy.table import Taxonomy, load_taxonomy

LAB_TAXONOMY = """kind,code,name,description
C,C9,lab material,Materials only this lab scans
S,C9S1,mycelium,Grown fungal materials
M,C9S1M1,mycelium leather,
"""
PROJECT_PACKAGES = ("scanner", "features", "taxonomy", "gui")


def _started(minute: int) -> str:
    return f"2026-11-21T08:{minute:02d}:00+00:00"


def _fill(db: Database) -> None:
    db.add(make_scan(0, sample_id="granite-01", scan_index=1, session_id="s-1", started=_started(0)))
    db.add(make_scan(1, sample_id="granite-01", scan_index=2, session_id="s-2", operator="cd",
                     started=_started(10)))
    db.add(make_scan(2, label="C7S1M1P8X1", sample_id="steel-01", session_id="s-2", operator="cd", rigid=True,
                     drop=("f_fold", "alpha_f"), raw=True, started=_started(20)))
    db.add(make_scan(3, label="C9S1M1P1X1", sample_id="mycelium-01", session_id="s-3", images=False,
                     calibration={"accel_zero_V": 1.62}, started=_started(30)))
    db.taxonomy_path.write_text(LAB_TAXONOMY, encoding="utf-8")
    write_settings(db.root, license="CC-BY-4.0", creator="Haptics Lab")


@pytest.fixture(scope="module")
def source(tmp_path_factory) -> Database:
    db = Database(tmp_path_factory.mktemp("source") / "db")
    _fill(db)
    return db


@pytest.fixture(scope="module")
def bundle(source, tmp_path_factory) -> Path:
    return export_database(source, tmp_path_factory.mktemp("bundles") / "bundle", workers=1).path


@pytest.fixture(scope="module")
def bundle_zip(source, tmp_path_factory) -> Path:
    return export_database(source, tmp_path_factory.mktemp("bundles") / "bundle.zip", workers=1).path


def _tree(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file() and not p.name.startswith("catalog.sqlite")}


def _catalog(root: Path) -> dict[str, list[tuple]]:
    """Every catalog table's rows, without the time each scan was added."""
    # Closed here, not whenever the garbage collector gets to it: the last connection to close deletes
    # the WAL file, which a copy of the folder running meanwhile would miss.
    with contextlib.closing(sqlite3.connect(root / "catalog.sqlite")) as conn:
        tables = {t: conn.execute(f"SELECT * FROM {t} ORDER BY 1").fetchall()
                  for t in ("materials", "samples", "sessions", "files")}
        tables["scans"] = conn.execute(
            "SELECT scan_id, label, sample_id, session_id, operator, scan_index, started, rigid, path, "
            "content_hash FROM scans ORDER BY scan_id").fetchall()
    return tables


def _snapshot(root: Path) -> tuple[dict[str, bytes], dict[str, list[tuple]]]:
    return _tree(root), _catalog(root)


def _refused(db: Database, bundle: Path, match: str) -> BundleError:
    with pytest.raises(BundleError) as caught:
        import_bundle(db, bundle)
    assert any(match in problem for problem in caught.value.problems), caught.value.problems
    assert "the database was not changed" in str(caught.value) and "\n" not in str(caught.value)
    return caught.value


@pytest.fixture
def target(tmp_path) -> Database:
    """A database that already holds a scan of its own."""
    db = Database(tmp_path / "target")
    db.add(make_scan(7, sample_id="oak-01", label="C1S1M1P4X1", session_id="t-1"))
    return db


# -- export ------------------------------------------------------------------------------------------

def test_bundle_holds_scans_features_taxonomy_loaders_and_a_manifest_of_every_file(source, bundle):
    names = {p.relative_to(bundle).as_posix() for p in bundle.rglob("*") if p.is_file()}
    scan_files = {entry.path for r in source.records() for entry in source.files(r.scan_id)}
    assert len(scan_files) == 3 * 4 + 1  # three scans with three photos, one without photos
    channel_tables = {f"channels/{m}_channels.{ext}" for m in ("audio", "flex", "force", "magnetic", "metal",
                                                              "reflectance", "thermal", "vibration")
                      for ext in ("tsv", "json")}
    assert names == scan_files | channel_tables | {
        "README.md", "load_texplorer.m", "load_texplorer.py", "features.csv", "features.mat", "taxonomy.csv",
        "scans.csv", "ro-crate-metadata.json", "croissant.json", "datapackage.json", "schemas/scans.schema.json",
        "schemas/features.schema.json", "schemas/taxonomy.schema.json", MANIFEST, MANIFEST_SUM}
    assert (bundle / "channels/thermal_channels.tsv").read_text().splitlines() == [
        "\t".join(CHANNEL_COLUMNS), "t_cool\tTEMP\tdegC\t20\tTU2 MLX90614 infrared thermometer on the sensor "
        "board\tt_cool\tn/a\tMLX90614 object temperature after heating (step thermal)"]
    for path in scan_files:
        assert (bundle / path).read_bytes() == (source.root / path).read_bytes()

    manifest_bytes = (bundle / MANIFEST).read_bytes()
    digest = hashlib.sha256(manifest_bytes).hexdigest()
    assert (bundle / MANIFEST_SUM).read_text() == f"{digest}  manifest.json\n"
    manifest = json.loads(manifest_bytes)
    assert set(manifest["files"]) == names - {MANIFEST, MANIFEST_SUM}
    for name, entry in manifest["files"].items():
        data = (bundle / name).read_bytes()
        assert entry == {"sha256": hashlib.sha256(data).hexdigest(), "size": len(data)}
    assert manifest["format"] == "texplorer-bundle" and manifest["bundle_schema"] == 1
    size = sum(e["size"] for e in manifest["files"].values())
    assert manifest["counts"] == {"scans": 4, "materials": 3, "samples": 3, "sessions": 3, "operators": 2,
                                  "files": len(names) - 2, "bytes": size, "feature_rows": 4,
                                  "feature_columns": 193}
    # Scans in acquisition order; two calibrations: the fixture's default and the mycelium scan's own.
    assert [s["scan_id"] for s in manifest["scans"]] == ["granite-01-001", "granite-01-002", "steel-01-001",
                                                         "mycelium-01-001"]
    assert manifest["calibrations"] == [
        {"values": {"accel_zero_V": 1.65, "accel_V_per_g": 0.33},
         "scans": ["granite-01-001", "granite-01-002", "steel-01-001"]},
        {"values": {"accel_zero_V": 1.62}, "scans": ["mycelium-01-001"]}]
    assert manifest["scans"][3]["files"] == {"mat": "scans/C9S1M1P1X1/mycelium-01/mycelium-01-001.mat"}


def test_bundle_feature_tables_hold_the_features_of_each_scan(source, bundle):
    csv_space = FeatureSpace.from_csv(bundle / "features.csv")
    mat_space = FeatureSpace.from_mat(bundle / "features.mat")
    assert csv_space.scan_ids == mat_space.scan_ids == ("granite-01-001", "granite-01-002", "steel-01-001",
                                                        "mycelium-01-001")
    np.testing.assert_array_equal(csv_space.X, mat_space.X)
    for row, scan_id in enumerate(csv_space.scan_ids):
        np.testing.assert_array_equal(csv_space.X[row], list(extract(source.get(scan_id)).values()))
    # The exporting database's taxonomy, its lab extension included.
    assert Taxonomy.from_csv(bundle / "taxonomy.csv") == load_taxonomy(source.taxonomy_path)
    assert Taxonomy.from_csv(bundle / "taxonomy.csv").name("C9S1M1") == "mycelium leather"


def test_export_filters_and_refusals(source, tmp_path):
    stones = export_database(source, tmp_path / "stones", label="C6", workers=1)
    assert stones.scans == 2
    assert [s["scan_id"] for s in json.loads((tmp_path / "stones" / MANIFEST).read_text())["scans"]] == [
        "granite-01-001", "granite-01-002"]
    session = export_database(source, tmp_path / "s2.zip", session="s-2", workers=1)
    with zipfile.ZipFile(session.path) as archive:
        manifest = json.loads(archive.read(MANIFEST))
    assert [s["scan_id"] for s in manifest["scans"]] == ["granite-01-002", "steel-01-001"]
    assert manifest["filters"] == {"label": None, "session": "s-2"}
    with pytest.raises(BundleError, match="no scans with label C5 and session s-2 to export"):
        export_database(source, tmp_path / "none", label="C5", session="s-2")
    with pytest.raises(BundleError, match="stones already exists"):
        export_database(source, tmp_path / "stones")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s2.zip", "stones"]  # no temporary leftovers


def test_export_refuses_a_database_file_changed_since_it_was_catalogued(tmp_path):
    db = Database(tmp_path / "db")
    db.add(make_scan(0, images=False))
    mat = tmp_path / "db/scans/C6S1M1P2X1/granite-01/granite-01-001.mat"
    extract_first = export_database(db, tmp_path / "ok", license="CC0-1.0", workers=1)  # fills the feature cache
    assert extract_first.scans == 1
    data = bytearray(mat.read_bytes())
    data[-1] ^= 0xFF
    mat.write_bytes(bytes(data))
    with pytest.raises(BundleError, match="differs from the catalog's SHA-256"):
        export_database(db, tmp_path / "bad.zip", license="CC0-1.0", workers=1)
    assert not any(p.name.startswith(".bad.zip") or p.name == "bad.zip" for p in tmp_path.iterdir())


# -- round trip ------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["folder", "zip"])
def test_export_then_import_into_an_empty_database_gives_the_same_catalog_and_files(
        source, bundle, bundle_zip, tmp_path, kind):
    db = Database(tmp_path / "copy")
    report = import_bundle(db, bundle if kind == "folder" else bundle_zip)
    assert report.added == ["granite-01-001", "granite-01-002", "steel-01-001", "mycelium-01-001"]
    assert report.identical == [] and report.conflicts == [] and report.unknown_labels == []
    assert _catalog(db.root) == _catalog(source.root)
    assert _tree(db.root / "scans") == _tree(source.root / "scans")
    assert db.check().ok
    assert not [p for p in db.root.iterdir() if p.name.startswith(".import")]  # staging folder removed
    assert not any((db.root / ".pending").iterdir())  # no write left a pending record
    # The lab's own material arrived in this database's taxonomy extension.
    assert report.taxonomy_added == ["C9", "C9S1", "C9S1M1"]
    assert db.taxonomy().name("C9S1M1") == "mycelium leather"
    assert db.get("steel-01-001") == source.get("steel-01-001")

    again = import_bundle(db, bundle_zip if kind == "folder" else bundle)
    assert again.added == [] and again.conflicts == [] and again.taxonomy_added == []
    assert again.identical == report.added
    assert _catalog(db.root) == _catalog(source.root)


# -- damaged, incomplete and hostile bundles -------------------------------------------------------

def test_every_changed_byte_or_missing_file_is_refused_and_the_database_is_unchanged(
        bundle, target, tmp_path):
    copy = tmp_path / "bundle"
    shutil.copytree(bundle, copy)
    before = _snapshot(target.root)
    rng = random.Random(11)
    files = sorted(p for p in copy.rglob("*") if p.is_file())
    assert len(files) == 21 + 23  # 23 files of standard metadata (docs/export.md)
    for path in files:
        name = path.relative_to(copy).as_posix()
        original = path.read_bytes()
        position = rng.randrange(len(original))
        flipped = bytearray(original)
        flipped[position] ^= 1 << rng.randrange(8)
        path.write_bytes(bytes(flipped))
        expected = {MANIFEST: "manifest.json: does not match", MANIFEST_SUM: "manifest.json: does not match"}
        _refused(target, copy, expected.get(name, f"{name}: SHA-256 differs from the manifest"))
        path.unlink()
        expected = {MANIFEST: "manifest.json: missing", MANIFEST_SUM: "manifest.json.sha256: missing"}
        _refused(target, copy, expected.get(name, f"{name}: missing"))
        path.write_bytes(original)
        assert _snapshot(target.root) == before, f"damaged {name} changed the database"
    assert import_bundle(target, copy).added  # the restored bundle is fine


def test_an_unlisted_or_truncated_file_is_refused(bundle, target, tmp_path):
    copy = tmp_path / "bundle"
    shutil.copytree(bundle, copy)
    before = _snapshot(target.root)
    (copy / "scans/C6S1M1P2X1/granite-01/notes.txt").write_text("extra")
    _refused(target, copy, "scans/C6S1M1P2X1/granite-01/notes.txt: not listed in the manifest")
    (copy / "scans/C6S1M1P2X1/granite-01/notes.txt").unlink()
    mat = copy / "scans/C7S1M1P8X1/steel-01/steel-01-001.mat"
    mat.write_bytes(mat.read_bytes()[:-10])
    _refused(target, copy, "steel-01-001.mat: ")
    assert _snapshot(target.root) == before


def _member_data_offsets(path: Path) -> dict[str, int]:
    """Offset of the middle byte of every member's stored data in a zip file."""
    offsets = {}
    with zipfile.ZipFile(path) as archive, open(path, "rb") as raw:
        for info in archive.infolist():
            raw.seek(info.header_offset + 26)
            name_length, extra_length = np.frombuffer(raw.read(4), dtype="<u2")
            offsets[info.filename] = (info.header_offset + 30 + int(name_length) + int(extra_length)
                                      + info.compress_size // 2)
    return offsets


def test_a_changed_byte_in_any_zip_member_or_a_truncated_zip_is_refused(bundle_zip, target, tmp_path):
    before = _snapshot(target.root)
    original = bundle_zip.read_bytes()
    offsets = _member_data_offsets(bundle_zip)
    assert len(offsets) == 21 + 23
    damaged = tmp_path / "damaged.zip"
    for name, offset in offsets.items():
        data = bytearray(original)
        data[offset] ^= 0x10
        damaged.write_bytes(bytes(data))
        with pytest.raises(BundleError, match="refused") as caught:
            import_bundle(target, damaged)
        assert caught.value.problems, f"a changed byte in {name} went unnoticed"
    damaged.write_bytes(original[:len(original) // 2])
    with pytest.raises(BundleError, match="not a readable zip file"):
        import_bundle(target, damaged)
    assert _snapshot(target.root) == before


@pytest.mark.parametrize("name", ["../evil.txt", "/tmp/evil.txt", "scans/../../evil.txt", "C:/evil.txt",
                                  "scans\\..\\evil.txt", "scans//evil.txt"])
def test_zip_slip_and_absolute_member_names_are_refused_before_anything_is_written(
        bundle_zip, target, tmp_path, name):
    hostile = tmp_path / "hostile.zip"
    shutil.copy(bundle_zip, hostile)
    with zipfile.ZipFile(hostile, "a") as archive:
        archive.writestr(name, "pwned")
    before = _snapshot(target.root)
    error = _refused(target, hostile, "could write outside the bundle")
    assert len(error.problems) == 1
    assert _snapshot(target.root) == before
    assert not (tmp_path / "evil.txt").exists() and not (target.root / "evil.txt").exists()


def test_links_in_a_bundle_are_refused(bundle, bundle_zip, target, tmp_path):
    hostile = tmp_path / "linked.zip"
    shutil.copy(bundle_zip, hostile)
    with zipfile.ZipFile(hostile, "a") as archive:
        info = zipfile.ZipInfo("scans/link")
        info.external_attr = (stat.S_IFLNK | 0o777) << 16
        archive.writestr(info, "/etc/passwd")
    _refused(target, hostile, "scans/link: a symbolic link")
    if os.name == "posix":
        folder = tmp_path / "linked"
        shutil.copytree(bundle, folder)
        (folder / "scans" / "outside").symlink_to(tmp_path)
        _refused(target, folder, "scans/outside: a symbolic link")


def _rewrite_manifest(folder: Path, change) -> None:
    manifest = json.loads((folder / MANIFEST).read_text())
    change(manifest)
    data = json.dumps(manifest, indent=1).encode()
    (folder / MANIFEST).write_bytes(data)
    (folder / MANIFEST_SUM).write_text(f"{hashlib.sha256(data).hexdigest()}  manifest.json\n")


@pytest.mark.parametrize(("change", "problem"), [
    (lambda m: m.update(bundle_schema=2), "unknown bundle schema 2 (this software reads 1)"),
    (lambda m: m.update(scan_schema=9), "unknown scan schema 9"),
    (lambda m: m.update(format="zip-of-things"), "format 'zip-of-things' is not 'texplorer-bundle'"),
    (lambda m: m["files"].pop("taxonomy.csv"), "does not list taxonomy.csv"),
    (lambda m: m["files"].update({"../../x": {"sha256": "0" * 64, "size": 1}}), "file '../../x': "),
    (lambda m: m["files"]["features.csv"].update(size=-1), "file features.csv: needs"),
    (lambda m: m["scans"][0].update(scan_index="1"), "missing or mistyped scan_index"),
    (lambda m: m["scans"][1].update(scan_id="granite-01-001"), "scan granite-01-001 is listed twice"),
    (lambda m: m["counts"].update(scans=5), "counts.scans is 5, but 4 are listed"),
])
def test_a_bad_manifest_is_refused_even_with_a_matching_checksum(bundle, target, tmp_path, change, problem):
    copy = tmp_path / "bundle"
    shutil.copytree(bundle, copy)
    _rewrite_manifest(copy, change)
    before = _snapshot(target.root)
    _refused(target, copy, problem)
    assert _snapshot(target.root) == before


@pytest.mark.parametrize(("change", "problem"), [
    (lambda m: m["scans"][0].update(label="C6S1M1P3X1"), "manifest entry differs from the scan in label"),
    (lambda m: m["scans"][2].update(content_hash="0" * 64), "content_hash in the manifest does not match"),
    (lambda m: m["scans"][0]["files"].pop("I_macro"), "belongs to no scan of the manifest"),
])
def test_a_manifest_that_misdescribes_its_scans_is_refused(bundle, target, tmp_path, change, problem):
    copy = tmp_path / "bundle"
    shutil.copytree(bundle, copy)
    _rewrite_manifest(copy, change)
    _refused(target, copy, problem)


def _listed(manifest: dict, root: Path, names: list[str]) -> None:
    """Enter files of ``root`` in the manifest with their true SHA-256 and size: a forged, consistent bundle."""
    for name in names:
        data = (root / name).read_bytes()
        manifest["files"][name] = {"sha256": hashlib.sha256(data).hexdigest(), "size": len(data)}


def _forge_scan(folder: Path, scan, **meta) -> None:
    """Add ``scan`` to a folder bundle, its ``meta`` changed as a foreign writer could, every checksum right."""
    from scanner.storage.database import FileEntry, content_hash
    from scanner.storage.matfile import encode_mat, scan_to_variables

    scan_id = f"{scan.meta.sample_id}-{int(meta.get('scan_index', scan.meta.scan_index)):03d}"
    mat = folder / f"scans/{scan.meta.label}/{scan.meta.sample_id}/{scan_id}.mat"
    save_scan(scan, mat)
    variables = scan_to_variables(scan, mat)
    variables["meta"].update(meta)
    mat.write_bytes(encode_mat(variables))
    files = {"mat": mat.relative_to(folder).as_posix(),
             **{var: mat.with_name(f"{scan_id}_{short}.png").relative_to(folder).as_posix()
                for var, short in (("I_disp", "disp"), ("I_macro", "macro"), ("I_illu", "illu"))}}

    def change(manifest):
        _listed(manifest, folder, list(files.values()))
        entries = [FileEntry(path, role, manifest["files"][path]["sha256"], manifest["files"][path]["size"])
                   for role, path in files.items()]
        m = scan.meta
        manifest["scans"].append({"scan_id": scan_id, "label": m.label, "sample_id": m.sample_id,
                                  "session_id": m.session_id, "operator": m.operator,
                                  "scan_index": int(meta.get("scan_index", m.scan_index)), "started": m.started,
                                  "rigid": m.rigid, "content_hash": content_hash(entries), "files": files})
        manifest["counts"]["scans"] += 1

    _rewrite_manifest(folder, change)


def test_forged_scans_with_consistent_checksums_are_refused_before_anything_moves(bundle, target, tmp_path):
    overflow = tmp_path / "overflow"
    shutil.copytree(bundle, overflow)
    _forge_scan(overflow, make_scan(20, sample_id="granite-09"), scan_index=2.0**63)
    bomb = tmp_path / "bomb"
    shutil.copytree(bundle, bomb)
    _forge_scan(bomb, make_scan(21, sample_id="granite-10", image_shape=(16, 16)))
    photo = "scans/C6S1M1P2X1/granite-10/granite-10-001_disp.png"
    (bomb / photo).write_bytes(png_bomb(20_000, 20_000))
    _rewrite_manifest(bomb, lambda m: _listed(m, bomb, [photo]))
    before = _snapshot(target.root)
    _refused(target, overflow, "granite-09-9223372036854775808.mat: meta.scan_index: must be a whole number "
                               "1..9999, got 9.22337e+18")
    assert _snapshot(target.root) == before
    error = _refused(target, bomb, "I_disp: photo granite-10-001_disp.png: the image has 400,000,000 pixels")
    own = [p for p in error.problems if not p.startswith(("ro-crate-metadata.json: ", "scans.csv: "))]
    assert len(own) == 1 and _snapshot(target.root) == before
    # The forged scan is in none of the metadata the exporter wrote, which says so too.
    assert "scans.csv: 4 scans, the manifest lists 5" in error.problems
    assert "ro-crate-metadata.json: does not describe scans/C6S1M1P2X1/granite-10/granite-10-001.mat" in error.problems


def test_a_zip_entry_nested_under_a_file_is_refused_with_the_list_of_problems(bundle_zip, target, tmp_path):
    hostile = tmp_path / "nested.zip"
    with zipfile.ZipFile(bundle_zip) as source, zipfile.ZipFile(hostile, "w") as out:
        manifest = json.loads(source.read(MANIFEST))
        for info in source.infolist():
            if info.filename not in (MANIFEST, MANIFEST_SUM):
                out.writestr(info, source.read(info))
        out.writestr("features.csv/x", b"hidden")
        manifest["files"]["features.csv/x"] = {"sha256": hashlib.sha256(b"hidden").hexdigest(), "size": 6}
        data = json.dumps(manifest, indent=1).encode()
        out.writestr(MANIFEST, data)
        out.writestr(MANIFEST_SUM, f"{hashlib.sha256(data).hexdigest()}  manifest.json\n")
    before = _snapshot(target.root)
    error = _refused(target, hostile, "features.csv/x: inside features.csv, which is a file")
    assert len(error.problems) == 1 and _snapshot(target.root) == before
    _, problems = parse_manifest(json.dumps({**manifest, "format": "texplorer-bundle"}).encode())
    assert "manifest.json: features.csv/x: inside features.csv, which is a file" in problems


@pytest.mark.parametrize(("fail", "at"), [("insert", 3), ("move", 1), ("move", 7), ("move", 13)])
def test_an_import_failing_at_the_catalog_or_a_move_leaves_the_database_byte_identical(
        bundle, target, monkeypatch, fail, at):
    import scanner.storage.database as database

    before = _snapshot(target.root)
    calls = []
    real_insert, real_replace = database.Database._insert, os.replace

    def insert(self, conn, meta, entries):
        calls.append("insert")
        if fail == "insert" and calls.count("insert") == at:
            raise sqlite3.IntegrityError("UNIQUE constraint failed: files.path")
        real_insert(self, conn, meta, entries)

    def replace(source, target_path):
        if fail == "move" and "/scans/" in str(target_path) and ".import.tmp-" in str(source):
            calls.append("move")
            if calls.count("move") == at:
                raise OSError(28, "No space left on device")
        real_replace(source, target_path)

    monkeypatch.setattr(database.Database, "_insert", insert)
    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(DatabaseError if fail == "insert" else OSError):
        import_bundle(target, bundle)
    assert calls.count("move") == (at if fail == "move" else 0)  # with a refused insert nothing moved
    assert _snapshot(target.root) == before  # taxonomy.csv included: the bundle's new codes were taken back
    assert not target.taxonomy_path.exists() and target.check().ok and target.check().leftovers == []


def test_not_a_bundle(target, tmp_path):
    (tmp_path / "empty").mkdir()
    _refused(target, tmp_path / "empty", "manifest.json: missing (not a texplorer bundle")
    (tmp_path / "text.zip").write_text("not a zip")
    with pytest.raises(BundleError, match="not a readable zip file"):
        import_bundle(target, tmp_path / "text.zip")
    with pytest.raises(BundleError, match="no such bundle"):
        import_bundle(target, tmp_path / "nothing")
    assert parse_manifest(b"[1, 2]") == (None, ["manifest.json: not a JSON object"])
    assert parse_manifest(b"\xff")[1][0].startswith("manifest.json: not valid JSON")


def test_unsafe_names():
    assert unsafe_name("scans/C6S1M1P2X1/granite-01/granite-01-001.mat") is None
    assert unsafe_name("..data/x") is None  # dots inside a name are fine, only '..' components are not
    for name, reason in [("", "empty name"), ("/etc/passwd", "absolute path"), ("c:evil", "absolute path"),
                         ("a\\b", "backslash"), ("ab:c", "colon"), ("a\x00b", "NUL"), ("a/../b", "'..'"),
                         ("./a", "'.'"), ("a/", "empty"), ("a//b", "empty")]:
        assert reason in unsafe_name(name), name


# -- merging ---------------------------------------------------------------------------------------

def test_merge_skips_identical_scans_and_reports_conflicts_without_overwriting(
        source, bundle, tmp_path, capsys):
    db = Database(tmp_path / "lab")
    # granite-01-001 identical; granite-01-002 the same id with other data; steel-01 already another material.
    for record in source.records(sample="granite-01")[:1]:
        db.add(source.get(record.scan_id))
    db.add(make_scan(42, sample_id="granite-01", scan_index=2, session_id="s-2", operator="cd"))
    db.add(make_scan(43, label="C7S2M1P8X1", sample_id="steel-01", scan_index=2, session_id="x"))
    mine = db.root / "scans/C6S1M1P2X1/granite-01/granite-01-002.mat"
    mine_bytes = mine.read_bytes()

    code = main(["import", str(bundle), "--db", str(db.root)])
    out = capsys.readouterr().out
    assert code == EXIT_PROBLEMS
    assert "conflict granite-01-002: stored here with other content; not overwritten" in out
    assert ("conflict steel-01-001: sample steel-01 is C7S2M1P8X1 here, C7S1M1P8X1 in the bundle; "
            "not imported") in out
    assert "1 added, 1 identical (skipped), 2 conflict(s)" in out
    assert "taxonomy codes added to" in out and "C9, C9S1, C9S1M1" in out
    assert mine.read_bytes() == mine_bytes
    assert sorted(r.scan_id for r in db.records()) == ["granite-01-001", "granite-01-002", "mycelium-01-001",
                                                       "steel-01-002"]
    assert db.check().ok


def test_a_taxonomy_code_named_differently_here_is_a_conflict(bundle, tmp_path):
    db = Database(tmp_path / "lab")
    db.taxonomy_path.write_text(LAB_TAXONOMY.replace("mycelium leather", "fungal felt"), encoding="utf-8")
    report = import_bundle(db, bundle)
    assert report.conflicts == ["mycelium-01-001: label C9S1M1P1X1: C9S1M1 is 'fungal felt' here but "
                                "'mycelium leather' in the bundle; not imported"]
    assert report.added == ["granite-01-001", "granite-01-002", "steel-01-001"]
    assert report.taxonomy_added == []
    assert db.taxonomy().name("C9S1M1") == "fungal felt"


def test_labels_no_taxonomy_knows_are_imported_and_listed(tmp_path):
    source = Database(tmp_path / "source")
    source.add(make_scan(0, label="C9S9M9P1X1", sample_id="odd-01", images=False))
    export_database(source, tmp_path / "b", license="none", workers=1)
    db = Database(tmp_path / "lab")
    report = import_bundle(db, tmp_path / "b")
    assert report.added == ["odd-01-001"] and report.unknown_labels == ["C9S9M9P1X1"]
    assert not db.taxonomy_path.exists()


def test_cli_export_and_import_print_summaries_and_list_problems(source, tmp_path, capsys):
    out = tmp_path / "cli.zip"
    assert main(["export", str(out), "--db", str(source.root), "--label", "C7", "--workers", "1"]) == 0
    assert "exported 1 scan(s), 35 files" in capsys.readouterr().out
    assert main(["import", str(out), "--db", str(tmp_path / "new")]) == 0
    assert "imported" in capsys.readouterr().out and len(Database(tmp_path / "new")) == 1
    data = bytearray(out.read_bytes())
    data[len(data) // 3] ^= 0xFF
    out.write_bytes(bytes(data))
    assert main(["import", str(out), "--db", str(tmp_path / "new")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("problem  ") and "texplorer: error: " in err
    assert "the database was not changed" in err
    assert main(["export", str(tmp_path / "cli.zip"), "--db", str(source.root)]) == 1
    assert "already exists" in capsys.readouterr().err


# -- the catalog primitive -------------------------------------------------------------------------

def test_add_written_moves_nothing_when_one_scan_of_the_batch_clashes(tmp_path):
    db = Database(tmp_path / "db")
    db.add(make_scan(0, images=False))
    staging = tmp_path / "staging"
    staged = []
    for seed, index in ((1, 2), (2, 1)):  # granite-01-002 is new, granite-01-001 is stored already
        scan = make_scan(seed, scan_index=index, images=False)
        save_scan(scan, staging / f"{scan.scan_id}.mat")
        staged.append((scan.meta, {"mat": staging / f"{scan.scan_id}.mat"}))
    with pytest.raises(DatabaseError, match="granite-01-001 is already in the database"):
        db.add_written(staged)
    assert sorted(p.name for p in staging.iterdir()) == ["granite-01-001.mat", "granite-01-002.mat"]
    assert [r.scan_id for r in db.records()] == ["granite-01-001"] and db.check().ok
    with pytest.raises(DatabaseError, match="staged file granite-01-001.mat cannot have role 'I_disp'"):
        db.add_written([(staged[0][0], {"mat": staged[0][1]["mat"], "I_disp": staged[1][1]["mat"]})])
    assert db.add_written(staged[:1]) == ["granite-01-002"]
    assert not (staging / "granite-01-002.mat").exists() and db.check().ok


# -- interrupted import ----------------------------------------------------------------------------

IMPORTER = textwrap.dedent("""
    import os, signal, sys, time
    import scanner.storage.database as database
    from scanner.storage.bundle import import_bundle

    mode, kill_at = sys.argv[3], int(sys.argv[4])
    calls = {"replace": 0, "insert": 0}
    real_replace, real_insert = os.replace, database.Database._insert

    def counted(kind):
        calls[kind] += 1
        if kind == mode and calls[kind] == kill_at:
            os.kill(os.getpid(), signal.SIGKILL)

    def replace(*args, **kwargs):
        counted("replace")
        return real_replace(*args, **kwargs)

    def insert(*args, **kwargs):
        real_insert(*args, **kwargs)
        counted("insert")

    os.replace = replace
    database.Database._insert = insert
    print("ready", flush=True)
    started = time.perf_counter()
    import_bundle(database.Database(sys.argv[1]), sys.argv[2])
    print(calls["replace"], calls["insert"], time.perf_counter() - started, flush=True)
""")


def _run_importer(script: Path, root: Path, bundle: Path, mode: str = "none", kill_at: int = 0,
                  delay: float | None = None) -> tuple[str, int]:
    process = subprocess.Popen([sys.executable, str(script), str(root), str(bundle), mode, str(kill_at)],
                               stdout=subprocess.PIPE, text=True)
    if delay is not None:
        assert process.stdout.readline().strip() == "ready"
        time.sleep(delay)
        process.send_signal(signal.SIGKILL)
    out, _ = process.communicate(timeout=120)
    return out, process.returncode


@pytest.mark.skipif(os.name != "posix", reason="SIGKILL of a subprocess is POSIX-only")
def test_an_import_killed_at_any_moment_leaves_the_database_as_it_was_or_complete(bundle, target, tmp_path):
    script = tmp_path / "importer.py"
    script.write_text(IMPORTER)
    base = target.root
    target.close()
    before_tree, before_catalog = _snapshot(base)
    complete = tmp_path / "complete"
    shutil.copytree(base, complete)
    counts = _run_importer(script, complete, bundle)[0].split()[-3:]
    replaces, inserts, duration = int(counts[0]), int(counts[1]), float(counts[2])
    # <db>/taxonomy.csv, the pending record, then the bundle's 13 files; the 4 scans' rows come first.
    assert inserts == 4 and replaces == 1 + 1 + 13
    full_catalog = _catalog(complete)
    rng = random.Random(5)
    # Deterministic kills inside the critical window (rows inserted, the record, moving files into place,
    # before the commit), then kills at random moments of the whole run.
    kills = [("insert", inserts)] + [("replace", k) for k in sorted({1, 2, 3, replaces // 2, replaces})]
    kills += [("none", 0)] * 4
    for round_, (mode, kill_at) in enumerate(kills):
        root = tmp_path / f"round-{round_}"
        shutil.copytree(base, root)
        delay = rng.uniform(0.0, duration) if mode == "none" else None
        _, returncode = _run_importer(script, root, bundle, mode, kill_at, delay)
        with sqlite3.connect(root / "catalog.sqlite") as conn:
            assert conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        catalog = _catalog(root)
        if mode == "none":
            assert catalog in (before_catalog, full_catalog), f"partial import after {delay:.3f} s"
        else:  # killed before the commit
            assert returncode == -signal.SIGKILL and catalog == before_catalog, (mode, kill_at)
        tree = _tree(root)
        assert all(tree[path] == data for path, data in before_tree.items() if path.startswith("scans/"))
        db = Database(root)
        report = db.check()
        # Whatever the kill left is recognised as a leftover (files moved before the commit, the staging
        # folder), never as a problem or as a file nobody owns.
        assert report.ok and not report.missing and not report.changed, (mode, kill_at, report)
        if catalog == before_catalog and returncode == -signal.SIGKILL:
            assert any(path.startswith(".import.tmp-") for path in report.leftovers), (mode, kill_at, report)
        import_bundle(db, bundle)  # importing again completes the job and removes the leftovers
        report = db.check()
        assert _catalog(root) == full_catalog and report.ok and report.leftovers == [], report
        db.close()


# -- the loaders in the bundle ---------------------------------------------------------------------

ISOLATED = textwrap.dedent("""
    import importlib.abc, runpy, sys

    class NoProject(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in {packages!r}:
                raise ImportError("the bundle loader must not import " + name)

    sys.meta_path.insert(0, NoProject())
    sys.argv = [sys.argv[1], *sys.argv[2:]]
    runpy.run_path(sys.argv[0], run_name="__main__")
""").format(packages=set(PROJECT_PACKAGES))

USE_LOADER = textwrap.dedent("""
    import sys
    import numpy as np
    from load_texplorer import load_features, load_features_mat, load_scan, verify

    bundle, out = sys.argv[1], sys.argv[2]
    assert verify(bundle) == []
    X, columns, rows = load_features(bundle)
    scan = load_scan(bundle + "/scans/C7S1M1P8X1/steel-01/steel-01-001.mat")
    mat = load_features_mat(bundle)
    np.savez(out, X=X, columns=np.array(columns), ids=np.array([r["scan_id"] for r in rows]),
             parts=np.array([[r[p] for p in "CSMPX"] for r in rows]), v_ts=scan["v_ts"],
             v_ts_raw=scan["v_ts_raw"],
             a_fs=scan["a_fs"], fs_a_fs=scan["meta"]["fs"]["a_fs"], label=scan["meta"]["label"],
             photo=str(scan["photos"]["I_disp"]), X_mat=mat["X"], labels_mat=mat["labels"])
    print("loaded")
""")


def _isolated(script_args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-I", "-c", ISOLATED, *script_args], cwd=cwd, capture_output=True,
                          text=True, timeout=120)


def test_the_python_loader_reads_the_bundle_without_the_project(source, bundle, tmp_path):
    probe = _isolated([str(bundle / "load_texplorer.py"), str(bundle)], tmp_path)
    assert probe.returncode == 0, probe.stderr
    assert "verified 42 files: 0 problem(s)" in probe.stdout
    assert "bundle of 4 scans, 3 materials" in probe.stdout
    assert "scan granite-01-001: label C6S1M1P2X1, v_ts (600, 3) at 3000 Hz, photos I_disp, I_illu, I_macro" \
        in probe.stdout
    assert "features: 4 scans x 193 columns" in probe.stdout

    user = tmp_path / "user.py"
    user.write_text(f"import sys\nsys.path.insert(0, {str(bundle)!r})\n" + USE_LOADER)
    result = _isolated([str(user), str(bundle), str(tmp_path / "out.npz")], tmp_path)
    assert result.returncode == 0 and result.stdout.strip() == "loaded", result.stderr
    got = np.load(tmp_path / "out.npz")
    space = FeatureSpace.from_csv(bundle / "features.csv")
    np.testing.assert_array_equal(got["X"], space.X)
    np.testing.assert_array_equal(got["X_mat"], space.X)
    assert tuple(got["columns"]) == space.columns and tuple(got["ids"]) == space.scan_ids
    np.testing.assert_array_equal(got["parts"], space.labels)
    np.testing.assert_array_equal(got["labels_mat"], space.labels)
    steel = source.get("steel-01-001")
    np.testing.assert_array_equal(got["v_ts"], steel["v_ts"].data)
    np.testing.assert_array_equal(got["v_ts_raw"], steel.raw["v_ts"].data)
    np.testing.assert_array_equal(got["a_fs"], steel["a_fs"].data)  # 1-D channels come back 1-D
    assert float(got["fs_a_fs"]) == 44100.0 and str(got["label"]) == "C7S1M1P8X1"
    assert Path(str(got["photo"])) == bundle / "scans/C7S1M1P8X1/steel-01/steel-01-001_disp.png"


def test_the_python_loader_reports_a_damaged_bundle(bundle, tmp_path):
    copy = tmp_path / "bundle"
    shutil.copytree(bundle, copy)
    (copy / "features.csv").write_text("scan_id\n")
    probe = _isolated([str(copy / "load_texplorer.py"), str(copy)], tmp_path)
    assert probe.returncode != 0
    assert "problem  features.csv: SHA-256 differs from the manifest" in probe.stdout


@pytest.mark.skipif(shutil.which("octave") is None,
                    reason="GNU Octave is not installed (apt-get install octave)")
def test_octave_loads_a_scan_and_the_feature_table(bundle, tmp_path):
    scan = bundle / "scans/C7S1M1P8X1/steel-01/steel-01-001.mat"
    code = (f"addpath('{bundle}'); s = load_texplorer('{scan}'); "
            "printf('%d %d\\n', size(s.v_ts)); printf('%s\\n', s.meta.label); "
            "printf('%g\\n', s.meta.fs.a_fs); printf('%s\\n', s.photos.I_disp); "
            f"F = load_texplorer('{bundle}'); printf('%d %d\\n', size(F.X)); "
            "printf('%s\\n', F.columns{1}); printf('%s\\n', F.scan_id{1});")
    result = subprocess.run(["octave", "--no-gui", "--no-window-system", "--quiet", "--eval", code],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.split()
    assert lines[:4] == ["600", "3", "C7S1M1P8X1", "44100"]
    assert lines[4].endswith("steel-01-001_disp.png")
    first_column = FeatureSpace.from_csv(bundle / "features.csv").columns[0]
    assert lines[5:] == ["4", "193", first_column, "granite-01-001"]

