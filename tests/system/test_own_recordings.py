"""A lab's own recordings through the project's pipeline from the command line (ingest -> features ->
evaluate -> report), on data shaped like public sets and made here: a folder of per-class WAV files, a
folder of per-class texture photos cut into patches, and a two-stream CSV set with gaps and its own
train/test split.

Each set's classes are separable by construction, so the accuracy must be far above chance; with the
labels reassigned so that they no longer follow the signal (but still follow the groups), the accuracy
must be at chance, which only holds if no group leaks across folds: the same run without grouping, which
lets a recording's twin into training, is far above chance (so the check can fail). The numbers printed
by the CLI equal those of the Python API.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.io import wavfile

from features import FeatureSpace
from features.recordings import Windowing, feature_space
from scanner.cli import main
from scanner.storage.ingest import load_recordings, set_folder
from taxonomy.learning.evaluation import evaluate, evaluate_grid, running_vote
from taxonomy.reports.report import cell_text


def cli(capsys, *argv: str) -> str:
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return captured.out


def table(out: str) -> dict[tuple[str, str, str, str], list[str]]:
    """Cells of the printed evaluation table by (set size, classifier, feature set, level)."""
    cells = {}
    lines = out.splitlines()
    for i, line in enumerate(lines):
        if "protocol," in line and (line.startswith("X") or line.startswith("all,")):
            size, levels = line.split(",")[0], lines[i + 1].split()[3:]
            for row in lines[i + 2:]:
                tokens = row.split()
                if len(tokens) != 2 + 5 * len(levels):
                    break
                for k, level in enumerate(levels):
                    cells[size, tokens[0], tokens[1], level] = tokens[2 + 5 * k:7 + 5 * k]
    return cells


def accuracies(cells: dict, level: str, feature_set: str = "all") -> list[float]:
    """Accuracies at ``level`` with ``feature_set`` (a single family is its own "all")."""
    sets = {key[2] for key in cells}
    chosen = feature_set if feature_set in sets else next(iter(sets))
    return [float(c[0]) / 100 for (_, _, fs, lvl), c in cells.items() if lvl == level and fs == chosen]


def chance_bound(classes: int, groups: int) -> float:
    """Chance plus three binomial standard deviations over the independent groups: the accuracy of labels
    that carry no information stays below it (a leak across folds gives far more)."""
    p = 1 / classes
    return p + 3 * math.sqrt(p * (1 - p) / groups)


def same_as_the_api(out: str, db: Path, name: str, levels: list[str], sizes: list[int | None]) -> None:
    """The written feature table and the printed cells equal what the Python API computes."""
    space, _ = feature_space(load_recordings(set_folder(db, name)), Windowing(), border=0, group_by="auto")
    written = FeatureSpace.from_csv(set_folder(db, name) / "features.csv")
    assert written.columns == space.columns and written.scan_ids == space.scan_ids
    assert np.array_equal(written.X, space.X, equal_nan=True)
    assert (written.label_text, written.groups, written.levels, written.split) == \
        (space.label_text, space.groups, space.levels, space.split)
    cells = table(out)
    reports = evaluate_grid(space, ["lda", "nb"], levels, sizes, workers=1)
    for report in reports:
        size = "all" if report.n_features is None else f"X{report.n_features}"
        assert cells[size, report.classifier, report.feature_set, report.level] == cell_text(report).split()


# -- a folder of per-class WAV files -----------------------------------------------------------------

SOUND_FS = 8000
SOUND_CLASSES = {"cardboard": 400.0, "wood": 1100.0, "metal": 2400.0}
"""Centre of each class's band of friction noise (Hz); each object adds a tone of its own."""


def write_sounds(root: Path, labels: dict[tuple[str, int], str]) -> None:
    """Six objects per class, two 0.5 s slides each: band noise of the class plus the object's own tone."""
    rng = np.random.default_rng(7)
    n = SOUND_FS // 2
    t = np.arange(n) / SOUND_FS
    for c, (material, centre) in enumerate(SOUND_CLASSES.items()):
        for obj in range(6):
            tone = 150.0 + 600.0 * c + 90.0 * obj
            for trial in range(2):
                spectrum = np.fft.rfft(rng.standard_normal(n))
                f = np.fft.rfftfreq(n, 1 / SOUND_FS)
                noise = np.fft.irfft(spectrum * np.exp(-0.5 * ((f - centre) / 150.0) ** 2), n)
                x = noise / np.abs(noise).max() * 0.3 + 0.3 * np.sin(2 * np.pi * tone * t)
                path = root / labels[material, obj] / f"{material[:4]}{obj}_{trial + 1}.wav"
                path.parent.mkdir(parents=True, exist_ok=True)
                wavfile.write(path, SOUND_FS, (x * 20000).astype(np.int16))
    table = ["recording,label,hardness"] + [
        f"{material[:4]}{obj}_{trial + 1},{labels[material, obj]},{'soft' if material == 'cardboard' else 'hard'}"
        for material in SOUND_CLASSES for obj in range(6) for trial in range(2)]
    (root / "labels.csv").write_text("\n".join(table) + "\n")


SOUND_MAPPING = """
name = "sounds"
label_level = "material"
[labels]
from = "csv"
csv = "labels.csv"
levels = ["hardness"]
[groups]
pattern = '^(?P<object>[a-z]+\\d)_(?P<trial>\\d)$'
[[files]]
glob = "**/*.wav"
"""


def test_a_folder_of_wav_files(tmp_path, capsys):
    root, db = tmp_path / "sounds", tmp_path / "db"
    write_sounds(root, {(m, o): m for m in SOUND_CLASSES for o in range(6)})
    (tmp_path / "sounds.toml").write_text(SOUND_MAPPING)
    out = cli(capsys, "ingest", root, "--mapping", tmp_path / "sounds.toml", "--db", db)
    assert out.splitlines()[-1].startswith("36 recording(s) from 36 file(s)")
    out = cli(capsys, "features", "set:sounds", "--db", db)
    assert "set:sounds: 36 recordings -> 36 rows (whole recordings), 18 groups; levels material (3 classes), " \
           "hardness (2 classes)" in out and "features: audio.audio (35)" in out
    out = cli(capsys, "evaluate", "set:sounds", "--db", db, "--report", tmp_path / "report", "--workers", 1)
    cells = table(out)
    assert {key[0] for key in cells} == {"X3", "X10", "all"}
    assert {key[1] for key in cells} == {"svm", "lda", "knn", "mlp", "rf", "nb", "ridge", "brf"}
    assert np.mean(accuracies(cells, "material")) > 0.9  # chance: 1/3
    assert all(cell[-1] == "-" for cell in cells.values())  # r_C needs taxonomy codes
    assert "5 grouped folds" in out
    page = (tmp_path / "report" / "index.html").read_text()
    assert "36 recordings, 18 groups, 35 features; classes: 2 hardness, 3 material." in page
    assert page.count("data:image/png;base64,") >= 6
    same_as_the_api(out, db, "sounds", ["material", "hardness"], [3, 10, None])

    # Labels that follow the objects but not the sound: each class's objects spread over three labels.
    shuffled = tmp_path / "shuffled"
    write_sounds(shuffled, {(m, o): f"label{o % 3}" for m in SOUND_CLASSES for o in range(6)})
    (tmp_path / "shuffled.toml").write_text(SOUND_MAPPING.replace('"sounds"', '"shuffled"'))
    cli(capsys, "ingest", shuffled, "--mapping", tmp_path / "shuffled.toml", "--db", db)
    quick = ["--classifier", "lda", "knn", "rf", "--n", "all", "--level", "material", "--workers", 1]
    grouped = table(cli(capsys, "evaluate", "set:shuffled", "--db", db, *quick))
    assert np.mean(accuracies(grouped, "material")) < chance_bound(3, 18)
    leaky = table(cli(capsys, "evaluate", "set:shuffled", "--db", db, *quick, "--group-by", "none"))
    assert np.mean(accuracies(leaky, "material")) > 0.8  # the twin slide of each object is in training


# -- a folder of per-class texture photos cut into patches -------------------------------------------

def texture(kind: int, photo: int, rng: np.random.Generator) -> np.ndarray:
    """128 x 128 px: stripes whose period and direction follow the class, in a hue and brightness of the
    photo's own (so its patches resemble each other more than other photos' of the class)."""
    y, x = np.mgrid[0:128, 0:128]
    period = (6.0, 14.0, 30.0)[kind]
    angle = (0.0, 0.8, 1.6)[kind]
    stripes = 0.5 + 0.5 * np.sin(2 * np.pi * (x * np.cos(angle) + y * np.sin(angle)) / period)
    value = 60 + 20 * photo + 100 * stripes + rng.normal(0, 8, stripes.shape)
    hsv = np.stack([np.full(value.shape, 10 * (6 * kind + photo)), np.full(value.shape, 200),
                    np.clip(value, 0, 255)], axis=2).astype(np.uint8)
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)


def write_photos(root: Path, labels: dict[tuple[int, int], str]) -> None:
    rng = np.random.default_rng(3)
    for kind in range(3):
        for photo in range(6):
            path = root / labels[kind, photo] / f"t{kind}p{photo}.png"
            path.parent.mkdir(parents=True, exist_ok=True)
            assert cv2.imwrite(str(path), texture(kind, photo, rng)[..., ::-1])


def test_a_folder_of_texture_photos_cut_into_patches(tmp_path, capsys):
    root, db = tmp_path / "photos", tmp_path / "db"
    write_photos(root, {(k, p): ("fine", "medium", "coarse")[k] for k in range(3) for p in range(6)})
    out = cli(capsys, "ingest", root, "--grid", "2x2", "--db", db)  # no mapping: photos labelled by folder
    assert out.splitlines()[-1].startswith(f"72 recording(s) from 18 file(s) -> {db}/recordings/photos")
    out = cli(capsys, "features", "set:photos", "--db", db)
    assert "72 recordings -> 72 rows (whole recordings), 18 groups; levels label (3 classes)" in out
    assert "features: image.photo (31)" in out
    space = FeatureSpace.from_csv(set_folder(db, "photos") / "features.csv")
    assert not np.isnan(space.X).any()  # 64 x 64 px patches: Tamura coarseness too
    out = cli(capsys, "evaluate", "set:photos", "--db", db, "--report", tmp_path / "report", "--workers", 1)
    cells = table(out)
    assert np.mean(accuracies(cells, "label")) > 0.9
    assert "Folds: grouped by " in (tmp_path / "report" / "index.html").read_text()  # the photo of each patch
    same_as_the_api(out, db, "photos", ["label"], [3, 10, None])

    shuffled = tmp_path / "shuffled"
    write_photos(shuffled, {(k, p): f"label{p % 3}" for k in range(3) for p in range(6)})
    cli(capsys, "ingest", shuffled, "--grid", "2x2", "--db", db)
    quick = ["--classifier", "lda", "knn", "rf", "--n", "all", "--workers", 1]
    grouped = table(cli(capsys, "evaluate", "set:shuffled", "--db", db, *quick))
    assert np.mean(accuracies(grouped, "label")) < chance_bound(3, 18)
    leaky = table(cli(capsys, "evaluate", "set:shuffled", "--db", db, *quick, "--group-by", "none"))
    # A photo's other patches are in training: the labels are learnt from its hue and brightness.
    assert np.mean(accuracies(leaky, "label")) > chance_bound(3, 18) and max(accuracies(leaky, "label")) > 0.85


# -- a two-stream CSV set with gaps and its own train/test split -------------------------------------


def test_evaluate_uses_the_sets_table_written_with_the_same_options(tmp_path, capsys, monkeypatch):
    from scanner.cli import analysis

    root, db = tmp_path / "sounds", tmp_path / "db"
    write_sounds(root, {(m, o): m for m in SOUND_CLASSES for o in range(6)})
    (tmp_path / "sounds.toml").write_text(SOUND_MAPPING)
    cli(capsys, "ingest", root, "--mapping", tmp_path / "sounds.toml", "--db", db)
    quick = ("--classifier", "nb", "--n", "3", "--level", "material", "--workers", 1)
    out = cli(capsys, "evaluate", "set:sounds", "--db", db, *quick)
    assert "set:sounds: extracting the features (no table written by 'texplorer features set:sounds')" in out
    cli(capsys, "features", "set:sounds", "--db", db, "--window", "0.25", "--combine", "rows")
    table_path = set_folder(db, "sounds") / "features.csv"
    written = FeatureSpace.from_csv(table_path)
    assert len(written) == 72  # two windows of each 0.5 s recording

    extracted = []
    original = analysis.set_space
    monkeypatch.setattr(analysis, "set_space", lambda args: extracted.append(args) or original(args))
    same = cli(capsys, "evaluate", "set:sounds", "--db", db, "--window", "0.25", "--combine", "rows", *quick)
    assert f"set:sounds: using {table_path} (written by 'texplorer features set:sounds' with the same options)" \
        in same
    assert extracted == []
    other = cli(capsys, "evaluate", "set:sounds", "--db", db, "--window", "0.1", *quick)
    assert f"set:sounds: extracting the features ({table_path} was written with other --window, --combine)" \
        in other
    assert len(extracted) == 1
    # The same cells as an evaluation that extracts again: the table holds what extraction gives.
    monkeypatch.setattr(analysis, "stored_set_table", lambda args, folder: (None, "extracting"))
    again = cli(capsys, "evaluate", "set:sounds", "--db", db, "--window", "0.25", "--combine", "rows", *quick)
    assert table(again) == table(same)


def test_windows_voted_with_those_before_them_and_the_history_refused_where_it_cannot_hold(tmp_path, capsys):
    root, db = tmp_path / "sounds", tmp_path / "db"
    write_sounds(root, {(m, o): m for m in SOUND_CLASSES for o in range(6)})
    (tmp_path / "sounds.toml").write_text(SOUND_MAPPING)
    cli(capsys, "ingest", root, "--mapping", tmp_path / "sounds.toml", "--db", db)
    windows = ("--window", "0.25", "--combine", "rows", "--classifier", "knn", "--n", "3", "--level", "material",
               "--workers", 1)
    alone = cli(capsys, "evaluate", "set:sounds", "--db", db, *windows)
    voted = cli(capsys, "evaluate", "set:sounds", "--db", db, *windows, "--history", "1")
    assert "each window voted with the 1 window before it in its recording" in voted
    assert table(voted).keys() == table(alone).keys()  # the same cells, every window still a row
    assert table(voted) != table(alone)  # here the window before mends a window
    assert table(cli(capsys, "evaluate", "set:sounds", "--db", db, *windows, "--history", "0")) == table(alone)
    # The figure the command prints is the running vote of the same evaluation through the API.
    space, _ = feature_space(load_recordings(set_folder(db, "sounds")), Windowing(0.25, "rows"), workers=1)
    result = evaluate(space, "knn", "material", 3, group_by="the set's groups")
    (cell,) = table(voted).values()
    assert cell[0] == f"{100 * running_vote(result, space.scan_ids, 1).accuracy_pooled:.1f}"
    # --leakage's second evaluation splits a recording's windows over the folds: nothing to vote over.
    code = main([str(a) for a in ("evaluate", "set:sounds", "--db", db, *windows, "--history", "1", "--leakage")])
    assert code == 1 and "--history answers with several windows of a recording" in capsys.readouterr().err
    for bad, message in ((("--history", "-1"), "the history is a whole number of windows >= 0, got '-1'"),
                         (("--history", "1", "--vote"), "not allowed with argument")):
        with pytest.raises(SystemExit) as refused:
            main([str(a) for a in ("evaluate", "set:sounds", "--db", db, *windows, *bad)])
        assert refused.value.code == 2 and message in capsys.readouterr().err


def test_a_set_table_is_reused_only_while_the_recordings_hold_what_it_was_computed_from(tmp_path, capsys):
    import os
    import shutil

    root, db = tmp_path / "sounds", tmp_path / "db"
    write_sounds(root, {(m, o): m for m in SOUND_CLASSES for o in range(6)})
    (tmp_path / "sounds.toml").write_text(SOUND_MAPPING)
    cli(capsys, "ingest", root, "--mapping", tmp_path / "sounds.toml", "--db", db)
    cli(capsys, "features", "set:sounds", "--db", db)
    folder = set_folder(db, "sounds")
    quick = ("--classifier", "nb", "--n", "3", "--level", "material", "--workers", 1)
    using = f"set:sounds: using {folder / 'features.csv'}"
    assert using in cli(capsys, "evaluate", "set:sounds", "--db", db, *quick)
    # The whole set copied as a backup restore does (cp -p: new inodes, times put back): contents equal.
    shutil.copytree(folder, tmp_path / "backup", copy_function=shutil.copy2)
    shutil.rmtree(folder)
    shutil.copytree(tmp_path / "backup", folder, copy_function=shutil.copy2)
    assert using in cli(capsys, "evaluate", "set:sounds", "--db", db, *quick)
    # One recording edited in place, same size, its modification time put back (rsync -t, touch -r): here
    # a letter of the MAT header's descriptive text, so the file stays readable and only its bytes tell.
    victim = sorted(folder.glob("*.mat"))[0]
    stat = victim.stat()
    data = bytearray(victim.read_bytes())
    assert data[:6] == b"MATLAB"
    data[1] = ord("a")
    victim.write_bytes(bytes(data))
    os.utime(victim, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert victim.stat().st_size == stat.st_size and victim.stat().st_mtime_ns == stat.st_mtime_ns
    out = cli(capsys, "evaluate", "set:sounds", "--db", db, *quick)
    assert f"set:sounds: extracting the features ({folder / 'features.csv'} was written with other the " \
           "recordings)" in out


def test_a_set_with_the_modern_families(tmp_path, capsys):
    """features and evaluate of set:NAME with --feature-set: the modern columns are extracted only when
    asked for, and each set, alone and fused, is evaluated on the same folds and shown side by side."""
    pytest.importorskip("sktime", reason="the modern families need texplorer[modern]")
    pytest.importorskip("pycatch22", reason="the modern families need texplorer[modern]")
    root, db = tmp_path / "sounds", tmp_path / "db"
    write_sounds(root, {(m, o): m for m in SOUND_CLASSES for o in range(6)})
    (tmp_path / "sounds.toml").write_text(SOUND_MAPPING)
    cli(capsys, "ingest", root, "--mapping", tmp_path / "sounds.toml", "--db", db)
    out = cli(capsys, "features", "set:sounds", "--db", db, "--feature-set", "catch22", "--workers", 1)
    assert "features: audio.audio (35), catch22.audio (22) in" in out
    out = cli(capsys, "evaluate", "set:sounds", "--db", db, "--workers", 1, "--classifier", "lda", "ridge",
              "--level", "material", "--n", "3", "--feature-set", "paper", "catch22", "minirocket",
              "paper+minirocket", "--report", tmp_path / "report")
    cells = table(out)
    assert {key[2] for key in cells} == {"paper", "catch22", "minirocket", "paper+minirocket"}
    # chance 1/3; guessing 36 rows has a standard deviation of sqrt(2 / 9 / 36) = 0.079: 0.7 is 4.6 of them
    assert np.mean(accuracies(cells, "material", "minirocket")) > 0.7
    page = (tmp_path / "report" / "index.html").read_text()
    assert "Feature sets side by side" in page and "paper+minirocket" in page
    with pytest.raises(SystemExit) as refused:
        main(["evaluate", "set:sounds", "--db", str(db), "--feature-set", "rocket"])
    assert refused.value.code == 2 and "unknown feature set 'rocket'" in capsys.readouterr().err


STREAM_MAPPING = """
name = "finger"
label_level = "surface"
[groups]
pattern = '^(?P<object>[a-z]+\\d)_t(?P<trial>\\d)$'
[[files]]
glob = "**/*_tactile.csv"
suffix = "_tactile.csv"
time_column = "t"
  [[files.channels]]
  name = "pac"
  role = "vibration"
  columns = "pac_01:pac_22"
  spread = true
  [[files.channels]]
  name = "pdc"
  role = "pressure_dc"
  columns = "pdc"
[[files]]
glob = "**/*_force.csv"
suffix = "_force.csv"
time_column = "t_ms"
time_unit = "ms"
rate = 200.0
  [[files.channels]]
  name = "force"
  role = "force_xyz"
  columns = ["fx", "fy", "fz"]
"""


def write_streams(root: Path, labels: dict[tuple[str, int], str]) -> None:
    """A tactile sensor with 22 vibration samples per 100 Hz row, and a 200 Hz force sensor starting 50 ms
    earlier whose link drops 40 ms of samples; four objects per surface, two slides each (the second one
    in the test part). Surfaces differ in vibration frequency and friction."""
    rng = np.random.default_rng(11)
    surfaces = {"silk": (90.0, 0.2), "denim": (240.0, 0.5), "sandpaper": (520.0, 0.9)}
    for surface, (frequency, mu) in surfaces.items():
        for obj in range(4):
            for trial in range(2):
                part = ("train", "test")[trial]
                stem = root / part / labels[surface, obj] / f"{surface[:4]}{obj}_t{trial + 1}"
                stem.parent.mkdir(parents=True, exist_ok=True)
                rows = 150  # 1.5 s
                t = 0.2 + np.arange(rows) / 100
                ts = 0.2 + np.arange(rows * 22) / 2200
                pac = 2000 + 300 * np.sin(2 * np.pi * (frequency + 8 * obj) * ts) + rng.normal(0, 30, ts.size)
                pdc = 500 + 20 * np.sin(np.pi * (t - 0.2) / 1.5)
                lines = ["t,pdc," + ",".join(f"pac_{k + 1:02d}" for k in range(22))]
                lines += [f"{t[r].item()!r},{pdc[r].item()!r},"
                          + ",".join(repr(v) for v in pac[22 * r:22 * r + 22].tolist())
                          for r in range(rows)]
                Path(f"{stem}_tactile.csv").write_text("\n".join(lines) + "\n")
                tf = np.round(0.15 + np.arange(320) / 200, 6)
                kept = (tf < 0.9) | (tf > 0.94)
                fz = np.clip(3 * (tf - 0.15) / 0.2, 0, 3) + rng.normal(0, 0.02, tf.size)
                fx = (mu + 0.02 * obj) * fz + rng.normal(0, 0.02, tf.size)
                force = ["t_ms,fx,fy,fz"] + [f"{1000 * a!r},{b!r},0.0,{c!r}"
                                             for a, b, c in zip(tf[kept].tolist(), fx[kept].tolist(),
                                                                fz[kept].tolist(), strict=True)]
                Path(f"{stem}_force.csv").write_text("\n".join(force) + "\n")


def test_a_two_stream_csv_set_with_gaps_and_its_own_split(tmp_path, capsys):
    root, db = tmp_path / "finger", tmp_path / "db"
    write_streams(root, {(s, o): s for s in ("silk", "denim", "sandpaper") for o in range(4)})
    (tmp_path / "finger.toml").write_text(STREAM_MAPPING)
    out = cli(capsys, "ingest", root, "--mapping", tmp_path / "finger.toml", "--db", db)
    lines = out.splitlines()
    # 24 files with a gap each: one summary line, the worst case and the first names, not 24 lines.
    assert lines[0].startswith("note     gaps in the timestamps bridged in 24 file(s) (deni0_t2_force.csv, "
                               "deni1_t2_force.csv, deni2_t2_force.csv and 21 more); worst: ")
    assert "9 sample(s) missing; the longest 0.05 s at t = 0.895 s (bridged linearly)" in lines[0]
    assert lines[-1].endswith("roles force_xyz, pressure_dc, vibration; split 12 train / 12 test; "
                              "0 problem line(s)")
    recording = load_recordings(set_folder(db, "finger"))[0]
    assert recording.channels["pac"].fs == pytest.approx(2200) and recording.channels["pac"].n == 3300
    assert recording.channels["force"].n == 300  # cut to the tactile stream's 0.2-1.7 s
    out = cli(capsys, "features", "set:finger", "--db", db)
    assert "features: audio.vibration (35), tactum.vibration (2), other.vibration (3), tactum.force_xyz (2)" in out
    out = cli(capsys, "evaluate", "set:finger", "--db", db, "--report", tmp_path / "report", "--workers", 1)
    assert "(nested protocol, the set's train/test split)" in out
    cells = table(out)
    assert np.mean(accuracies(cells, "surface")) > 0.9 and np.mean(accuracies(cells, "surface", "tactum")) > 0.9
    page = (tmp_path / "report" / "index.html").read_text()
    assert "24 recordings (the set&#x27;s split: 12 train, 12 test)" in page
    same_as_the_api(out, db, "finger", ["surface"], [3, 10, None])

    shuffled = tmp_path / "shuffled"
    write_streams(shuffled, {(s, o): f"label{o % 2}" for s in ("silk", "denim", "sandpaper") for o in range(4)})
    (tmp_path / "shuffled.toml").write_text(STREAM_MAPPING.replace('"finger"', '"shuffled"'))
    cli(capsys, "ingest", shuffled, "--mapping", tmp_path / "shuffled.toml", "--db", db)
    quick = ["--classifier", "lda", "knn", "rf", "--n", "all", "--workers", 1]
    held_out = table(cli(capsys, "evaluate", "set:shuffled", "--db", db, *quick))
    assert np.mean(accuracies(held_out, "surface")) < chance_bound(2, 12)
