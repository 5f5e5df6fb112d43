"""The related methods (docs/features.md#related): simulated sensors, classifiers and protocols, compare() end to
end: the system tests (the related methods end to end and scikit-learn's estimator checks)."""

from __future__ import annotations

from sklearn.naive_bayes import GaussianNB
from sklearn.preprocessing import StandardScaler
from sklearn.utils.estimator_checks import parametrize_with_checks

from scanner.simulation import recordings as sim
from taxonomy import related as methods
from taxonomy.related import Dataset, compare
from taxonomy.related.xie_features import XieFeatures


def test_xie_end_to_end():
    chosen = ["sponge", "cotton", "PVC", "rubber", "sandpaper", "iron", "ceramics", "acrylic"]
    data = Dataset.from_recordings("sim:array", sim.array_recordings(materials=chosen, trials=6))
    results = compare(data, ["xie"], seed=1)
    assert [r.classifier for r in results[:7]] == list(methods.XIE_CLASSIFIERS)
    best = {level: max(r.accuracy_mean for r in results if r.level == level)
            for level in ("material", "property")}
    assert best["material"] > 0.5 and best["property"] > 0.7  # chance 0.125 and 0.25
    assert all(r.detail.startswith("per sample: images -> sequences ") for r in results)
    assert all("PCA dimensions per fold [" in r.detail for r in results)


def test_huang_and_hoelscher_end_to_end():
    data = Dataset.from_recordings("sim:biotac", sim.biotac_recordings(
        classes=["metal", "sponge", "wood", "fabric"], objects=2, trials=4,
        motions=["static", "slide_left"]))
    huang = compare(data, ["huang"])
    assert [r.classifier for r in huang] == ["svm", "rf", "knn"] and huang[0].motions == "slides"
    assert max(r.accuracy_mean for r in huang) > 0.5  # 8 objects: chance 0.125
    results = compare(data, ["hoelscher"], repeats=2)
    singles = [r for r in results if r.motions == "each"]
    assert {r.feature_set for r in singles} == set(methods.HOELSCHER_SETS)
    assert len(singles) == len(methods.HOELSCHER_SETS) * len(methods.HOELSCHER_CLASSIFIERS)
    combined = {(r.motions, r.classifier, r.level, r.splitting): r for r in results if r.motions != "each"}
    concatenated = combined[("2 motions, concatenation", "linear-svm", "object", "2 x one per object")]
    assert concatenated.accuracy_mean > 0.6 and concatenated.paper.startswith("97.6")
    assert ("2 motions, probabilities", "gaussian", "object", "2 x one per object") in combined
    material = combined[("2 motions, concatenation", "linear-svm", "material", "2 x one per object")]
    assert material.accuracy_mean > 0.6
    held_out = combined[("2 motions, concatenation", "linear-svm", "material", "held-out objects")]
    assert len(held_out.accuracy) == 8  # one split per object


def test_fishel_on_scans():
    from scanner.simulation import synthetic_scans

    scans = list(synthetic_scans(["polyurethane-foam", "mild-steel-brushed", "float-glass"], 3,
                                 image_size=(64, 64)))
    results = compare(scans, ["fishel"])
    assert {r.level for r in results} == {"coarse", "medium", "fine"}
    assert {r.classifier for r in results} == {"svm", "lda", "knn", "mlp", "rf", "nb", "ridge", "brf"}
    assert max(r.accuracy_mean for r in results if r.level == "fine") > 0.6  # chance 1/3
    assert methods.applicable(methods.Dataset.from_scans("db", scans)) == ["fishel", "huang", "hoelscher"]


def test_cli_compare_prints_the_table_and_writes_the_report(tmp_path, capsys):
    from scanner.cli import main
    from scanner.cli.recordings import COMPARE_METHODS

    assert COMPARE_METHODS == tuple(methods.METHODS)
    report = tmp_path / "report"
    assert main(["compare", "sim:soft3axis", "--db", str(tmp_path / "none"), "--repeats", "2",
                 "--report", str(report)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("sim:soft3axis: 720 recordings of 8 objects; levels material (8)")
    # Every method with its outcome: the roles a method lacks are named.
    assert out[1] == "fishel       not run: needs scans (v_ts, f_frn, f_frt); sim:soft3axis has recordings only"
    assert out[2].startswith("xie          not run: needs the role taxels or electrodes; 720 of 720 recordings "
                             "lack taxels or electrodes (roles present: force_xyz)")
    assert out[4].startswith("chathuranga  ran (3 results)")
    assert out[6].split()[:3] == ["method", "features", "classifier"] and out[8].startswith("chathuranga")
    # --repeats 2 repeats chathuranga's holdout twice (it ran half as many, at least 2, unsaid).
    assert "--repeats 2: chathuranga repeated 2 times" in out and any("2 x holdout 1/6" in line for line in out)
    page = (report / "index.html").read_text()
    assert "<th>classify us</th>" in page and "pairwise-svm" in page and "<td>not run: needs the role" in page
    assert page.count("data:image/png;base64,") == 2  # the accuracy chart and one confusion matrix
    assert main(["compare", "sim:gelsight", "--db", str(tmp_path)]) == 1
    assert "unknown simulated sensor 'gelsight'" in capsys.readouterr().err


XIE_WIDTH = "XieFeatures takes 3n-vectors (n >= 2) of Xie's three sequences; this check feeds another width"


def _expected_failures(estimator) -> dict[str, str]:
    if not isinstance(estimator, XieFeatures):
        return {}
    return dict.fromkeys((
        "check_fit_score_takes_y", "check_estimators_dtypes", "check_dtype_object", "check_pipeline_consistency",
        "check_estimators_pickle", "check_f_contiguous_array_estimator", "check_transformer_data_not_an_array",
        "check_transformer_general", "check_transformer_preserve_dtypes", "check_methods_sample_order_invariance",
        "check_methods_subset_invariance", "check_dict_unchanged", "check_fit_idempotent"), XIE_WIDTH)


@parametrize_with_checks([methods.PairwiseEliminationSVM(palpations=1), methods.NearestSpatialPeriod(),
                          methods.ShrunkGaussian(),
                          methods.MotionCombination(StandardScaler(), methods.ShrunkGaussian(), blocks=1),
                          methods.MotionCombination(StandardScaler(), GaussianNB(), blocks=1, mode="voting"),
                          XieFeatures()],
                         expected_failed_checks=_expected_failures)
def test_scikit_learn_estimator_checks(estimator, check):
    check(estimator)
