"""Import of other labs' recordings: every format quirk on small fixture files, bad files, storage."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from scanner.scan import Recording, Trace
from scanner.simulation.recordings import biotac_recordings, biotac_rows
from scanner.storage import ingest
from scanner.storage.ingest import IngestError

FIXTURES = Path(__file__).parents[1] / "fixtures" / "ingest"


def run(lab: str) -> ingest.IngestReport:
    return ingest.ingest(FIXTURES / f"lab-{lab}", ingest.load_mapping(FIXTURES / f"lab-{lab}.toml"))


@pytest.fixture(scope="module")
def lab_a():
    return run("a")


def test_csv_and_tsv_stems_labels_and_groups(lab_a):
    by = {r.name: r for r in lab_a.recordings}
    assert sorted(by) == ["metal-1_t01_static", "sponge-1_t01_static"]
    sponge = by["sponge-1_t01_static"]
    assert sponge.label == "sponge" and sponge.meta["label_level"] == "material"
    assert dict(sponge.group) == {"object": "sponge-1", "trial": "01", "motion": "static"}
    assert dict(sponge.roles) == {"vibration": "pac", "pressure_dc": "pdc", "electrodes": "electrodes",
                                  "temperature": "tdc"}
    assert sponge.meta["source"] == ["sponge/sponge-1_t01_static_pac.csv",
                                     "sponge/sponge-1_t01_static_slow.tsv"]


def test_spread_columns_become_one_fast_channel(lab_a):
    pac = {r.name: r for r in lab_a.recordings}["metal-1_t01_static"].channels["pac"]
    # Rows 10 ms apart (a millisecond time column) with 22 samples each: 2200 Hz. Sample k holds 1000 + k;
    # the nan and -nan tokens at samples 25 and 32 are filled by linear interpolation, so they too.
    assert pac.fs == pytest.approx(2200.0) and pac.unit == "bit"
    assert np.array_equal(pac.data, 1000.0 + np.arange(88))
    assert "metal-1_t01_static_pac.csv: channel pac: 2 missing sample(s) interpolated" in map(str, lab_a.notes)


def test_tsv_at_a_given_rate_with_comment_and_column_index(lab_a):
    sponge = {r.name: r for r in lab_a.recordings}["sponge-1_t01_static"]
    assert sponge.channels["pdc"].fs == 50.0 and sponge.channels["pdc"].data.tolist() == [100.0, 101.0, 102.0]
    assert sponge.channels["electrodes"].data.tolist() == [[3000, 3100, 3200], [3001, 3101, 3201],
                                                          [3002, 3102, 3202]]
    assert sponge.channels["tdc"].data == pytest.approx([25.0, 24.99, 24.98])  # column 4, scale 0.01
    assert sponge.channels["tdc"].unit == "degC"


def test_bad_files_are_named_and_skipped(lab_a):
    assert lab_a.files == 8
    skipped = [line.replace(str(FIXTURES), "F") for line in lab_a.skipped]
    assert skipped == [
        "F/lab-a/metal/metal-1_t02_static_pac.csv: line 4, column pac_05: 'abc' is not a number",
        "metal/metal-1_t02_static: recording skipped, metal-1_t02_static_pac.csv is unusable",
        "F/lab-a/metal/metal-1_t03_static_pac.csv: line 4: 22 fields, expected 23",
        "metal/metal-1_t03_static: recording skipped, metal-1_t03_static_pac.csv is unusable",
        "F/lab-a/sponge/notes_pac.csv: name does not match groups.pattern",
    ]


def test_wav_npz_and_a_label_table():
    report = run("b")
    by = {r.name: r for r in report.recordings}
    assert sorted(by) == ["cup_01", "plate_01"]
    cup = by["cup_01"]
    assert cup.label == "cup" and cup.meta["levels"] == {"material": "ceramic"}
    assert cup.meta["label_level"] == "object"
    # 16-bit PCM to full scale: 16384 is 0.5, 32767 is 32767 / 32768.
    assert cup.channels["audio"].fs == 8000.0 and cup.channels["audio"].data[:4].tolist() == [0, 0.5, -0.5,
                                                                                               32767 / 32768]
    # The rate comes from the archive's "fs" variable.
    assert cup.channels["xyz"].fs == 1000.0 and cup.channels["xyz"].data.shape == (10, 3)
    assert np.array_equal(by["plate_01"].channels["xyz"].data, 2 * np.arange(30.0).reshape(10, 3))
    skipped = [line.replace(str(FIXTURES), "F") for line in report.skipped]
    assert skipped[0].startswith("F/lab-b/broken_01.npz: not a readable NPZ file (BadZipFile")
    assert skipped[1:] == ["broken_01: recording skipped, broken_01.npz is unusable",
                           "mug_01: recording skipped: no label for 'mug_01' in labels.csv"]


def test_npy_mat_headerless_csv_and_labels_from_the_name():
    report = run("c")
    by = {r.name: r for r in report.recordings}
    assert sorted(by) == ["foam_a", "wood_b"]
    wood = by["wood_b"]
    assert wood.label == "wood" and dict(wood.group) == {"object": "b"}
    assert wood.meta["sensor"] == "lab C array"
    assert wood.channels["taxels"].data.shape == (5, 4, 4) and wood.role("taxels") is wood.channels["taxels"]
    assert np.array_equal(wood.channels["electrodes"].data, np.arange(10.0).reshape(5, 2) + 2)
    assert wood.channels["temp"].data.shape == (5,) and wood.channels["temp"].data[0] == 32.0  # n x 1 -> 1-D
    # Headerless, trailing commas: column 1 at the given 200 Hz.
    assert wood.channels["pdc"].fs == 200.0
    assert wood.channels["pdc"].data.tolist() == [2.0, 2.5, 3.0, 3.5, 4.0]
    assert report.skipped[0].endswith("wood_c.mat: MATLAB v7.3 (HDF5) files are not read; save with -v7")


def test_array_files_announcing_more_than_the_limit_are_refused_from_their_headers(tmp_path, monkeypatch):
    from hostile_scans import inflation_bomb

    header = {"descr": "<f8", "fortran_order": False, "shape": (10**6, 10**6)}
    with open(tmp_path / "huge.npy", "wb") as handle:  # 8 TB announced in 128 bytes
        np.lib.format.write_array_header_1_0(handle, header)
        handle.write(bytes(64))
    spec = ingest.FileMap(glob="*", suffix=None, format=None, channels=(ingest.ChannelMap("v", "vibration"),),
                          rate=100.0)
    with pytest.raises(IngestError, match=r"huge.npy: its arrays take 8000000 MB, more than the 1074 MB"):
        ingest.read_file(tmp_path / "huge.npy", spec)
    (tmp_path / "bomb.mat").write_bytes(inflation_bomb(64 << 20))  # 64 MB of zeros in 64 kB
    monkeypatch.setattr(ingest.readers, "MAX_ARRAY_BYTES", 16 << 20)
    with pytest.raises(IngestError, match="bomb.mat: not a readable MAT file .its variables inflate beyond"):
        ingest.read_file(tmp_path / "bomb.mat", spec)
    np.savez(tmp_path / "ok.npz", v=np.arange(4.0))  # within the limit: read
    assert ingest.read_file(tmp_path / "ok.npz", spec)[0]["v"].data.tolist() == [0.0, 1.0, 2.0, 3.0]


def test_read_table_quirks(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("a,b,c,\n1,nan,3,\n4,-NaN,,\n")
    names, values = ingest.read_table(path, ",", header=True)
    assert names == ["a", "b", "c"]
    assert np.array_equal(values, [[1, np.nan, 3], [4, np.nan, np.nan]], equal_nan=True)
    path.write_text("a;b\n1;2\n3\n")
    with pytest.raises(IngestError, match=r"t.csv: line 3: 1 fields, expected 2$"):
        ingest.read_table(path, ";", header=True)
    path.write_text("a\n")
    with pytest.raises(IngestError, match="a header but no data rows"):
        ingest.read_table(path, ",", header=True)


def test_rate_from_a_time_column(tmp_path):
    path = tmp_path / "x.csv"
    times = np.array([0.0, 0.01, 0.02, 0.03])
    assert ingest.rate_from_times(times, "s", path) == (pytest.approx(100.0), None)
    rate, note = ingest.rate_from_times(np.array([0, 1000, 2000, 3200, 4000]), "us", path)
    assert rate == pytest.approx(1000.0) and note == "x.csv: time steps vary by up to 20 %"
    with pytest.raises(IngestError, match="the time column does not increase at data row 3"):
        ingest.rate_from_times(np.array([0.0, 1.0, 1.0]), "s", path)


def test_missing_samples_can_be_refused(tmp_path):
    mapping = ingest.parse_mapping('missing = "error"\n[[files]]\nglob = "**/*.csv"\nrate = 10.0\n'
                                   '[[files.channels]]\nname = "v"\nrole = "vibration"\ncolumns = "v"\n', "m")
    (tmp_path / "lab" / "foam").mkdir(parents=True)
    (tmp_path / "lab" / "foam" / "r1.csv").write_text("v\n1\nnan\n3\n")
    report = ingest.ingest(tmp_path / "lab", mapping)
    assert report.recordings == [] and report.skipped[0].endswith("r1.csv: channel v: 1 missing sample(s)")


@pytest.mark.parametrize("text, message", [
    ('[[files]]\nglob = "*.csv"\n', "files[0]: needs at least one [[files.channels]] table"),
    ('[[files]]\nglob = "*.csv"\n[[files.channels]]\nname = "v"\nrole = "vibe"\n',
     "files[0].channels[0]: unknown role 'vibe'"),
    ('[[files]]\nglob = "*.csv"\nformat = "xlsx"\n[[files.channels]]\nname = "v"\n', "unknown format 'xlsx'"),
    ('[[files]]\nglob = "*.csv"\ndelim = ","\n[[files.channels]]\nname = "v"\n', "unknown key(s) delim"),
    ('[groups]\npattern = "(?P<x"\n[[files]]\nglob = "*"\n[[files.channels]]\nname = "v"\n',
     "groups: pattern is not a regular expression"),
    ('[labels]\nfrom = "pattern"\n[[files]]\nglob = "*"\n[[files.channels]]\nname = "v"\n',
     "labels: from = 'pattern' needs a (?P<label>...) group"),
    ('[[files]]\nglob = "*"\nrate = -1\n[[files.channels]]\nname = "v"\n', "rate must be positive, got -1"),
    ('[[files]]\nglob = "*"\n[[files.channels]]\nname = "2v"\n',
     "name '2v' must be a MATLAB-style identifier"),
    ("name = 'a b'\n", "name 'a b' must be 1-64 letters"),
    ("files = [\n", "not valid TOML"),
])
def test_mapping_errors_name_the_key(text, message):
    with pytest.raises(IngestError) as info:
        ingest.parse_mapping(text, "m", "MAP.toml")
    text = str(info.value)
    assert text.startswith("MAP.toml") and message in text and "\n" not in text


def test_simulated_biotac_rows_round_trip_through_csv(tmp_path):
    recording = biotac_recordings(classes=["paper"], objects=1, trials=1, motions=["slide_left"])[0]
    columns, rows = biotac_rows(recording)
    folder = tmp_path / "data" / "paper"
    folder.mkdir(parents=True)
    lines = [",".join(columns)] + [",".join(repr(float(v)) for v in row) for row in rows]
    (folder / "paper-1_t01_slideleft.csv").write_text("\n".join(lines) + "\n")
    mapping = ingest.parse_mapping(
        '[[files]]\nglob = "**/*.csv"\ntime_column = "time"\n'
        '[[files.channels]]\nname = "pac"\nrole = "vibration"\ncolumns = "pac_01:pac_22"\nspread = true\n'
        '[[files.channels]]\nname = "electrodes"\nrole = "electrodes"\ncolumns = "e01:e19"\n', "sim")
    back = ingest.ingest(tmp_path / "data", mapping).recordings[0]
    assert back.label == "paper" and back.channels["pac"].fs == pytest.approx(2200.0)
    assert np.array_equal(back.channels["pac"].data, recording.channels["pac"].data)
    assert np.array_equal(back.channels["electrodes"].data, recording.channels["electrodes"].data)


def test_store_and_load_a_set(tmp_path, lab_a):
    folder = ingest.store_recordings(tmp_path, "lab-a", lab_a.recordings)
    assert folder == tmp_path / "recordings" / "lab-a" and ingest.recording_sets(tmp_path) == ["lab-a"]
    back = ingest.load_recordings(folder)
    for original, loaded in zip(lab_a.recordings, back, strict=True):
        assert loaded.name == original.name and dict(loaded.channels) == dict(original.channels)
        assert (dict(loaded.roles), loaded.label, dict(loaded.group), dict(loaded.meta)) == \
            (dict(original.roles), original.label, dict(original.group), dict(original.meta))
    with pytest.raises(IngestError, match="the set 'lab-a' exists"):
        ingest.store_recordings(tmp_path, "lab-a", lab_a.recordings)
    one = [Recording("only", {"v": Trace(np.arange(4.0), 10.0, "-")}, label="x")]
    ingest.store_recordings(tmp_path, "lab-a", one, replace=True)
    assert [r.name for r in ingest.load_recordings(folder)] == ["only"]
    assert [p.name for p in (tmp_path / "recordings").iterdir() if p.is_dir()] == ["lab-a"]  # no temporary folders
    with pytest.raises(IngestError, match="set name '../x' must be"):
        ingest.store_recordings(tmp_path, "../x", one)
    (tmp_path / "junk.mat").write_bytes(b"not a mat file")
    with pytest.raises(IngestError, match="junk.mat: not a readable recording file"):
        ingest.read_recording(tmp_path / "junk.mat")


def test_cli_ingest_reports_bad_files_and_stores_the_set(tmp_path, capsys):
    from scanner.cli import main

    db = tmp_path / "db"
    lab_b = [str(FIXTURES / "lab-b"), "--mapping", str(FIXTURES / "lab-b.toml"), "--db", str(db)]
    code = main(["ingest", *lab_b])
    out = capsys.readouterr().out.splitlines()
    assert code == 3  # some files were bad
    assert [line.split()[0] for line in out] == ["skipped"] * 3 + ["2"]
    folder = db / "recordings" / "lab-b-audio-force"
    assert out[-1] == f"2 recording(s) from 8 file(s) -> {folder}; roles audio, force_xyz; 3 problem line(s)"
    assert ingest.recording_sets(db) == ["lab-b-audio-force"]
    assert main(["ingest", *lab_b]) == 1
    assert "the set 'lab-b-audio-force' exists" in capsys.readouterr().err
    lab_c = [str(FIXTURES / "lab-c"), "--mapping", str(FIXTURES / "lab-c.toml"), "--db", str(db)]
    assert main(["ingest", *lab_c, "--name", "c"]) == 3
    assert ingest.recording_sets(db) == ["c", "lab-b-audio-force"]


# -- photos, patches, splits, names, time bases -------------------------------------------------------

def write_png(path: Path, image: np.ndarray) -> None:
    import cv2

    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), image[..., ::-1] if image.ndim == 3 else image)


def test_photos_of_every_kind_become_rgb_and_a_grid_cuts_them_into_patches(tmp_path):
    import cv2

    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (41, 62, 3), dtype=np.uint8)
    write_png(tmp_path / "cork" / "a.png", rgb)
    write_png(tmp_path / "cork" / "gray.bmp", rgb[..., 0])
    (tmp_path / "felt").mkdir()
    assert cv2.imwrite(str(tmp_path / "felt" / "deep.tif"), rgb[..., ::-1].astype(np.uint16) * 257)
    (tmp_path / "felt" / "broken.jpg").write_bytes(b"\xff\xd8\xff\xe0 not really")
    report = ingest.ingest(tmp_path, ingest.default_mapping("photos"))
    by = {r.name: r for r in report.recordings}
    assert sorted(by) == ["a", "deep", "gray"] and by["a"].label == "cork" and by["deep"].label == "felt"
    assert np.array_equal(by["a"].image(), rgb) and by["a"].roles == {"photo": "photo"}
    assert np.array_equal(by["gray"].image(), np.repeat(rgb[..., :1], 3, axis=2))
    assert np.array_equal(by["deep"].image(), rgb)  # 16 bits: v * 257 / 257
    assert report.skipped[0].endswith("broken.jpg: cannot read the image (the JPEG file is damaged "
                                      "(no frame header))")
    cut = ingest.ingest(tmp_path, ingest.with_grid(ingest.default_mapping("patches"), (2, 3)))
    patches = [r for r in cut.recordings if r.group.get("photo") == "a"]
    # 41 x 62 px in 2 x 3 patches of 20 x 20 px; the odd row and the 2 spare columns split around them.
    assert [r.name for r in patches] == [f"a_r{r}c{c}" for r in range(2) for c in range(3)]
    assert np.array_equal(patches[4].image(), rgb[20:40, 21:41]) and patches[4].meta["patch"] == [1, 1]
    folder = ingest.store_recordings(tmp_path / "db", "patches", cut.recordings)
    back = {r.name: r for r in ingest.load_recordings(folder)}
    assert np.array_equal(back["a_r1c1"].image(), rgb[20:40, 21:41])
    assert back["a_r1c1"].group == {"photo": "a", "row": "1", "column": "1"}


def test_images_beyond_the_photo_limit_or_of_other_kinds_are_refused_before_decoding(tmp_path):
    import struct

    from conftest import png_bomb

    folder = tmp_path / "lab" / "cork"
    folder.mkdir(parents=True)
    (folder / "bomb.png").write_bytes(png_bomb(20_000, 20_000))
    bmp = b"BM" + bytes(12) + struct.pack("<Iii", 40, 100_000, -100_000) + bytes(64)
    (folder / "huge.bmp").write_bytes(bmp)
    entries = [(256, 4, 1, 70_000), (257, 4, 1, 70_000)]  # ImageWidth, ImageLength as LONGs
    tiff = b"II*\x00" + struct.pack("<I", 8) + struct.pack("<H", len(entries)) + b"".join(
        struct.pack("<HHII", *entry) for entry in entries) + bytes(4)
    (folder / "tall.tif").write_bytes(tiff)
    (folder / "photo.jpg").write_bytes(b"GIF89a" + bytes(64))
    report = ingest.ingest(tmp_path / "lab", ingest.default_mapping("photos"))
    assert report.recordings == []
    assert sorted(line.split("/")[-1] for line in report.skipped if "cannot read" in line) == sorted([
        "bomb.png: cannot read the image (bomb.png: the image has 400,000,000 pixels (20000 x 20000); at most "
        "25,000,000 are accepted ($TEXPLORER_MAX_PHOTO_PIXELS))",
        "huge.bmp: cannot read the image (huge.bmp: the image has 10,000,000,000 pixels (100000 x 100000); at "
        "most 25,000,000 are accepted ($TEXPLORER_MAX_PHOTO_PIXELS))",
        "tall.tif: cannot read the image (tall.tif: the image has 4,900,000,000 pixels (70000 x 70000); at most "
        "25,000,000 are accepted ($TEXPLORER_MAX_PHOTO_PIXELS))",
        "photo.jpg: cannot read the image (not a PNG, JPEG, BMP or TIFF file)"])


def test_a_split_by_folder_is_kept_and_equal_names_get_ids_from_their_paths(tmp_path):
    from scipy.io import wavfile

    for part in ("train", "test"):
        for label in ("cork", "felt"):
            path = tmp_path / "sounds" / part / label / "take1.wav"
            path.parent.mkdir(parents=True)
            wavfile.write(path, 8000, np.zeros(800, np.int16))
    report = ingest.ingest(tmp_path / "sounds", ingest.default_mapping("s"))
    names = {r.name: (r.label, r.meta.get("split")) for r in report.recordings}
    assert names == {"test_cork_take1": ("cork", "test"), "test_felt_take1": ("felt", "test"),
                     "train_cork_take1": ("cork", "train"), "train_felt_take1": ("felt", "train")}
    assert ingest.recording_names([tmp_path / "x" / ("a" * 70), tmp_path / "y" / ("a" * 70)], tmp_path) == {
        tmp_path / "x" / ("a" * 70): "x_" + "a" * 53 + "-" + __import__("hashlib").sha256(
            ("x/" + "a" * 70).encode()).hexdigest()[:8],
        tmp_path / "y" / ("a" * 70): "y_" + "a" * 53 + "-" + __import__("hashlib").sha256(
            ("y/" + "a" * 70).encode()).hexdigest()[:8]}
    only_train = ingest.ingest(tmp_path / "sounds" / "train", ingest.default_mapping("s"))
    assert all("split" not in r.meta for r in only_train.recordings)  # one part is not a split
    pattern = ingest.parse_mapping('[groups]\npattern = "^(?P<split>[a-z]+)_"\n[split]\nfrom = "pattern"\n'
                                   'test = ["val"]\n[[files]]\nglob = "**/*.wav"\n', "m")
    (tmp_path / "flat" / "cork").mkdir(parents=True)
    for stem in ("train_1", "val_1", "other_1"):
        wavfile.write(tmp_path / "flat" / "cork" / f"{stem}.wav", 8000, np.zeros(800, np.int16))
    report = ingest.ingest(tmp_path / "flat", pattern)
    assert {r.name: r.meta["split"] for r in report.recordings} == {"train_1": "train", "val_1": "test"}
    assert report.skipped == ["cork/other_1: recording skipped: other_1: split 'other' is neither train "
                              "(train, training) nor test (val)"]


def two_stream_mapping(missing: str = "interpolate") -> ingest.IngestMapping:
    return ingest.parse_mapping(
        f'missing = "{missing}"\n'
        '[[files]]\nglob = "**/*_tactile.csv"\nsuffix = "_tactile.csv"\ntime_column = "t"\n'
        '[[files.channels]]\nname = "pdc"\nrole = "pressure_dc"\ncolumns = "p"\n'
        '[[files]]\nglob = "**/*_force.csv"\nsuffix = "_force.csv"\ntime_column = "t_ms"\ntime_unit = "ms"\n'
        'rate = 200.0\n[[files.channels]]\nname = "force"\nrole = "force_xyz"\ncolumns = ["fx", "fy", "fz"]\n',
        "two")


def test_timestamped_streams_are_aligned_and_gaps_reported_not_silently_filled(tmp_path):
    folder = tmp_path / "lab" / "cork"
    folder.mkdir(parents=True)
    # Tactile at 100 Hz from t = 0.10 s; force at 200 Hz from t = 0.05 s with the samples of 0.30-0.34 s lost.
    t = (0.10 + np.arange(100) / 100).tolist()
    (folder / "r1_tactile.csv").write_text("t,p\n" + "".join(f"{a!r},{3 * a!r}\n" for a in t))
    tf = np.round(0.05 + np.arange(240) / 200, 9)
    kept = tf[(tf < 0.299) | (tf > 0.341)].tolist()
    (folder / "r1_force.csv").write_text("t_ms,fx,fy,fz\n" + "".join(
        f"{1000 * a!r},{a!r},{2 * a!r},1.0\n" for a in kept))
    report = ingest.ingest(tmp_path / "lab", two_stream_mapping())
    recording = report.recordings[0]
    pdc, force = recording.channels["pdc"], recording.channels["force"]
    # Common span: from 0.10 s (the later start) to 1.10 s (the tactile stream's end).
    assert pdc.fs == pytest.approx(100.0, rel=1e-12) and np.array_equal(pdc.data, 3 * np.array(t))
    assert force.fs == 200.0 and force.data.shape == (200, 3)
    grid = 0.10 + np.arange(200) / 200
    # fx = t is linear, so bridging the gap linearly gives back t exactly (to rounding) on the whole grid.
    assert force.data[:, 0] == pytest.approx(grid, abs=1e-12) and np.all(force.data[:, 2] == 1.0)
    notes = [str(n) for n in report.notes]
    assert "r1_force.csv: channel force: 1 gap(s) in the timestamps, 9 sample(s) missing; the longest 0.05 s " \
        "at t = 0.295 s (bridged linearly)" in notes
    assert any(n.startswith("r1_force.csv: channel(s) force cut to the span (1 s from t = 0.1 s)") for n in notes)
    info = recording.meta["time_base"]
    assert info["start_s"] == pytest.approx(0.10) and info["channels"]["force"]["bridged_samples"] == 9
    refused = ingest.ingest(tmp_path / "lab", two_stream_mapping("error"))
    assert refused.recordings == [] and "9 sample(s) missing" in refused.skipped[0]


def test_notes_are_summarised_per_kind_with_the_worst_first_names():
    notes = [ingest.Note("irregular", f"f{i}.csv", i / 100, f"f{i}.csv: time steps vary by up to {i} %")
             for i in range(1, 6)] + [ingest.Note("missing", "g.csv", 2, "g.csv: 2 missing sample(s)")]
    assert ingest.summarise_notes(notes) == [
        "irregular time steps resampled in 5 file(s) (f1.csv, f2.csv, f3.csv and 2 more); worst: f5.csv: "
        "time steps vary by up to 5 %",
        "missing samples interpolated in 1 file(s) (g.csv); worst: g.csv: 2 missing sample(s)"]


def test_unix_timestamps_print_as_dates():
    assert ingest.alignment.moment(1581070496.25) == "2020-02-07 10:14:56.250 UTC"
    assert ingest.alignment.span(1581070496.25, 1581070498.25) == "2 s from 2020-02-07 10:14:56.250 UTC"
    assert ingest.alignment.moment(0.295) == "t = 0.295 s"
