"""Write the regression suite's stored scans (run once; the committed files are the suite's fixed input).

    .venv/bin/python tests/regression/generate_scans.py       # rewrites tests/regression/scans/

The scans come from the simulator, but the suite replays the committed files, so a later change of the
simulator does not change them. After a deliberate change of a feature's numbers, regenerate only the
expected values::

    .venv/bin/texplorer replay tests/regression/scans --write-expected tests/regression/expected_features.csv
"""

from __future__ import annotations

from pathlib import Path

from scanner.simulation import synthetic_scan
from scanner.storage.matfile import save_scan

MATERIALS = ("granite-polished", "oak-planed", "polyurethane-foam", "mild-steel-brushed")
"""Stone, wood, a soft foldable foam and a conductive, magnetic metal: every sensor sees something."""
IMAGE_SIZE = (320, 320)
"""Photos just above the 264 px every image feature needs (100 px crop per border plus Tamura's windows)."""
SEED = 2026


def main() -> None:
    folder = Path(__file__).with_name("scans")
    folder.mkdir(exist_ok=True)
    for old in folder.iterdir():
        old.unlink()
    for offset, slug in enumerate(MATERIALS):
        scan = synthetic_scan(slug, seed=SEED + offset, image_size=IMAGE_SIZE, session_id="regression",
                              operator="sim")
        for path in save_scan(scan, folder / f"{scan.scan_id}.mat"):
            print(path)


if __name__ == "__main__":
    main()
