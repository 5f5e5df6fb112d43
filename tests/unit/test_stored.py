"""Stored scans loaded elsewhere (scanner.storage.stored): a worker's view of the files is checked against the
catalogued size and SHA-256, and a scan sent as bytes loads, or fails, exactly as a local load does."""

from __future__ import annotations

import hashlib
import pickle
import shutil
from pathlib import Path

import pytest
from conftest import make_scan

from scanner.photo import MAX_PIXELS_ENV
from scanner.storage import matfile
from scanner.storage.matfile import ScanFormatError, encode_mat, load_scan, photo_names, save_scan, scan_to_variables
from scanner.storage.stored import ChangedSinceStored, NotOnThisMachine, SeenFiles, ShippedScan, StoredScan


def stored(tmp_path: Path, image_shape: tuple[int, int] = (240, 320)) -> StoredScan:
    """A saved scan with the size and SHA-256 of its files, as ``Database.stored_scans`` gives it."""
    files = save_scan(make_scan(seed=3, image_shape=image_shape), tmp_path / "scan.mat")
    return StoredScan(tmp_path / "scan.mat", {p.name: (p.stat().st_size, hashlib.sha256(p.read_bytes()).hexdigest())
                                              for p in files})


def local_error(path: Path) -> str:
    with pytest.raises(ScanFormatError) as local:
        load_scan(path)
    return str(local.value)


def received(scan: StoredScan, folder: Path) -> ShippedScan:
    """The scan as a worker gets it from the client (pickled), with the client's files gone."""
    shipped = pickle.loads(pickle.dumps(scan.shipped()))
    shutil.rmtree(folder)
    folder.mkdir()
    return shipped


def test_a_file_view_gives_the_same_scan_as_the_file_system(tmp_path):
    scan = stored(tmp_path)
    expected = scan()
    assert load_scan(scan.path, files=SeenFiles(scan.catalogued)) == expected
    assert photo_names(scan.path.read_bytes()) == ["scan_disp.png", "scan_macro.png", "scan_illu.png"]
    assert photo_names(b"not a mat file") == []


def test_shipped_bytes_travel_and_load_as_the_files(tmp_path):
    scan = stored(tmp_path)
    expected = scan()
    total = sum(p.stat().st_size for p in tmp_path.iterdir())
    shipped = received(scan, tmp_path)  # the worker has none of the files
    assert sorted(shipped.files) == ["scan.mat", "scan_disp.png", "scan_illu.png", "scan_macro.png"]
    assert shipped.nbytes == total and shipped() == expected


def _damage(scan: StoredScan, folder: Path, damage: str) -> None:
    if damage == "missing photo":
        (folder / "scan_macro.png").unlink()
    elif damage == "photo is a folder":
        (folder / "scan_macro.png").unlink()
        (folder / "scan_macro.png").mkdir()
    elif damage == "truncated mat":
        scan.path.write_bytes(scan.path.read_bytes()[:200])
    elif damage == "missing mat":
        scan.path.unlink()
    elif damage == "photo not an image":
        (folder / "scan_illu.png").write_bytes(b"no png")
    else:
        variables = scan_to_variables(make_scan(seed=3), scan.path)
        scan.path.write_bytes(encode_mat({**variables, "I_disp": "../scan_disp.png"}))


@pytest.mark.parametrize("damage", ["missing photo", "photo is a folder", "truncated mat", "missing mat",
                                    "photo not an image", "photo name with a folder"])
def test_a_shipped_scan_fails_exactly_as_a_local_load(tmp_path, damage):
    scan = stored(tmp_path)
    _damage(scan, tmp_path, damage)
    with pytest.raises((ScanFormatError, ChangedSinceStored)) as local:
        scan()  # a catalogued file damaged in place is one changed since it was stored
    shipped = received(scan, tmp_path)
    with pytest.raises(type(local.value)) as remote:
        shipped()
    assert str(remote.value) == str(local.value)
    assert isinstance(local.value, ChangedSinceStored) == (damage not in ("missing photo", "missing mat"))


def test_files_beyond_the_limits_are_refused_unread_and_reported_as_locally(tmp_path, monkeypatch):
    scan = stored(tmp_path, image_shape=(800, 800))  # photos of noise: PNG files of about 2 MB
    monkeypatch.setenv(MAX_PIXELS_ENV, "10000")  # files beyond 4 bytes a pixel and 1 MB are not read
    expected = local_error(scan.path)
    assert "MB is more than a photo within the pixel limit can take" in expected
    shipped = received(scan, tmp_path)
    assert all(shipped.files[name].data is None for name in ("scan_disp.png", "scan_macro.png", "scan_illu.png"))
    with pytest.raises(ScanFormatError) as remote:
        shipped()
    assert str(remote.value) == expected
    monkeypatch.delenv(MAX_PIXELS_ENV)
    scan = stored(tmp_path)
    monkeypatch.setattr(matfile, "MAX_SCAN_BYTES", 1000)
    monkeypatch.setattr("scanner.storage.stored.MAX_SCAN_BYTES", 1000)
    expected = local_error(scan.path)
    assert "MB is larger than the 0 MB a scan file may have" in expected
    shipped = received(scan, tmp_path)
    assert list(shipped.files) == ["scan.mat"] and shipped.files["scan.mat"].data is None
    with pytest.raises(ScanFormatError) as remote:
        shipped()
    assert str(remote.value) == expected


def test_a_worker_loads_only_the_catalogued_bytes(tmp_path):
    scan = stored(tmp_path)
    expected = scan()
    assert scan.visible() and scan.load_seen() == expected
    photo = tmp_path / "scan_illu.png"
    original = photo.read_bytes()
    photo.write_bytes((tmp_path / "scan_disp.png").read_bytes())  # another valid photo of the same size
    assert scan.visible()  # the probe looks at the .mat only
    with pytest.raises(NotOnThisMachine, match=r"scan_illu.png: other content than catalogued \(SHA-256"):
        scan.load_seen()
    photo.write_bytes(original + b"\0")
    with pytest.raises(NotOnThisMachine, match=r"scan_illu.png: other content than catalogued \(size"):
        scan.load_seen()
    photo.write_bytes(original)
    scan.path.rename(tmp_path / "elsewhere.mat")
    assert not scan.visible()
    with pytest.raises(NotOnThisMachine, match=r"scan.mat: no such file here"):
        scan.load_seen()
    uncatalogued = StoredScan(tmp_path / "elsewhere.mat")  # files named on the command line: no catalog
    assert uncatalogued.visible() and uncatalogued.load_seen() == expected


def test_a_shipped_scan_without_its_file_says_so():
    with pytest.raises(ScanFormatError, match="file not found"):
        ShippedScan(Path("gone/scan.mat"), {})()
