"""The feature space X0 (docs/evaluation.md): rows = scans, named feature columns, label and group columns.

Rows may also be the recordings of an imported set, labelled with the set's own class names
(``label_level`` names their level, e.g. ``material``), with coarser ``levels`` where the set defines them
and the set's own train/test ``split``.

Files:

- CSV: header ``scan_id,sample_id,label,C,S,M,P,X,<feature columns...>``; one row per scan; ``NaN`` for
  undefined values; floats written with full precision (``repr``), so a round trip is exact. A space with
  free labels writes ``label:<level>`` as the third column (C..X are then -1), and between ``X`` and the
  features a ``level:<name>`` column per coarser level and a ``split`` column (``train``/``test``) if it
  has a split.
- ``.mat``: ``X`` (n x f double), ``columns`` (1 x f cell of names), ``labels`` (n x 5 double: C, S, M, P, X),
  ``label`` (n x 1 cell of label text), ``scan_id`` and ``sample_id`` (n x 1 cells); with free labels also
  ``label_level`` (text), ``levels`` (a struct of n x 1 cells) and ``split`` (n x 1 cell, if any).
"""

from __future__ import annotations

import csv
import html
import io
import math
import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy  # scipy.io loads at its first use (scipy's submodules load when first read)

from features.registry import REGISTRY
from scanner.lazy import optional
from scanner.storage.files import atomic_write_bytes
from taxonomy.errors import TexplorerError
from taxonomy.labels import LEVELS, Label, check_level

_ID_COLUMNS = ("scan_id", "sample_id", "label")
_LABEL_PARTS = ("C", "S", "M", "P", "X")
SPLITS = ("train", "test")
"""The parts of a set's own split."""


class FeatureSpaceError(TexplorerError, ValueError):
    """A feature space or feature file is inconsistent; the message names what is wrong."""


@dataclass(frozen=True)
class FeatureSpace:
    """Feature matrix ``X`` (n scans x f features) with its column names, scan ids, labels and groups.

    Parameters
    ----------
    X : numpy.ndarray
        (n, f) float values, NaN where a feature is undefined.
    columns : tuple of str
        Feature names, e.g. ``features.NAMES``.
    scan_ids : tuple of str
        One id per row.
    label_text : tuple of str
        One label per row: a taxonomy label, or a free class name at ``label_level``.
    groups : tuple of str
        Sample ids: scans of one sample stay in one cross-validation fold.
    failed : tuple of (str, str)
        ``(scan_id, reason)`` of scans that could not be extracted (they have no row).
    label_level : str, optional
        None for taxonomy labels (levels coarse, medium, fine); a name for free class names at that level
        (an imported set's ``material``, ``object``, ...).
    levels : mapping of str to tuple of str
        Coarser levels the set defines: name -> one class per row.
    split : tuple of str
        Empty, or ``train``/``test`` per row.

    Raises
    ------
    FeatureSpaceError
        Inconsistent lengths or shapes, repeated column names or scan ids.

    Examples
    --------
    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> space = FeatureSpace(np.array([[1.0, 2.0], [3.0, 4.0]]), ("tactum.matx", "other.density"), ("a", "b"),
    ...                      ("C6S1M1P2X1", "C1S1M1P4X1"), ("granite-01", "oak-01"))
    >>> space.y("coarse").tolist(), space.modality("other").columns
    (['C6', 'C1'], ('other.density',))
    """

    X: np.ndarray
    columns: tuple[str, ...]
    scan_ids: tuple[str, ...]
    label_text: tuple[str, ...]
    groups: tuple[str, ...]
    failed: tuple[tuple[str, str], ...] = field(default=())
    label_level: str | None = None
    levels: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    split: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        X = np.array(self.X, dtype=np.float64)
        if X.ndim != 2:
            raise FeatureSpaceError(f"X must be 2-D (scans x features), got shape {X.shape}")
        n, f = X.shape
        if len(self.columns) != f:
            raise FeatureSpaceError(f"{len(self.columns)} column names for {f} feature columns")
        if len(set(self.columns)) != f:
            raise FeatureSpaceError("column names are not unique")
        for name, values in (("scan_ids", self.scan_ids), ("label_text", self.label_text), ("groups", self.groups)):
            if len(values) != n:
                raise FeatureSpaceError(f"{len(values)} {name} for {n} rows")
        if np.isinf(X).any():
            raise FeatureSpaceError("X contains inf; undefined features must be NaN")
        X.flags.writeable = False
        object.__setattr__(self, "X", X)
        for name in ("columns", "scan_ids", "label_text", "groups", "split"):
            object.__setattr__(self, name, tuple(str(v) for v in getattr(self, name)))
        object.__setattr__(self, "failed", tuple((str(a), str(b)) for a, b in self.failed))
        self._check_labels(n)

    def _check_labels(self, n: int) -> None:
        levels = {str(k): tuple(str(v) for v in values) for k, values in self.levels.items()}
        if self.label_level is None and levels:
            raise FeatureSpaceError("taxonomy labels have the levels coarse, medium and fine; extra levels "
                                    "need free labels (label_level)")
        for name, values in levels.items():
            if len(values) != n:
                raise FeatureSpaceError(f"{len(values)} classes of level {name!r} for {n} rows")
            if name == self.label_level or not name.strip() or "," in name:
                raise FeatureSpaceError(f"level name {name!r} is empty, has a comma or repeats the label's")
        if self.split and (len(self.split) != n or not set(self.split) <= set(SPLITS)):
            raise FeatureSpaceError(f"split must give train or test for each of the {n} rows")
        object.__setattr__(self, "levels", levels)

    @property
    def level_names(self) -> tuple[str, ...]:
        """The classification levels, coarse to fine: coarse, medium, fine for taxonomy labels; the set's
        coarser levels, then the label's level, for free labels."""
        return LEVELS if self.label_level is None else (*self.levels, self.label_level)

    def check_level(self, level: str | None = None) -> str:
        """``level`` if this space has it (None and ``fine`` mean the finest level); else an error naming
        the levels there are.

        Parameters
        ----------
        level : str, optional
            A level of :attr:`level_names`, ``fine`` or None (the finest: the label's own level).

        Returns
        -------
        str
            The level's name in this space: ``fine`` for taxonomy labels, the label's level (``material``)
            for free labels.

        Raises
        ------
        LabelError
            An unknown level of a space with taxonomy labels (a ``ValueError``).
        FeatureSpaceError
            A level the free labels of this space do not have.

        Examples
        --------
        >>> import numpy as np
        >>> from features import FeatureSpace
        >>> taxonomy = FeatureSpace(np.zeros((1, 1)), ("other.density",), ("a",), ("C6S1M1P2X1",), ("g",))
        >>> taxonomy.check_level(), taxonomy.check_level("coarse")
        ('fine', 'coarse')
        >>> free = FeatureSpace(np.zeros((1, 1)), ("other.density",), ("a",), ("cork",), ("g",),
        ...                     label_level="material", levels={"hardness": ("soft",)})
        >>> free.check_level(), free.check_level("fine"), free.check_level("hardness")
        ('material', 'material', 'hardness')
        >>> free.check_level("coarse")
        Traceback (most recent call last):
        ...
        features.space.FeatureSpaceError: no level 'coarse' in this feature space (levels: hardness, material)
        """
        if self.label_level is None:
            return check_level("fine" if level is None else level)
        if level is None or level == "fine":
            return self.label_level
        if level not in self.level_names:
            raise FeatureSpaceError(f"no level {level!r} in this feature space (levels: "
                                    f"{', '.join(self.level_names)})")
        return level

    def __len__(self) -> int:
        return self.X.shape[0]

    # -- notebooks ---------------------------------------------------------------------------------

    def __repr__(self) -> str:
        """One line: rows x features, groups, classes, failed scans (the values: :meth:`to_pandas`)."""
        return f"FeatureSpace({self._shape_text()})"

    def _shape_text(self) -> str:
        level = self.label_level or "fine"
        text = (f"{len(self)} rows x {len(self.columns)} features, {len(set(self.groups))} groups, "
                f"{len(set(self.label_text))} classes at {level}")
        if self.levels:
            text += f" (coarser levels: {', '.join(self.levels)})"
        if self.split:
            text += f", split {self.split.count('train')} train / {self.split.count('test')} test"
        return text + (f", {len(self.failed)} failed" if self.failed else "")

    def _repr_html_(self, rows: int = 5, features: int = 6) -> str:
        """The first ``rows`` rows and ``features`` features as an HTML table, under the :meth:`__repr__` line."""
        shown = self.columns[:features]
        header = ["scan", "label", "group", *shown] + (["..."] if len(self.columns) > features else [])
        body = [[self.scan_ids[i], self.label_text[i], self.groups[i], *(f"{v:.4g}" for v in self.X[i, :features])]
                + (["..."] if len(self.columns) > features else []) for i in range(min(rows, len(self)))]
        if len(self) > rows:
            body.append(["..."] * len(header))
        return f"<p>FeatureSpace: {html.escape(self._shape_text())}</p>" + _html_table(header, body)

    def to_pandas(self):
        """The feature space as a ``pandas.DataFrame``: one row per scan, indexed by ``scan_id``.

        Returns
        -------
        pandas.DataFrame
            The columns ``label`` and ``group`` (the sample: scans of one group stay in one fold), for a
            recording set also its coarser levels (``level:<name>``) and ``split``, then one float column per
            feature, named as :attr:`columns` (``frame[space.columns]`` is ``X``; NaN where undefined).

        Raises
        ------
        ModuleNotFoundError
            pandas is not installed (``pip install 'texplorer[pandas]'``).

        Examples
        --------
        >>> frame = space.to_pandas()  # doctest: +SKIP
        >>> frame.groupby("label")["other.density"].mean()  # doctest: +SKIP
        """
        pd = optional("pandas", "pandas", "FeatureSpace.to_pandas()")
        names, values = self._label_columns()
        described = {"label": self.label_text, "group": self.groups, **dict(zip(names, values, strict=True))}
        frame = pd.DataFrame(described, index=pd.Index(self.scan_ids, name="scan_id"))
        features = pd.DataFrame(self.X, index=frame.index, columns=list(self.columns))
        return pd.concat([frame, features], axis=1)

    @property
    def labels(self) -> np.ndarray:
        """(n, 5) integer array of the label parts C, S, M, P, X."""
        if self.label_level is not None:
            raise FeatureSpaceError(f"the labels are free class names of level {self.label_level!r}, "
                                    "not taxonomy codes")
        return np.array([Label.parse(text).numbers() for text in self.label_text], dtype=np.int64).reshape(-1, 5)

    def y(self, level: str | None = "fine") -> np.ndarray:
        """Class of every row at ``level`` ("coarse" = C, "medium" = C+S, "fine" = full label; for free
        labels the label's level, ``fine`` or None, or a coarser level of the set).

        Parameters
        ----------
        level : str, optional
            The classification level (:meth:`check_level`); default the finest.

        Returns
        -------
        numpy.ndarray of str, shape (n,)
            The class of every row at that level, in row order.

        Raises
        ------
        ValueError
            A level this space does not have (:meth:`check_level`).

        Examples
        --------
        >>> import numpy as np
        >>> from features import FeatureSpace
        >>> space = FeatureSpace(np.zeros((2, 1)), ("other.density",), ("a", "b"), ("C6S1M1P2X1", "C6S2M1P1X1"),
        ...                      ("granite-01", "marble-01"))
        >>> space.y("coarse").tolist(), space.y("medium").tolist(), space.y().tolist()
        (['C6', 'C6'], ['C6S1', 'C6S2'], ['C6S1M1P2X1', 'C6S2M1P1X1'])
        >>> free = FeatureSpace(np.zeros((3, 1)), ("other.density",), ("r0", "r1", "r2"), ("cork", "felt", "oak"),
        ...                     ("r0", "r1", "r2"), label_level="material",
        ...                     levels={"hardness": ("soft", "soft", "hard")})
        >>> free.y().tolist(), free.y("hardness").tolist()
        (['cork', 'felt', 'oak'], ['soft', 'soft', 'hard'])
        """
        level = self.check_level(level)
        if self.label_level is None:
            return np.array([Label.parse(text).at(level) for text in self.label_text])
        return np.array(self.label_text if level == self.label_level else self.levels[level])

    def modality(self, name: str) -> FeatureSpace:
        """The columns of one modality: a registered family (``tactum``, ``image``, ``audio``, ``other``),
        whose name is the first part of its column names.

        Parameters
        ----------
        name : str
            The name of a registered family (:data:`features.REGISTRY`).

        Returns
        -------
        FeatureSpace
            The same rows with only the columns whose first name part is ``name``, in their order.

        Raises
        ------
        FeatureSpaceError
            If ``name`` is not a registered family.

        Examples
        --------
        >>> import numpy as np
        >>> from features import FeatureSpace
        >>> space = FeatureSpace(np.array([[1.0, 2.0, 3.0]]), ("tactum.matx", "other.density", "tactum.fst"),
        ...                      ("a",), ("C6S1M1P2X1",), ("granite-01",))
        >>> tactum = space.modality("tactum")
        >>> tactum.columns, tactum.X.tolist()
        (('tactum.matx', 'tactum.fst'), [[1.0, 3.0]])
        """
        if name not in REGISTRY:
            known = ", ".join(f.name for f in REGISTRY.every)
            raise FeatureSpaceError(f"unknown modality {name!r} (known: {known})")
        return self.subset([c for c in self.columns if c.split(".", 1)[0] == name])

    def subset(self, columns: Sequence[str]) -> FeatureSpace:
        """A feature space with only ``columns`` (in that order).

        Parameters
        ----------
        columns : sequence of str
            Names of columns of this space, in the order wanted.

        Returns
        -------
        FeatureSpace
            The same rows, labels and groups with those columns only.

        Raises
        ------
        FeatureSpaceError
            If a name is not a column of this space.

        Examples
        --------
        >>> import numpy as np
        >>> from features import FeatureSpace
        >>> space = FeatureSpace(np.array([[1.0, 2.0], [3.0, 4.0]]), ("tactum.matx", "other.density"), ("a", "b"),
        ...                      ("C6S1M1P2X1", "C1S1M1P4X1"), ("granite-01", "oak-01"))
        >>> space.subset(["other.density", "tactum.matx"]).X.tolist()
        [[2.0, 1.0], [4.0, 3.0]]
        """
        index = {name: i for i, name in enumerate(self.columns)}
        missing = [c for c in columns if c not in index]
        if missing:
            raise FeatureSpaceError(f"no such feature column(s): {', '.join(missing[:5])}")
        picked = [index[c] for c in columns]
        return FeatureSpace(self.X[:, picked], tuple(columns), self.scan_ids, self.label_text, self.groups,
                            self.failed, self.label_level, self.levels, self.split)

    def rows(self, indices: Sequence[int]) -> FeatureSpace:
        """A feature space with only the rows ``indices`` (in that order).

        Parameters
        ----------
        indices : sequence of int
            Row numbers of this space; one may repeat.

        Returns
        -------
        FeatureSpace
            Those rows with their scan ids, labels, groups, coarser levels and split; the same columns and
            failed scans.

        Examples
        --------
        >>> import numpy as np
        >>> from features import FeatureSpace
        >>> space = FeatureSpace(np.array([[1.0], [2.0], [3.0]]), ("other.density",), ("a", "b", "c"),
        ...                      ("C6S1M1P2X1", "C1S1M1P4X1", "C1S1M1P4X1"), ("granite-01", "oak-01", "oak-02"))
        >>> picked = space.rows([2, 0])
        >>> picked.scan_ids, picked.X.tolist(), picked.groups
        (('c', 'a'), [[3.0], [1.0]], ('oak-02', 'granite-01'))
        """
        picked = list(indices)
        return FeatureSpace(self.X[picked], self.columns, [self.scan_ids[i] for i in picked],
                            [self.label_text[i] for i in picked], [self.groups[i] for i in picked],
                            self.failed, self.label_level,
                            {k: [v[i] for i in picked] for k, v in self.levels.items()},
                            [self.split[i] for i in picked] if self.split else ())

    def _label_columns(self) -> tuple[list[str], list[tuple[str, ...]]]:
        """Header and values of the columns between ``X`` and the features: coarser levels, split."""
        names = [f"level:{name}" for name in self.levels]
        values = list(self.levels.values())
        if self.split:
            names.append("split")
            values.append(self.split)
        return names, values

    # -- files -------------------------------------------------------------------------------------

    def to_csv(self, path: str | os.PathLike[str]) -> Path:
        """Write the CSV described in the module docstring, atomically.

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (replaced if it exists).

        Returns
        -------
        pathlib.Path
            ``path``.

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> import numpy as np
        >>> from features import FeatureSpace
        >>> space = FeatureSpace(np.array([[0.1, np.nan]]), ("tactum.matx", "other.density"), ("a",),
        ...                      ("C6S1M1P2X1",), ("granite-01",))
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     print(space.to_csv(Path(folder) / "space.csv").read_text(), end="")
        scan_id,sample_id,label,C,S,M,P,X,tactum.matx,other.density
        a,granite-01,C6S1M1P2X1,6,1,1,2,1,0.1,NaN
        """
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        label = "label" if self.label_level is None else f"label:{self.label_level}"
        extra, values = self._label_columns()
        writer.writerow([*_ID_COLUMNS[:2], label, *_LABEL_PARTS, *extra, *self.columns])
        parts = _label_parts(self.label_text)
        for i in range(len(self)):
            writer.writerow([self.scan_ids[i], self.groups[i], self.label_text[i], *parts[i],
                             *(v[i] for v in values), *(_format_float(v) for v in self.X[i])])
        atomic_write_bytes(path, buffer.getvalue().encode("utf-8"))
        return Path(path)

    @classmethod
    def from_csv(cls, path: str | os.PathLike[str]) -> FeatureSpace:
        """Read a CSV written by :meth:`to_csv`; errors name the file, line and column.

        Parameters
        ----------
        path : str or os.PathLike
            A CSV file in the format of the module docstring.

        Returns
        -------
        FeatureSpace
            The space written, values exact (no failed scans: the CSV does not keep them).

        Raises
        ------
        FeatureSpaceError
            If the file cannot be read, its header is not that of a feature space, a row has another number
            of fields or a value is not a number.

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> import numpy as np
        >>> from features import FeatureSpace
        >>> space = FeatureSpace(np.array([[1 / 3], [np.nan]]), ("other.density",), ("r0", "r1"), ("cork", "felt"),
        ...                      ("r0", "r1"), label_level="material", split=("train", "test"))
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     read = FeatureSpace.from_csv(space.to_csv(Path(folder) / "space.csv"))
        >>> bool(read.X[0, 0] == 1 / 3), bool(np.isnan(read.X[1, 0])), read.label_level, read.split
        (True, True, 'material', ('train', 'test'))
        """
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise FeatureSpaceError(f"{path}: cannot read ({exc})") from None
        rows = list(csv.reader(io.StringIO(text)))
        if not rows:
            raise FeatureSpaceError(f"{path}: empty file")
        header = rows[0]
        first = len(_ID_COLUMNS) + len(_LABEL_PARTS)
        label_level = header[2][len("label:"):] if len(header) > 2 and header[2].startswith("label:") else None
        fixed = (*_ID_COLUMNS[:2], header[2] if label_level else "label", *_LABEL_PARTS)
        if tuple(header[:first]) != fixed:
            raise FeatureSpaceError(f"{path}: line 1: header must start with {','.join((*_ID_COLUMNS, *_LABEL_PARTS))}")
        while first < len(header) and (header[first].startswith("level:") or header[first] == "split"):
            first += 1
        extra = header[len(fixed):first]
        columns = header[first:]
        ids, groups, labels, values = [], [], [], []
        kept: list[list[str]] = [[] for _ in extra]
        for line, row in enumerate(rows[1:], start=2):
            if not row:
                continue
            if len(row) != len(header):
                raise FeatureSpaceError(f"{path}: line {line}: {len(row)} fields, header has {len(header)}")
            ids.append(row[0])
            groups.append(row[1])
            labels.append(row[2])
            for k in range(len(extra)):
                kept[k].append(row[len(fixed) + k])
            try:
                values.append([float(v) for v in row[first:]])
            except ValueError as exc:
                raise FeatureSpaceError(f"{path}: line {line}: {exc}") from None
        X = np.array(values, dtype=np.float64).reshape(len(values), len(columns))
        levels = {name[len("level:"):]: tuple(v) for name, v in zip(extra, kept, strict=True) if name != "split"}
        split = next((tuple(v) for name, v in zip(extra, kept, strict=True) if name == "split"), ())
        try:
            return cls(X, tuple(columns), tuple(ids), tuple(labels), tuple(groups), (), label_level, levels,
                       split)
        except FeatureSpaceError as exc:
            raise FeatureSpaceError(f"{path}: {exc}") from None

    def to_mat(self, path: str | os.PathLike[str]) -> Path:
        """Write ``X``, ``columns``, ``labels``, ``label``, ``scan_id``, ``sample_id`` as MATLAB v5, atomically.

        With free labels also ``label_level``, ``levels`` and ``split`` (module docstring).

        Parameters
        ----------
        path : str or os.PathLike
            The ``.mat`` file to write (replaced if it exists).

        Returns
        -------
        pathlib.Path
            ``path``.

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> import numpy as np
        >>> import scipy.io
        >>> from features import FeatureSpace
        >>> space = FeatureSpace(np.array([[1.0, 2.0]]), ("tactum.matx", "other.density"), ("a",),
        ...                      ("C6S1M1P2X1",), ("granite-01",))
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     data = scipy.io.loadmat(space.to_mat(Path(folder) / "space.mat"), simplify_cells=True)
        >>> data["X"].tolist(), data["labels"].tolist(), data["columns"].tolist()
        ([1.0, 2.0], [6.0, 1.0, 1.0, 2.0, 1.0], ['tactum.matx', 'other.density'])
        """
        buffer = io.BytesIO()
        free = {} if self.label_level is None else {
            "label_level": self.label_level,
            "levels": {name: _cell(values).reshape(-1, 1) for name, values in self.levels.items()}}
        scipy.io.savemat(buffer, {
            "X": self.X,
            "columns": _cell(self.columns).reshape(1, -1),
            "labels": _label_parts(self.label_text).astype(np.float64),
            "label": _cell(self.label_text).reshape(-1, 1),
            "scan_id": _cell(self.scan_ids).reshape(-1, 1),
            "sample_id": _cell(self.groups).reshape(-1, 1),
            **free, **({"split": _cell(self.split).reshape(-1, 1)} if self.split else {}),
        }, long_field_names=True, do_compression=True)
        atomic_write_bytes(path, buffer.getvalue())
        return Path(path)

    @classmethod
    def from_mat(cls, path: str | os.PathLike[str]) -> FeatureSpace:
        """Read a ``.mat`` file written by :meth:`to_mat`; errors name the file and the variable.

        Parameters
        ----------
        path : str or os.PathLike
            A ``.mat`` file with the variables of the module docstring.

        Returns
        -------
        FeatureSpace
            The space written (no failed scans: the file does not keep them).

        Raises
        ------
        FeatureSpaceError
            If the file is not a readable ``.mat`` file or lacks one of ``X``, ``columns``, ``label``,
            ``scan_id``, ``sample_id``, or its variables do not make a consistent space.

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> import numpy as np
        >>> from features import FeatureSpace
        >>> space = FeatureSpace(np.array([[0.1, 2.0], [3.0, np.nan]]), ("tactum.matx", "other.density"),
        ...                      ("a", "b"), ("C6S1M1P2X1", "C1S1M1P4X1"), ("granite-01", "oak-01"))
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     read = FeatureSpace.from_mat(space.to_mat(Path(folder) / "space.mat"))
        >>> read.X.tolist(), read.columns, read.y("coarse").tolist()
        ([[0.1, 2.0], [3.0, nan]], ('tactum.matx', 'other.density'), ['C6', 'C1'])
        """
        path = Path(path)
        try:
            data = scipy.io.loadmat(path, simplify_cells=True)
        except Exception as exc:  # scipy raises many types for foreign files
            raise FeatureSpaceError(f"{path}: not a readable .mat feature file ({exc})") from None
        missing = [k for k in ("X", "columns", "label", "scan_id", "sample_id") if k not in data]
        if missing:
            raise FeatureSpaceError(f"{path}: missing variable(s) {', '.join(missing)}")
        columns = _as_strings(data["columns"])
        X = np.asarray(data["X"], dtype=np.float64).reshape(-1, len(columns))
        levels = {str(k): _as_strings(v) for k, v in dict(data.get("levels") or {}).items()}
        return cls(X, columns, _as_strings(data["scan_id"]), _as_strings(data["label"]),
                   _as_strings(data["sample_id"]), (), data.get("label_level") or None, levels,
                   _as_strings(data["split"]) if "split" in data else ())


def _label_parts(label_text: Sequence[str]) -> np.ndarray:
    """C, S, M, P, X of each label; -1 for labels outside the taxonomy format (generic recordings)."""
    parts = []
    for text in label_text:
        try:
            parts.append(Label.parse(text).numbers())
        except ValueError:
            parts.append((-1,) * 5)
    return np.array(parts, dtype=np.int64).reshape(-1, 5)


def _format_float(value: float) -> str:
    return "NaN" if math.isnan(value) else repr(float(value))


def _cell(values: Sequence[str]) -> np.ndarray:
    cell = np.empty(len(values), dtype=object)
    cell[:] = list(values)
    return cell


def _as_strings(value: object) -> tuple[str, ...]:
    if isinstance(value, str):
        return (value,)
    return tuple(str(v) for v in np.asarray(value, dtype=object).ravel())


def _html_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A plain HTML table of text cells (escaped)."""
    def row(cells: Sequence[str], tag: str) -> str:
        return "<tr>" + "".join(f"<{tag}>{html.escape(str(cell))}</{tag}>" for cell in cells) + "</tr>"

    return f"<table><thead>{row(header, 'th')}</thead><tbody>{''.join(row(r, 'td') for r in rows)}</tbody></table>"


# -- the rows and columns a classifier can learn from ------------------------------------------------

def drop_nan_columns(space: FeatureSpace) -> tuple[FeatureSpace, tuple[str, ...]]:
    """Rows and columns with NaN left out before splitting: no classifier takes NaN.

    A row that is NaN in every column (a recording lacking every role the families need) is left out with
    a warning naming how many and the first few; then a column with NaN in any row is left out (it gets FQ
    0 anyway) and listed in the result; when that would leave no column, the rows with NaN are left out
    instead, with a warning.

    Parameters
    ----------
    space : FeatureSpace
        The feature space.

    Returns
    -------
    subset : FeatureSpace
        The rows and columns kept, checked by :func:`check_degenerate`.
    dropped : tuple of str
        The columns left out.

    Raises
    ------
    FeatureSpaceError
        Every row holds only NaN, or the values kept cannot be scaled or are constant.

    Examples
    --------
    The metal value of one scan is missing: the column is left out, the scan kept:

    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> X = np.array([[1.0, 5.0, 3.0], [2.0, np.nan, 1.0], [3.0, 4.0, 2.0]])
    >>> space = FeatureSpace(X, ("tactum.matx", "other.metal", "other.density"), ("a", "b", "c"),
    ...                      ("C1S1M1P1X1", "C2S1M1P1X1", "C2S1M1P1X1"), ("a", "b", "c"))
    >>> from features.space import drop_nan_columns
    >>> subset, dropped = drop_nan_columns(space)
    >>> subset.columns, dropped, subset.scan_ids
    (('tactum.matx', 'other.density'), ('other.metal',), ('a', 'b', 'c'))
    """
    empty = np.isnan(space.X).all(axis=1)
    if empty.all():
        raise FeatureSpaceError(f"every one of the {space.X.shape[0]} rows holds only NaN: no feature could be "
                              "computed")
    if empty.any():
        space = _without_rows(space, empty, "have no feature value (every column NaN)")
    has_nan = np.isnan(space.X).any(axis=0)
    dropped = tuple(c for c, bad in zip(space.columns, has_nan, strict=True) if bad)
    if not dropped:
        return check_degenerate(space), ()
    kept = [c for c, bad in zip(space.columns, has_nan, strict=True) if not bad]
    if not kept:
        return check_degenerate(_without_rows(space, np.isnan(space.X).any(axis=1), "hold NaN in some column")), ()
    return check_degenerate(space.subset(kept)), dropped


def check_degenerate(space: FeatureSpace, first: int = 3) -> FeatureSpace:
    """``space`` itself if its values can be scaled and tell rows apart; else a :class:`FeatureSpaceError`
    saying what is wrong with the data: a column whose values are infinite or span more than float64 holds
    (+-1e308: the scaler's range overflows and every value becomes NaN), or every column constant.

    Parameters
    ----------
    space : FeatureSpace
        The feature space.
    first : int
        How many overflowing columns the message names.

    Returns
    -------
    FeatureSpace
        ``space`` itself.

    Raises
    ------
    FeatureSpaceError
        A column spans more than a float64 can scale, or every column is constant.

    Examples
    --------
    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> from features.space import check_degenerate
    >>> labels, ids = ("C1S1M1P1X1", "C2S1M1P1X1"), ("a", "b")
    >>> space = FeatureSpace(np.array([[1.0], [2.0]]), ("other.density",), ids, labels, ids)
    >>> check_degenerate(space) is space
    True
    >>> constant = FeatureSpace(np.array([[1.0], [1.0]]), ("other.density",), ids, labels, ids)
    >>> check_degenerate(constant)  # doctest: +NORMALIZE_WHITESPACE
    Traceback (most recent call last):
    ...
    features.space.FeatureSpaceError: every one of the 1 feature column(s) is constant over the 2 rows
    (other.density = 1, ...): no feature can tell the classes apart
    """
    X = space.X
    with np.errstate(over="ignore", invalid="ignore"):
        span = X.max(axis=0) - X.min(axis=0) if X.size else np.zeros(X.shape[1])
    overflowing = np.flatnonzero(~np.isfinite(span))
    if overflowing.size:
        shown = ", ".join(f"{space.columns[k]} ({X[:, k].min():.3g} to {X[:, k].max():.3g})"
                          for k in overflowing[:first])
        raise FeatureSpaceError(f"{overflowing.size} feature column(s) hold infinite values or span more than a "
                              f"64-bit float can scale: {shown}; check the data's units or scale")
    if X.shape[1] and not np.any(span > 0):
        raise FeatureSpaceError(f"every one of the {X.shape[1]} feature column(s) is constant over the "
                              f"{X.shape[0]} rows ({space.columns[0]} = {X[0, 0]:.6g}, ...): no feature can tell "
                              "the classes apart")
    return space


def _without_rows(space: FeatureSpace, bad: np.ndarray, why: str, first: int = 3) -> FeatureSpace:
    """``space`` without the rows ``bad``, with a warning naming how many and the first few."""
    names = [space.scan_ids[i] for i in np.flatnonzero(bad)]
    shown = ", ".join(names[:first]) + (f" and {len(names) - first} more" if len(names) > first else "")
    warnings.warn(f"{len(names)} of {len(space.scan_ids)} row(s) {why} and are left out: {shown}", stacklevel=3)
    return space.rows(np.flatnonzero(~bad))
