"""The related work's feature sets on recordings, by name (docs/features.md#related): what each reads and the
function computing it from a recording, each defined beside its paper's method. Names are
``<set>.<feature>``; ``fishel3`` works on scans (:func:`taxonomy.related.fishel_features.fishel3`)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType

from scanner.scan import Recording
from taxonomy.related.chathuranga_features import chathuranga4, chathuranga_net, chathuranga_period
from taxonomy.related.hoelscher_features import CHU_ROLES, MEAN_ROLES, chitta, chu, dallaire, mean23, temperature, xu3
from taxonomy.related.huang_features import huang7
from taxonomy.related.inputs import RelatedFeatureError
from taxonomy.related.xie_features import xie11


@dataclass(frozen=True)
class RelatedSet:
    """A related-work feature set: what it reads and the function computing it from a recording."""

    name: str
    roles: tuple[str, ...]
    source: str
    function: Callable[[Recording], dict[str, float]]

    def applies_to(self, recording: Recording) -> bool:
        """Whether the recording has every role this set reads (``xie11``: taxels or electrodes).

        Parameters
        ----------
        recording : Recording
            Any recording.

        Returns
        -------
        bool
            True if :attr:`function` can compute the set from the recording's roles.

        Examples
        --------
        >>> import numpy as np
        >>> from scanner import Recording, Trace
        >>> from taxonomy.related.sets import FEATURE_SETS
        >>> channels = {"e": Trace(np.zeros((4, 19)), 100.0, "-"), "pac": Trace(np.zeros(4), 100.0, "-")}
        >>> recording = Recording("r1", channels, {"electrodes": "e", "vibration": "pac"})
        >>> [name for name, found in FEATURE_SETS.items() if found.applies_to(recording)]
        ['xie11', 'huang7', 'dallaire', 'chitta']
        """
        if self.name == "xie11":
            return "taxels" in recording.roles or "electrodes" in recording.roles
        return all(role in recording.roles for role in self.roles)


FEATURE_SETS: Mapping[str, RelatedSet] = MappingProxyType({s.name: s for s in (
    RelatedSet("xie11", ("taxels",), "Xie et al. 2019", xie11),
    RelatedSet("huang7", ("vibration",), "Huang and Wu 2021", huang7),
    RelatedSet("chathuranga4", ("force_xyz",), "Chathuranga et al. 2015", chathuranga4),
    RelatedSet("chathuranga_period", ("force_xyz",), "Chathuranga et al. 2015, spatial-period baseline",
               chathuranga_period),
    RelatedSet("chathuranga_net", ("force_xyz",), "Chathuranga et al. 2015, neural-net baseline",
               chathuranga_net),
    RelatedSet("xu3", ("electrodes", "vibration", "heat_flow"), "Hoelscher et al. 2015 after Xu et al.", xu3),
    RelatedSet("chu", CHU_ROLES, "Hoelscher et al. 2015 after Chu et al.", chu),
    RelatedSet("mean23", MEAN_ROLES, "Hoelscher et al. 2015", mean23),
    RelatedSet("dallaire", ("vibration",), "Hoelscher et al. 2015 after Dallaire et al.", dallaire),
    RelatedSet("chitta", ("electrodes",), "Hoelscher et al. 2015 after Chitta et al.", chitta),
    RelatedSet("temperature", ("heat_flow", "temperature"), "Hoelscher et al. 2015", temperature),
)})
"""Feature sets on recordings by name; ``fishel3`` works on scans (:func:`fishel3`)."""


def compute(name: str, recording: Recording) -> dict[str, float]:
    """The feature set ``name`` of one recording (docs/features.md#related).

    Parameters
    ----------
    name : str
        A key of :data:`FEATURE_SETS`: ``fishel3``, ``xie11``, ``huang7``, ``chathuranga4``, ``xu3``,
        ``chu``, ``mean23``, ``dallaire``, ``chitta``, ``temperature``.
    recording : Recording
        A recording with the set's roles (a scan is one through :func:`scan_recording`).

    Returns
    -------
    dict of str to float
        The set's features, ``<set>.<feature>``.

    Raises
    ------
    RelatedFeatureError
        The recording lacks a role the set reads, an unknown set name, or data the set cannot use.

    Examples
    --------
    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> from taxonomy.related.inputs import RelatedFeatureError
    >>> from taxonomy.related.sets import compute
    >>> recording = Recording("r1", {"pac": Trace(np.array([1.0, -1.0] * 4), 100.0, "-")}, {"vibration": "pac"})
    >>> compute("dallaire", recording)["dallaire.total_variation"]
    14.0
    >>> try:
    ...     compute("chitta", recording)
    ... except RelatedFeatureError as problem:
    ...     print(problem)
    chitta needs the role(s) electrodes; recording 'r1' lacks electrodes
    """
    if name not in FEATURE_SETS:
        raise RelatedFeatureError(f"unknown feature set {name!r} (known: {', '.join(FEATURE_SETS)})")
    return FEATURE_SETS[name].function(recording)
