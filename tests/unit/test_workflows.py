"""The shared workflows (scanner.workflows): a database's features through its cache, named predictions."""

from __future__ import annotations

from scanner.workflows.predictions import NOT_IN_TAXONOMY, Prediction, format_predictions, name_predictions
from taxonomy.table import load_taxonomy


def test_predictions_are_named_by_the_taxonomy_given():
    named = name_predictions([("C6S1M1P2X1", 0.75), ("C9S9M9P9X9", 0.25)], load_taxonomy())
    assert named[0] == Prediction("C6S1M1P2X1", 0.75, load_taxonomy().name("C6S1M1P2X1"))
    assert named[1].names == NOT_IN_TAXONOMY
    first, second = format_predictions(named).splitlines()
    assert first.startswith("1. C6S1M1P2X1   75.0 %  granite")
    assert second.endswith("25.0 %  (not in the taxonomy table)")


def test_a_lab_code_is_named_by_the_database_taxonomy(tmp_path):
    extension = tmp_path / "taxonomy.csv"
    extension.write_text("kind,code,name,description\nM,C6S1M9,diorite,Intermediate intrusive rock\n")
    taxonomy = load_taxonomy(extension)
    assert "diorite" in name_predictions([("C6S1M9P2X1", 1.0)], taxonomy)[0].names
    assert name_predictions([("C6S1M9P2X1", 1.0)], load_taxonomy())[0].names == NOT_IN_TAXONOMY
