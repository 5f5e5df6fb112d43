"""The feature-family registries: a toy family added through the registry alone reaches extraction, the
feature space, evaluation, the web groups and the cache key; a toy family of generic recordings reaches
their families, columns, feature space and the message naming the roles the families need."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
from conftest import make_scan

from features import NAMES, REGISTRY, Family, FeatureSpace, code_version, extract, extract_many, registry
from features.extraction import source_of
from features.recordings import describe_families, families, feature_space
from features.registry import ParameterError, RoleFamily
from gui.browser import group_features
from scanner import cli
from scanner.acquisition.session import STEP_TITLES
from scanner.scan import CHANNELS, Recording, Trace
from scanner.simulation import synthetic_scan
from scanner.storage.database import Database
from scanner.storage.ingest.sets import store_recordings
from taxonomy.learning.evaluation import default_feature_sets, evaluate

TOY = ("toy.peak_v_ts", "toy.samples_v_ts")


def toy_values(prepared) -> dict[str, float]:
    """The largest |v_ts| and the number of v_ts samples: two values known without any feature code."""
    v_ts = prepared.scan["v_ts"].data
    return {"toy.peak_v_ts": float(np.abs(v_ts).max()), "toy.samples_v_ts": float(v_ts.shape[0])}


@pytest.fixture
def toy():
    before = code_version()
    family = REGISTRY.register(Family("toy", "toy: v_ts at a glance", TOY, toy_values))
    yield before
    REGISTRY.unregister(family.name)


class DictCache:
    def __init__(self) -> None:
        self.store: dict[tuple[str, str], dict[str, float]] = {}

    def cached_features(self, content_hash, version):
        return self.store.get((content_hash, version))

    def store_features(self, content_hash, version, values):
        self.store[(content_hash, version)] = dict(values)


def test_the_paper_families_in_order():
    assert REGISTRY.modalities == ("tactum", "image", "audio", "other")
    assert REGISTRY.names == NAMES and len(NAMES) == 193
    assert [len(family.columns) for family in REGISTRY] == [15, 93, 70, 15]


def test_a_toy_family_is_extracted_after_the_others(toy):
    scan = make_scan(seconds=5.0, images=False)
    with pytest.warns(Warning):  # no photos: the image features are NaN
        values = extract(scan)
    assert tuple(values) == (*NAMES, *TOY)
    assert values["toy.peak_v_ts"] == np.abs(scan["v_ts"].data).max()
    assert values["toy.samples_v_ts"] == scan["v_ts"].data.shape[0]


def test_a_toy_family_is_a_modality_of_the_feature_space(toy):
    space = extract_many([make_scan(seconds=5.0, images=False)], workers=1, progress=False)
    assert space.columns == (*NAMES, *TOY)
    assert space.modality("toy").columns == TOY


def test_a_toy_family_is_a_feature_set_of_the_evaluation(toy):
    assert default_feature_sets() == {"tactum": "tactum", "image": "image", "audio": "audio", "other": "other",
                                      "toy": "toy", "all": None}
    rng = np.random.default_rng(0)
    labels = tuple(f"C{1 + i % 2}S1M1P1X1" for i in range(12))
    X = np.column_stack([np.array([1 + i % 2 for i in range(12)]) + 0.1 * rng.standard_normal(12),
                         rng.standard_normal(12), rng.standard_normal(12)])
    space = FeatureSpace(X, ("toy.peak_v_ts", "toy.samples_v_ts", "other.noise"), tuple(f"s{i}" for i in range(12)),
                         labels, tuple(f"g{i}" for i in range(12)))
    report = evaluate(space, "lda", level="coarse", n_features=1, folds=3, feature_set="toy")
    assert report.columns == TOY and report.accuracy_mean == 1.0


def test_a_toy_family_is_a_group_of_the_web_page(toy):
    assert REGISTRY.groups[-1] == ("toy", "toy: v_ts at a glance")
    values = {**dict.fromkeys(NAMES, 1.0), "toy.peak_v_ts": 2.5, "toy.samples_v_ts": 15000.0}
    assert group_features(values)[-1] == ("toy: v_ts at a glance", [("peak_v_ts", "2.5"), ("samples_v_ts", "15000")])


def test_a_toy_family_is_counted_in_the_cli_help(toy, capsys):
    with pytest.raises(SystemExit):
        cli.main(["features", "--help"])
    assert f"Extract the {len(NAMES) + 2} features of every scan" in " ".join(capsys.readouterr().out.split())
    with pytest.raises(SystemExit):
        cli.main(["evaluate", "--help"])
    assert "toy" in capsys.readouterr().out


def test_a_toy_family_changes_the_cache_key_and_is_not_served_stale(toy):
    assert code_version() != toy
    assert __name__ in REGISTRY.code_modules()  # the family's own module
    scan = make_scan(seconds=5.0, images=False)
    cache = DictCache()
    source = dataclasses.replace(source_of(scan), cache_key="content-hash")
    REGISTRY.unregister("toy")
    try:
        without = extract_many([source], workers=1, cache=cache, progress=False)
    finally:
        REGISTRY.register(Family("toy", "toy: v_ts at a glance", TOY, toy_values))
    space = extract_many([source], workers=1, cache=cache, progress=False)
    assert without.columns == NAMES and space.columns == (*NAMES, *TOY)
    assert sorted(version for _, version in cache.store) == sorted((toy, code_version()))


def test_a_family_is_refused_when_it_clashes():
    with pytest.raises(ParameterError, match="already registered"):
        REGISTRY.register(Family("tactum", "again", ("tactum.matx",), toy_values))
    with pytest.raises(ParameterError, match="must start with 'toy.'"):
        Family("toy", "toy", ("peak",), toy_values)
    with pytest.raises(ParameterError, match="no feature family 'smell'"):
        REGISTRY.unregister("smell")


# -- families of generic recordings -----------------------------------------------------------------------

TOY_TEMPERATURE = ("other.temperature.mean", "other.temperature.range")


def temperature_values(window: np.ndarray, fs: float) -> list[float]:
    """The mean and the range of a temperature window: values known without any feature code."""
    return [float(window.mean()), float(window.max() - window.min())]


@pytest.fixture
def toy_role():
    family = REGISTRY.roles.register(RoleFamily("temperature", "temperature", TOY_TEMPERATURE, temperature_values,
                                               applies=lambda fs: fs >= 1.0))
    yield family
    REGISTRY.roles.unregister(family.name)


def warm(name: str, label: str, degrees: float) -> Recording:
    ramp = degrees + np.linspace(0.0, 2.0, 40)
    return Recording(name, {"t": Trace(ramp, 10.0, "degC")}, {"temperature": "t"}, label)


def test_the_project_families_of_recordings_in_order():
    assert REGISTRY.roles.modalities == ("audio.audio", "audio.vibration", "image.photo", "vibration", "friction")
    assert [family.role for family in REGISTRY.roles] == ["audio", "vibration", "photo", "vibration", "force_xyz"]


def test_a_toy_role_family_reaches_the_recordings_features(toy_role):
    recordings = [warm("a", "cold", 20.0), warm("b", "warm", 30.0)]
    assert families(recordings[0]) == ["temperature"]
    space, notes = feature_space(recordings)
    assert space.columns == TOY_TEMPERATURE and notes == []
    assert space.X.tolist() == [[21.0, 2.0], [31.0, 2.0]]
    assert space.modality("other").columns == TOY_TEMPERATURE
    assert describe_families(space.columns) == "other.temperature (2)"
    slow = Recording("c", {"t": Trace(np.ones(4), 0.5, "degC")}, {"temperature": "t"}, "cold")
    assert families(slow) == []  # its applies() refuses 0.5 Hz


def fragile_values(window: np.ndarray, fs: float) -> list[float]:
    """The toy family's values, failing as a bug would (not a ValueError of bad input) above 25 degrees."""
    if window.mean() > 25.0:
        raise RuntimeError("a bug met a warm window")
    return temperature_values(window, fs)


def test_a_recording_whose_extraction_fails_is_named_and_the_others_kept():
    # The one extraction path of scans and recordings: a recording that fails is left out with its reason,
    # as a broken scan is, instead of stopping the set.
    family = REGISTRY.roles.register(RoleFamily("temperature", "temperature", TOY_TEMPERATURE, fragile_values))
    try:
        space, notes = feature_space([warm("a", "cold", 20.0), warm("b", "warm", 30.0), warm("c", "cold", 21.0)])
    finally:
        REGISTRY.roles.unregister(family.name)
    assert space.scan_ids == ("a", "c") and space.X.tolist() == [[21.0, 2.0], [22.0, 2.0]]
    assert space.failed == (("b", "RuntimeError: a bug met a warm window"),)
    assert notes == ["recording 'b' could not be extracted and is left out: RuntimeError: a bug met a warm window"]


def test_features_of_a_set_with_a_failed_recording_exit_1_and_are_not_reused(tmp_path, capsys):
    # The table is written without the failed recording, which is named; its options are not, so evaluate
    # extracts again instead of reusing a table that lacks a recording.
    db = tmp_path / "db"
    Database(db).close()
    store_recordings(db, "warmth", [warm("a", "cold", 20.0), warm("b", "warm", 30.0), warm("c", "cold", 21.0),
                                    warm("d", "warm", 32.0)])
    family = REGISTRY.roles.register(RoleFamily("temperature", "temperature", TOY_TEMPERATURE, fragile_values))
    try:
        assert cli.main(["features", "set:warmth", "--db", str(db), "--workers", "1"]) == 1
    finally:
        REGISTRY.roles.unregister(family.name)
    err = capsys.readouterr().err
    assert "recording 'b' could not be extracted and is left out: RuntimeError: a bug met a warm window" in err
    folder = db / "recordings" / "warmth"
    assert (folder / "features.csv").read_text().count("\n") == 3 and not (folder / "features.json").exists()


def test_the_roles_the_families_need_come_from_the_registry(toy_role):
    pressed = Recording("p", {"d": Trace(np.ones(10), 100.0, "kPa")}, {"pressure_dc": "d"}, "soft")
    with pytest.raises(ValueError, match="the families need audio, vibration, photo, force_xyz or temperature$"):
        feature_space([pressed])


def test_a_role_family_is_refused_when_it_clashes():
    with pytest.raises(ParameterError, match="'<modality>.photo.<feature>'"):
        RoleFamily("toy", "photo", ("image.disp.lbp_0",), temperature_values)
    with pytest.raises(ParameterError, match="already registered: audio.audio.zcr"):
        REGISTRY.roles.register(RoleFamily("sound again", "audio", ("audio.audio.zcr",), temperature_values))


def test_scan_and_role_families_share_one_registry(toy_role):
    # One store: a name or a column is unique over both kinds, each view shows its own kind, and the scan
    # families' columns (the rows of every scan table) do not change when a role family is registered.
    assert toy_role.name in REGISTRY.roles and toy_role.name not in REGISTRY and len(REGISTRY.names) == 193
    with pytest.raises(ParameterError, match="a feature family 'temperature' is already registered"):
        REGISTRY.register(Family("temperature", "Toy", ("temperature.mean",), lambda prepared: {}))
    clash = REGISTRY.register(Family("toy", "Toy", ("toy.temperature.mean",), lambda prepared: {}))
    try:
        with pytest.raises(ParameterError, match="already registered: toy.temperature.mean"):
            REGISTRY.roles.register(RoleFamily("toy again", "temperature", ("toy.temperature.mean",),
                                               temperature_values))
    finally:
        REGISTRY.unregister(clash.name)
    with pytest.raises(ParameterError, match="'temperature twin' is a RoleFamily; this registry holds Family"):
        REGISTRY.register(RoleFamily("temperature twin", "temperature", ("other.temperature.std",),
                                     temperature_values))
    with pytest.raises(ParameterError, match="no feature family 'tactum'"):
        REGISTRY.roles.unregister("tactum")  # a scan family is not the role view's to remove
    assert "tactum" in REGISTRY


def test_unregistering_a_role_family_frees_its_columns(toy_role):
    twin = RoleFamily("temperature twin", "temperature", TOY_TEMPERATURE, temperature_values)
    with pytest.raises(ParameterError, match="already registered: other.temperature.mean"):
        REGISTRY.roles.register(twin)
    REGISTRY.roles.unregister(toy_role.name)
    try:
        assert REGISTRY.roles.register(twin) is twin
    finally:
        REGISTRY.roles.unregister(twin.name)
        REGISTRY.roles.register(toy_role)  # for the fixture to take away


MODULE_TOP = """
from __future__ import annotations
import json, features.space
from taxonomy.labels import Label, LEVELS
from features import modern as opt_in
from . import sibling
if TYPE_CHECKING:
    from scanner.scan import Scan
try:
    import taxonomy.table as table
except ImportError:
    table = None
with open(__file__):
    from features import kernels


class Holder:
    from scanner import replay


def later():
    import gui.app
"""


def test_the_code_version_follows_the_imports_of_a_module_s_top_level_only():
    code = compile(MODULE_TOP, "sample.py", "exec", dont_inherit=True)
    assert registry._imports_in(code) == {"features.space", "taxonomy.labels", "features", "features.modern",
                                          "scanner.scan", "taxonomy.table", "features.kernels"}


# --- which steps each column needs -----------------------------------------------------------------------


def _swapped(scan, donor, step):
    """``scan`` with the recordings of ``step`` taken from ``donor`` (channels, raw volts, photos or TU4 values)."""
    if step == "photos":
        return dataclasses.replace(scan, images=dict(donor.images))
    if step == "tu4":
        meta = dataclasses.replace(scan.meta, mass_g=donor.meta.mass_g, volume_cm3=donor.meta.volume_cm3,
                                   atk=donor.meta.atk, cyd=donor.meta.cyd)
        return dataclasses.replace(scan, meta=meta)
    names = [name for name, spec in CHANNELS.items() if spec.step == step]
    traces = {**{k: v for k, v in scan.traces.items() if k not in names},
              **{k: v for k, v in donor.traces.items() if k in names}}
    raw = {k: v for k, v in scan.raw.items() if k not in names}
    meta = dataclasses.replace(scan.meta, rigid=donor.meta.rigid) if step == "fold" else scan.meta
    return dataclasses.replace(scan, meta=meta, traces=traces, raw=raw)


@pytest.fixture(scope="module")
def contrasting_scans():
    """A soft, warm, foldable sample and a hard, cold, conductive one: every step records something different."""
    soft = synthetic_scan("leather-smooth", seed=3, image_size=(240, 240), fold_skip_probability=0.0)
    hard = synthetic_scan("mild-steel-brushed", seed=4, image_size=(240, 240), fold_skip_probability=0.0)
    return soft, hard


@pytest.mark.parametrize("step", [step for step in STEP_TITLES if step != "finger_tap"])
def test_a_step_changes_only_the_columns_that_declare_it(contrasting_scans, step):
    soft, hard = contrasting_scans
    needs = REGISTRY.column_steps()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        before, after = extract(soft), extract(_swapped(soft, hard, step))
    changed = {c for c in NAMES if not _same_value(before[c], after[c])}
    declared = {c for c in NAMES if step in needs[c]}
    assert changed <= declared, f"{step} changes undeclared columns: {sorted(changed - declared)[:5]}"
    assert len(changed) >= max(1, len(declared) // 2), f"{step}: only {sorted(changed)} of {len(declared)} changed"


def test_the_finger_tap_feeds_no_feature(contrasting_scans):
    soft, hard = contrasting_scans
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        before, after = extract(soft), extract(_swapped(soft, hard, "finger_tap"))
    assert all(_same_value(before[c], after[c]) for c in NAMES)
    assert not any("finger_tap" in steps for steps in REGISTRY.column_steps().values())


def test_every_paper_column_names_its_steps_and_only_steps_of_the_procedure():
    needs = REGISTRY.column_steps()
    assert set(needs) == set(NAMES)
    assert all(needs[c] and needs[c] <= set(STEP_TITLES) for c in NAMES)
    assert needs["image.macro.lbp_3"] == {"photos"} and needs["tactum.ccp"] == {"press", "fold"}


def test_a_family_without_steps_needs_the_whole_scan_and_a_stray_key_is_refused():
    plain = Family("plain", "plain", ("plain.a",), lambda prepared: {"plain.a": 0.0})
    assert plain.steps == {}
    with pytest.raises(ParameterError, match="steps given for columns it does not have: plain.b"):
        Family("plain", "plain", ("plain.a",), lambda prepared: {"plain.a": 0.0}, steps={"plain.b": ("press",)})
    with pytest.raises(ParameterError, match="no step named for plain.a"):
        Family("plain", "plain", ("plain.a",), lambda prepared: {"plain.a": 0.0}, steps={"plain.a": ()})


def _same_value(a: float, b: float) -> bool:
    return (np.isnan(a) and np.isnan(b)) or a == b
