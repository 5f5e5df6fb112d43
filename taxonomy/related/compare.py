"""The registry of the related methods and :func:`compare`, which runs every one that applies to a dataset."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass

from scanner.scan import Recording, Scan
from taxonomy.learning.results import Result
from taxonomy.related.chathuranga import run_chathuranga
from taxonomy.related.datasets import REPEATS, SEED, Dataset, ExtractedSets, MethodError, MethodSkipped, every
from taxonomy.related.fishel import run_fishel
from taxonomy.related.hoelscher import HOELSCHER_SETS, run_hoelscher
from taxonomy.related.huang import run_huang
from taxonomy.related.xie import run_xie


@dataclass(frozen=True)
class Method:
    """A related method: the paper, what it needs and how it runs."""

    name: str
    paper: str
    needs: str
    applies: Callable[[Dataset], bool]
    run: Callable[[Dataset, ExtractedSets, int, int], list[Result]]




METHODS: Mapping[str, Method] = {m.name: m for m in (
    Method("fishel", "Strese et al. 2020 Fig. 18 (features after Fishel and Loeb 2012)",
           "scans (v_ts, f_frn, f_frt)", lambda d: bool(d.scans), run_fishel),
    Method("xie", "Xie et al. 2019, Applied Sciences", "taxels or electrodes",
           lambda d: every(d, "xie11"), run_xie),
    Method("huang", "Huang and Wu 2021, Sensors", "vibration", lambda d: every(d, "huang7"),
           run_huang),
    Method("chathuranga", "Chathuranga et al. 2015, IROS", "force_xyz",
           lambda d: every(d, "chathuranga4"), run_chathuranga),
    Method("hoelscher", "Hoelscher, Peters and Hermans 2015, Humanoids",
           "one of vibration, electrodes, heat_flow + temperature",
           lambda d: any(every(d, s) for s in HOELSCHER_SETS), run_hoelscher),
)}
"""The related methods by name, in the order :func:`compare` runs them."""


def applicable(dataset: Dataset) -> list[str]:
    """Names of the methods whose inputs every recording of ``dataset`` has."""
    return [name for name, method in METHODS.items() if method.applies(dataset)]


METHOD_ROLES: Mapping[str, tuple[tuple[str, ...], ...]] = {
    "xie": (("taxels", "electrodes"),), "huang": (("vibration",),), "chathuranga": (("force_xyz",),),
    "hoelscher": (("vibration",), ("electrodes",), ("heat_flow", "temperature")),
}
"""What each method reads: alternatives (any one suffices) of roles that must all be present."""


def not_applicable(dataset: Dataset, name: str) -> str | None:
    """Why method ``name`` does not apply to ``dataset`` (the missing role or input), or None if it does."""
    method = METHODS[name]
    if method.applies(dataset):
        return None
    if name == "fishel":
        return f"needs scans ({method.needs.split('(')[-1].rstrip(')')}); {dataset.name} has recordings only"
    have = sorted(set.union(*(set(r.roles) for r in dataset.recordings)))
    options = METHOD_ROLES[name]
    lacking = min(([role for role in option if not all(role in r.roles for r in dataset.recordings)]
                   for option in options), key=len)
    count = sum(1 for r in dataset.recordings if not all(role in r.roles for role in lacking))
    lacks = "taxels or electrodes" if name == "xie" else " + ".join(lacking)
    needs = f"the role {lacks}" if len(options) == 1 else method.needs
    return (f"needs {needs}; {count} of {len(dataset)} recordings lack {lacks} "
            f"(roles present: {', '.join(have) or 'none'})")


@dataclass(frozen=True)
class MethodComparison:
    """The results of :func:`compare_methods` and, for every method, ``ran`` or why it did not run."""

    results: list[Result]
    outcome: dict[str, str]

    def format_outcome(self) -> str:
        width = max(len(name) for name in self.outcome)
        return "\n".join(f"{name:<{width}}  {status}" for name, status in self.outcome.items())


def compare_methods(dataset: Dataset | Sequence[Recording] | Sequence[Scan], methods: Sequence[str] | None = None,
                    *, seed: int = SEED, repeats: int = REPEATS,
                    progress: Callable[[Iterable[str]], Iterable[str]] = iter) -> MethodComparison:
    """:func:`compare`, with the outcome of every method:
    ``ran (n results)`` (and the parts it skipped), or ``not run:`` the role or value it lacks, or why the
    data could not feed it."""
    data = _as_dataset(dataset)
    outcome = {name: f"not run: {reason}" for name in METHODS
               if methods is None and (reason := not_applicable(data, name))}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", MethodSkipped)
        results = compare(data, methods, seed=seed, repeats=repeats, progress=progress)
    skipped = [str(w.message) for w in caught if issubclass(w.category, MethodSkipped)]
    for w in caught:
        if not issubclass(w.category, MethodSkipped):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    for name in METHODS if methods is None else methods:
        if name in outcome:
            continue
        count = sum(1 for r in results if r.method == name)
        own = [line.split(":", 1)[1].strip() if line.startswith(f"method {name} skipped:") else
               line.removeprefix(f"method {name}: ") for line in skipped
               if line.startswith((f"method {name} skipped:", f"method {name}:"))]
        if count == 0:
            outcome[name] = "not run: " + ("; ".join(own) or "no result")
        else:
            outcome[name] = f"ran ({count} results)" + "".join(f"; {line}" for line in own)
    return MethodComparison(results, {name: outcome[name] for name in METHODS if name in outcome})


def compare(dataset: Dataset | Sequence[Recording] | Sequence[Scan], methods: Sequence[str] | None = None, *,
            seed: int = SEED, repeats: int = REPEATS,
            progress: Callable[[Iterable[str]], Iterable[str]] = iter) -> list[Result]:
    """Run the related methods on one dataset, each with its published features, classifiers and protocol.

    The splits of each configuration are fitted one after the other here, or side by side on the current
    runtime's Dask cluster (:func:`scanner.runtime.current`); the scores are the same.

    Parameters
    ----------
    dataset : Dataset, or a sequence of recordings or scans
    methods : names from :data:`METHODS`, optional
        Default: every method that applies (:func:`applicable`); one that then cannot run on the data (too
        few rows per class, recordings too short, ...) is skipped with a :class:`MethodSkipped` warning.
        A named method that does not apply or cannot run is an error.
    seed : int
        Seed of every split and classifier.
    repeats : int
        Repetitions of the repeated protocols (Hoelscher et al.'s one-per-object splits; Chathuranga's holdouts use
        half as many, at least two).
    progress : callable
        Wraps the iteration over the methods (e.g. a tqdm bar).

    Returns
    -------
    list of Result
        In method order; see :func:`taxonomy.learning.results.format_comparison` for the table.
    """
    data = _as_dataset(dataset)
    names = applicable(data) if methods is None else list(methods)
    unknown = [name for name in names if name not in METHODS]
    if unknown:
        raise MethodError(f"unknown method(s) {', '.join(unknown)} (known: {', '.join(METHODS)})")
    for name in names:
        if not METHODS[name].applies(data):
            raise MethodError(f"method {name} needs {METHODS[name].needs}, which dataset {data.name!r} lacks")
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise MethodError(f"repeats must be a positive integer, got {repeats!r}")
    cache = ExtractedSets(data)
    results: list[Result] = []
    for name in progress(names):
        try:
            results += METHODS[name].run(data, cache, seed, repeats)
        except ValueError as exc:
            # A method the caller asked for must run; one merely applicable may find the data too small.
            reason = str(exc) if isinstance(exc, MethodError) else f"{type(exc).__name__}: {exc}"
            if methods is not None:
                raise MethodError(f"method {name}: {reason}") from None
            warnings.warn(f"method {name} skipped: {reason}", MethodSkipped, stacklevel=2)
    return results


def _as_dataset(dataset: Dataset | Sequence[Recording] | Sequence[Scan]) -> Dataset:
    if isinstance(dataset, Dataset):
        return dataset
    items = list(dataset)
    if items and all(isinstance(item, Scan) for item in items):
        return Dataset.from_scans("scans", items)
    if items and all(isinstance(item, Recording) for item in items):
        return Dataset.from_recordings("recordings", items)
    raise MethodError("compare needs a Dataset, or a non-empty list of only scans or only recordings")
