"""Load a texplorer export bundle with numpy and scipy only; texplorer itself is not needed.

From a shell, in or beside the bundle folder::

    python load_texplorer.py BUNDLE        # check every SHA-256, then summarise scans and features

From Python::

    from load_texplorer import load_scan, load_features, verify
    scan = load_scan("scans/C6S1M1P2X1/granite-polished-01/granite-polished-01-001.mat")
    scan["v_ts"]                  # (n, 3) tool-slide acceleration in g
    scan["meta"]["fs"]["v_ts"]    # its sample rate, 3000.0 Hz
    scan["photos"]["I_disp"]      # path of the photo (PNG; read it with matplotlib.pyplot.imread)
    X, columns, rows = load_features("BUNDLE")   # X: scans x features, NaN where undefined

Units and channels are in README.md.
"""

import csv
import hashlib
import json
import sys
from pathlib import Path

import numpy as np
import scipy.io

PHOTOS = ("I_disp", "I_macro", "I_illu")


def load_scan(path):
    """All variables of one scan ``.mat`` as a dict; 1-D channels as 1-D arrays, ``meta`` as nested dicts.

    ``photos`` maps each photo variable to the full path of its PNG file beside the ``.mat``.
    """
    path = Path(path)
    variables = scipy.io.loadmat(path, simplify_cells=True)
    scan = {name: value for name, value in variables.items() if not name.startswith("__")}
    scan["photos"] = {name: path.with_name(scan[name]) for name in PHOTOS if name in scan}
    return scan


def load_features(bundle):
    """The feature table of ``features.csv``: ``(X, columns, rows)``.

    ``X`` is a float array (scans x features) with NaN where a feature is undefined, ``columns`` the
    feature names and ``rows`` one dict per scan with ``scan_id``, ``sample_id``, ``label`` and the label
    parts ``C``, ``S``, ``M``, ``P``, ``X`` as integers.
    """
    with open(Path(bundle) / "features.csv", newline="", encoding="utf-8") as handle:
        reader = csv.reader(handle)
        header = next(reader)
        first = header.index("X") + 1
        rows, values = [], []
        for record in reader:
            row = {name: record[i] for i, name in enumerate(header[:first])}
            row.update({part: int(row[part]) for part in "CSMPX"})
            rows.append(row)
            values.append([float(v) for v in record[first:]])
    X = np.array(values, dtype=np.float64).reshape(len(values), len(header) - first)
    return X, header[first:], rows


def load_features_mat(bundle):
    """``features.mat`` as a dict: ``X``, ``columns``, ``labels`` (n x 5: C S M P X), ``label``, ``scan_id``,
    ``sample_id``."""
    data = scipy.io.loadmat(Path(bundle) / "features.mat", simplify_cells=True)
    return {name: value for name, value in data.items() if not name.startswith("__")}


def verify(bundle):
    """Problems found checking every file against ``manifest.json`` (an empty list means the bundle is whole)."""
    bundle = Path(bundle)
    manifest_bytes = (bundle / "manifest.json").read_bytes()
    expected_sum = f"{hashlib.sha256(manifest_bytes).hexdigest()}  manifest.json\n"
    problems = []
    if (bundle / "manifest.json.sha256").read_text(encoding="ascii") != expected_sum:
        problems.append("manifest.json: does not match manifest.json.sha256")
    for name, entry in json.loads(manifest_bytes)["files"].items():
        path = bundle / name
        if not path.is_file():
            problems.append(f"{name}: missing")
        elif hashlib.sha256(path.read_bytes()).hexdigest() != entry["sha256"]:
            problems.append(f"{name}: SHA-256 differs from the manifest")
    return problems


def main(argv):
    if len(argv) != 2:
        print(f"usage: python {Path(argv[0]).name} BUNDLE_FOLDER", file=sys.stderr)
        return 2
    bundle = Path(argv[1])
    manifest = json.loads((bundle / "manifest.json").read_text(encoding="utf-8"))
    problems = verify(bundle)
    for problem in problems:
        print(f"problem  {problem}")
    print(f"verified {len(manifest['files'])} files: {len(problems)} problem(s)")
    if problems:
        return 1
    counts = manifest["counts"]
    print(f"bundle of {counts['scans']} scans, {counts['materials']} materials, created {manifest['created']} "
          f"by texplorer {manifest['software_version']}")
    first = manifest["scans"][0]
    scan = load_scan(bundle / first["files"]["mat"])
    print(f"scan {first['scan_id']}: label {scan['meta']['label']}, v_ts {scan['v_ts'].shape} "
          f"at {scan['meta']['fs']['v_ts']:g} Hz, photos {', '.join(sorted(scan['photos']))}")
    X, columns, rows = load_features(bundle)
    print(f"features: {X.shape[0]} scans x {X.shape[1]} columns, {int(np.isnan(X).any(axis=0).sum())} with NaN")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
