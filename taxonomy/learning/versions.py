"""Model versions of a database: every trained model kept, one of them current (docs/evaluation.md#models).

A database's models live in ``<db>/models/``: each training writes a new file
``v<NNN>-<classifier>-<level>-X<n>.skops`` (never over an existing one) and a row in the index
``models/versions.json``, which also names the current version, the one ``texplorer serve``, ``classify``
and the terminal scan use when not told otherwise. A row records when the model was made, its protocol
(classifier, level, features), its classes, the training data's fingerprint (a SHA-256 over the scans' ids
and content hashes, and the feature code version that computed their features) and its headline figures
(cross-validated accuracy of the same settings when the trainer measured it, the rejection rule's
leave-classes-out AUROC inside training), so a lab can tell which data a model saw and go back to an
older one (:func:`use_version`).

The index is rewritten atomically under an exclusive lock (``models/.versions.lock``), so two trainings
that finish together both get a version. A model file written before versions existed
(``models/rf-fine-X10.skops``, made by ``texplorer demo``) is listed as version 0 and is current while the
index names no other.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import math
import os
import re
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from scanner.storage.files import atomic_write_bytes, read_json
from taxonomy.errors import TexplorerError
from taxonomy.learning.models import TrainedModel, save_model

MODELS = "models"
INDEX = "versions.json"
LOCK = ".versions.lock"
LEGACY = "rf-fine-X10.skops"
"""The file ``texplorer demo`` wrote before model versions: version 0 when present."""
MAX_INDEX_BYTES = 16 << 20
_VERSION = re.compile(r"v?(\d{1,6})")


class VersionError(TexplorerError, ValueError):
    """A model version that does not exist, or an index that cannot be read."""


@dataclass(frozen=True)
class ModelVersion:
    """One trained model of a database, as its index row records it."""

    version: int
    file: str
    created: str
    classifier: str
    level: str
    n_features: int
    classes: tuple[str, ...]
    rows: int
    fingerprint: str
    feature_code_version: str
    figures: Mapping[str, float] = field(default_factory=dict)
    note: str = ""

    def protocol(self) -> str:
        """``rf, fine level, 10 features``.

        Returns
        -------
        str
            The classifier, the level and the number of selected features.

        Examples
        --------
        >>> from taxonomy.learning.versions import ModelVersion
        >>> version = ModelVersion(3, "v003-rf-fine-X10.skops", "2024-05-02T09:30:00+00:00", "rf", "fine", 10,
        ...                        ("C1S1M1P4X1", "C6S1M1P2X1"), 120, "", "",
        ...                        {"cv_accuracy": 0.932, "inner_auroc": 0.91})
        >>> version.protocol()
        'rf, fine level, 10 features'
        """
        return f"{self.classifier}, {self.level} level, {self.n_features} features"

    def figures_text(self) -> str:
        """The headline figures in words (``CV accuracy 93.2 %, rejection AUROC 0.91``).

        Returns
        -------
        str
            The known figures (``cv_accuracy``, ``inner_auroc``) in the order recorded; ``-`` for none.

        Examples
        --------
        >>> from taxonomy.learning.versions import ModelVersion
        >>> version = ModelVersion(3, "v003-rf-fine-X10.skops", "2024-05-02T09:30:00+00:00", "rf", "fine", 10,
        ...                        ("C1S1M1P4X1", "C6S1M1P2X1"), 120, "", "",
        ...                        {"cv_accuracy": 0.932, "inner_auroc": 0.91})
        >>> version.figures_text()
        'CV accuracy 93.2 %, rejection AUROC 0.91'
        >>> ModelVersion(1, "v001-rf-fine-X10.skops", "", "rf", "fine", 10, (), 0, "", "").figures_text()
        '-'
        """
        words = {"cv_accuracy": ("CV accuracy", lambda v: f"{100 * v:.1f} %"),
                 "inner_auroc": ("rejection AUROC", lambda v: f"{v:.2f}")}
        return ", ".join(f"{words[k][0]} {words[k][1](v)}" for k, v in self.figures.items() if k in words) or "-"


def training_fingerprint(rows: Iterable[tuple[str, str]], feature_code_version: str) -> str:
    r"""SHA-256 over the training rows' ``(scan id, content hash)`` pairs in order and the feature code
    version: two models share it exactly when they were trained on the same stored scans' same features.

    Parameters
    ----------
    rows : iterable of (str, str)
        The ``(scan id, content hash)`` of each training row; they are sorted before hashing, so their order
        does not matter.
    feature_code_version : str
        The version of the feature code that computed the rows' features.

    Returns
    -------
    str
        64 hexadecimal digits.

    Examples
    --------
    Without rows the digest is that of the feature code version and a line break:

    >>> import hashlib
    >>> from taxonomy.learning.versions import training_fingerprint
    >>> training_fingerprint([], "abc") == hashlib.sha256(b"abc\n").hexdigest()
    True
    >>> rows = [("scan-1", "9f2c"), ("scan-2", "41aa")]
    >>> training_fingerprint(rows, "abc") == training_fingerprint(rows[::-1], "abc")
    True
    >>> training_fingerprint(rows, "abc") == training_fingerprint(rows, "abd")
    False
    """
    digest = hashlib.sha256(f"{feature_code_version}\n".encode())
    for scan_id, content in sorted(rows):
        digest.update(f"{scan_id}\0{content}\n".encode())
    return digest.hexdigest()


def models_folder(db_root: str | os.PathLike[str]) -> Path:
    """The folder of a database's model files.

    Parameters
    ----------
    db_root : str or os.PathLike
        The database's folder.

    Returns
    -------
    pathlib.Path
        ``<db_root>/models`` (it need not exist).

    Examples
    --------
    >>> from taxonomy.learning.versions import models_folder
    >>> models_folder("/data/lab").as_posix()
    '/data/lab/models'
    """
    return Path(db_root) / MODELS


@contextlib.contextmanager
def _locked(folder: Path) -> Iterator[None]:
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / LOCK, "a+b") as handle:
        fcntl.flock(handle.fileno(), fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle.fileno(), fcntl.LOCK_UN)


def _read_index(folder: Path) -> dict[str, Any]:
    path = folder / INDEX
    index = read_json(path, MAX_INDEX_BYTES, VersionError, {"current": None, "versions": []},
                      "; the model files beside it are intact")
    if not isinstance(index, dict) or not isinstance(index.get("versions"), list):
        raise VersionError(f"{path}: not a model index (an object with a 'versions' list)")
    return index


_TEXT_FIELDS = ("file", "created", "classifier", "level", "fingerprint", "feature_code_version", "note")


def _row(path: Path, entry: Any) -> ModelVersion:
    try:
        row = dict(entry)
        row["classes"] = tuple(str(c) for c in row["classes"])
        row["figures"] = {str(k): float(v) for k, v in dict(row.get("figures") or {}).items()}
        version = ModelVersion(**row)
    except (TypeError, ValueError, KeyError) as exc:
        raise VersionError(f"{path}: a version entry cannot be read ({str(exc)[:200]})") from None
    numbers = (version.version, version.n_features, version.rows)
    if not all(isinstance(n, int) and not isinstance(n, bool) and n >= 0 for n in numbers) \
            or not all(isinstance(getattr(version, f), str) for f in _TEXT_FIELDS) \
            or not all(math.isfinite(v) for v in version.figures.values()):
        raise VersionError(f"{path}: version entry {str(entry)[:200]} has a field of the wrong type")
    if "/" in version.file or "\\" in version.file or version.file.startswith("."):
        raise VersionError(f"{path}: version entry {str(entry)[:200]} names no model file of {path.parent}")
    return version


def _legacy(folder: Path) -> ModelVersion | None:
    path = folder / LEGACY
    if not path.is_file():
        return None
    created = datetime.fromtimestamp(path.stat().st_mtime, UTC).replace(microsecond=0).isoformat()
    return ModelVersion(0, LEGACY, created, "rf", "fine", 10, (), 0, "", "", {},
                        "written by 'texplorer demo' before model versions")


def versions(db_root: str | os.PathLike[str]) -> list[ModelVersion]:
    """Every model version of the database, oldest first (version 0: a model from before versions).

    Parameters
    ----------
    db_root : str or os.PathLike
        The database's folder.

    Returns
    -------
    list of ModelVersion
        By version number; empty for a database without models.

    Raises
    ------
    VersionError
        The index cannot be read, or one of its entries is malformed.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from taxonomy.learning.versions import versions
    >>> with tempfile.TemporaryDirectory() as db:
    ...     before = versions(db)
    ...     (Path(db) / "models").mkdir()
    ...     (Path(db) / "models" / "rf-fine-X10.skops").touch()  # written by 'texplorer demo'
    ...     after = versions(db)
    >>> before, [(v.version, v.file, v.protocol()) for v in after]
    ([], [(0, 'rf-fine-X10.skops', 'rf, fine level, 10 features')])
    """
    folder = models_folder(db_root)
    rows = [_row(folder / INDEX, entry) for entry in _read_index(folder)["versions"]]
    legacy = _legacy(folder)
    return ([legacy] if legacy else []) + sorted(rows, key=lambda v: v.version)


def current_version(db_root: str | os.PathLike[str]) -> ModelVersion | None:
    """The version the web application and ``classify`` use by default: the index's current one, else the
    newest, else a model from before versions, else None.

    Parameters
    ----------
    db_root : str or os.PathLike
        The database's folder.

    Returns
    -------
    ModelVersion or None
        None for a database without models.

    Raises
    ------
    VersionError
        The index cannot be read, or one of its entries is malformed.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from taxonomy.learning.versions import current_version
    >>> with tempfile.TemporaryDirectory() as db:
    ...     before = current_version(db)
    ...     (Path(db) / "models").mkdir()
    ...     (Path(db) / "models" / "rf-fine-X10.skops").touch()
    ...     after = current_version(db)
    >>> before, after.version, after.note
    (None, 0, "written by 'texplorer demo' before model versions")
    """
    folder = models_folder(db_root)
    index = _read_index(folder)
    found = versions(db_root)
    chosen = [v for v in found if v.version == index.get("current")]
    return chosen[0] if chosen else (found[-1] if found else None)


def version_file(db_root: str | os.PathLike[str], version: ModelVersion) -> Path:
    """The model file of ``version`` in the database at ``db_root``.

    Parameters
    ----------
    db_root : str or os.PathLike
        The database's folder.
    version : ModelVersion
        A version of that database.

    Returns
    -------
    pathlib.Path
        The file in :func:`models_folder` (whether it exists or not).

    Examples
    --------
    >>> from taxonomy.learning.versions import ModelVersion, version_file
    >>> version = ModelVersion(3, "v003-rf-fine-X10.skops", "", "rf", "fine", 10, (), 0, "", "")
    >>> version_file("/data/lab", version).as_posix()
    '/data/lab/models/v003-rf-fine-X10.skops'
    """
    return models_folder(db_root) / version.file


def add_version(db_root: str | os.PathLike[str], model: TrainedModel, *, fingerprint: str,
                feature_code_version: str, figures: Mapping[str, float] | None = None, note: str = "",
                make_current: bool = True) -> ModelVersion:
    """Save ``model`` as the database's next version (a new file; nothing is overwritten) and record it in
    the index, as the current version unless ``make_current`` is false.

    Parameters
    ----------
    db_root : str or os.PathLike
        The database's folder.
    model : TrainedModel
        The model to keep.
    fingerprint : str
        The training data's :func:`training_fingerprint`.
    feature_code_version : str
        The version of the feature code that computed the training features.
    figures : mapping of str to float, optional
        Headline figures (``cv_accuracy``); the rejection rule's ``inner_auroc`` is added where the model has
        one, and values that are not finite are left out.
    note : str
        A remark kept with the version.
    make_current : bool
        Whether the new version becomes the current one (the first version always does).

    Returns
    -------
    ModelVersion
        The new version, as the index records it.

    Raises
    ------
    VersionError
        A file of the new version's name exists that the index does not name, or the index cannot be read.
    ModelError
        A model that could not be read back (:func:`taxonomy.learning.models.save_model`).

    Examples
    --------
    >>> import tempfile
    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> from taxonomy.learning.models import train_model
    >>> density = np.array([2.6, 2.7, 2.8, 2.65, 0.6, 0.7, 0.8, 0.65])  # granite, then oak (g/cm^3)
    >>> space = FeatureSpace(density[:, None], ("other.density",), tuple(f"s{i}" for i in range(8)),
    ...                      ("C6S1M1P2X1",) * 4 + ("C1S1M1P4X1",) * 4, tuple(f"g{i}" for i in range(8)))
    >>> model = train_model(space, "fine", 1, "nb")
    >>> from taxonomy.learning.versions import add_version, current_version
    >>> with tempfile.TemporaryDirectory() as db:
    ...     first = add_version(db, model, fingerprint="", feature_code_version="", figures={"cv_accuracy": 1.0})
    ...     second = add_version(db, model, fingerprint="", feature_code_version="", make_current=False)
    ...     current = current_version(db).version
    >>> first.file, first.figures_text(), second.file, current
    ('v001-nb-fine-X1.skops', 'CV accuracy 100.0 %', 'v002-nb-fine-X1.skops', 1)
    """
    folder = models_folder(db_root)
    with _locked(folder):
        index = _read_index(folder)
        taken = [_row(folder / INDEX, entry).version for entry in index["versions"]]
        number = max([0, *taken]) + 1
        name = f"v{number:03d}-{model.classifier}-{model.level}-X{model.n_features}.skops"
        if (folder / name).exists():  # a file nobody indexed (a copy, a crash before the index): keep it
            raise VersionError(f"{folder / name} exists but is not in {folder / INDEX}; move it away first")
        figures = dict(figures or {})
        if model.rejection is not None:
            figures.setdefault("inner_auroc", float(model.rejection.inner_auroc))
        figures = {key: float(value) for key, value in figures.items() if math.isfinite(value)}
        row = ModelVersion(number, name, datetime.now(UTC).replace(microsecond=0).isoformat(), model.classifier,
                           model.level, int(model.n_features), tuple(model.classes), int(model.n_rows),
                           fingerprint, feature_code_version, figures, note)
        index["versions"].append(_plain(row))
        if make_current or index.get("current") is None:
            index["current"] = number
        text = _index_bytes(index)  # before the model is written: an index that cannot be written leaves nothing
        save_model(model, folder / name)
        try:
            atomic_write_bytes(folder / INDEX, text)
        except BaseException:
            (folder / name).unlink(missing_ok=True)  # no model file the index does not name
            raise
    return row


def use_version(db_root: str | os.PathLike[str], spec: str | int) -> ModelVersion:
    """Make an existing version current again; returns it. A version that does not exist is refused before
    anything is written (the lock file included).

    Parameters
    ----------
    db_root : str or os.PathLike
        The database's folder.
    spec : str or int
        The version's number (``3``, ``"v3"``, ``"v003"``; :func:`find_version`).

    Returns
    -------
    ModelVersion
        The version now current.

    Raises
    ------
    VersionError
        No such version, or its file is gone.

    Examples
    --------
    >>> import tempfile
    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> from taxonomy.learning.models import train_model
    >>> density = np.array([2.6, 2.7, 2.8, 2.65, 0.6, 0.7, 0.8, 0.65])  # granite, then oak (g/cm^3)
    >>> space = FeatureSpace(density[:, None], ("other.density",), tuple(f"s{i}" for i in range(8)),
    ...                      ("C6S1M1P2X1",) * 4 + ("C1S1M1P4X1",) * 4, tuple(f"g{i}" for i in range(8)))
    >>> model = train_model(space, "fine", 1, "nb")
    >>> from taxonomy.learning.versions import add_version, current_version, use_version
    >>> with tempfile.TemporaryDirectory() as db:
    ...     for _ in range(2):
    ...         _ = add_version(db, model, fingerprint="", feature_code_version="")
    ...     newest = current_version(db).version
    ...     chosen = use_version(db, "v1").version
    ...     current = current_version(db).version
    >>> newest, chosen, current
    (2, 1, 1)
    """
    folder = models_folder(db_root)
    find_version(db_root, spec)
    with _locked(folder):
        chosen = find_version(db_root, spec)
        index = _read_index(folder)
        index["current"] = chosen.version
        _write_index(folder, index)
    return chosen


def find_version(db_root: str | os.PathLike[str], spec: str | int) -> ModelVersion:
    """The version ``spec`` names (``3``, ``"v3"``, ``"v003"``).

    Parameters
    ----------
    db_root : str or os.PathLike
        The database's folder.
    spec : str or int
        A version number, with or without a leading ``v`` and zeros.

    Returns
    -------
    ModelVersion
        The version, whose file exists.

    Raises
    ------
    VersionError
        No such version, or its file is gone.

    Examples
    --------
    A model from before versions is version 0:

    >>> import tempfile
    >>> from pathlib import Path
    >>> from taxonomy.learning.versions import find_version
    >>> with tempfile.TemporaryDirectory() as db:
    ...     (Path(db) / "models").mkdir()
    ...     (Path(db) / "models" / "rf-fine-X10.skops").touch()
    ...     found = [find_version(db, spec).file for spec in (0, "v0", "v000")]
    >>> found
    ['rf-fine-X10.skops', 'rf-fine-X10.skops', 'rf-fine-X10.skops']
    >>> find_version("/data/lab", "latest")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    taxonomy.learning.versions.VersionError: 'latest' is not a model version (give its number, ...)
    """
    match = _VERSION.fullmatch(str(spec).strip())
    if match is None:
        raise VersionError(f"{spec!r} is not a model version (give its number, as 'texplorer models' lists them)")
    number = int(match[1])
    found = {v.version: v for v in versions(db_root)}
    if number not in found:
        known = ", ".join(f"v{n}" for n in sorted(found)) or "none: train one with 'texplorer train'"
        raise VersionError(f"{models_folder(db_root)}: no model version {number} (versions: {known})")
    if not version_file(db_root, found[number]).is_file():
        raise VersionError(f"{version_file(db_root, found[number])}: the file of version {number} is missing")
    return found[number]


def is_version(spec: str | os.PathLike[str]) -> bool:
    """Whether a ``--model`` value names a version (``3``, ``v3``) rather than a file.

    Parameters
    ----------
    spec : str or os.PathLike
        The value given; a path that exists is a file even where it looks like a version.

    Returns
    -------
    bool
        True for a version number (with or without ``v``) that is not an existing path.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from taxonomy.learning.versions import is_version
    >>> is_version("3"), is_version("v012"), is_version("models/rf-fine-X10.skops"), is_version("latest")
    (True, True, False, False)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     (Path(folder) / "7").touch()
    ...     named_7 = is_version(Path(folder) / "7")
    >>> named_7
    False
    """
    return _VERSION.fullmatch(str(spec).strip()) is not None and not Path(spec).exists()


def _plain(row: ModelVersion) -> dict[str, Any]:
    plain = asdict(row)
    plain["classes"] = list(row.classes)
    plain["figures"] = dict(row.figures)
    return plain


def _index_bytes(index: Mapping[str, Any]) -> bytes:
    return (json.dumps(index, indent=1, allow_nan=False) + "\n").encode("utf-8")


def _write_index(folder: Path, index: Mapping[str, Any]) -> None:
    atomic_write_bytes(folder / INDEX, _index_bytes(index))
