"""The commit-msg check of CONTRIBUTING.md (.githooks/commit-msg) on messages that keep or break the rules."""

from __future__ import annotations

import importlib.machinery
import importlib.util
from pathlib import Path

import pytest

HOOK = Path(__file__).resolve().parents[2] / ".githooks" / "commit-msg"


def load_hook():
    """The hook's module (a script without the .py suffix)."""
    loader = importlib.machinery.SourceFileLoader("commit_msg", str(HOOK))
    module = importlib.util.module_from_spec(importlib.util.spec_from_loader("commit_msg", loader))
    loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def hook():
    return load_hook()


@pytest.mark.parametrize("message", [
    "Add the catch22 family\n\nWhy, and what was measured.\n",
    "Fix the slide window at 44.1 kHz\n",
    "Speed up the Harris response\n",
    "Merge branch 'structure' into main with a subject git writes itself and that runs long\n",
    "fixup! Add the catch22 family\n",
    "# a comment git strips\nMove the Pacer to scanner/pacing.py\n",
])
def test_messages_that_keep_the_convention_pass(hook, message):
    assert hook.problems(message) == []


@pytest.mark.parametrize(("message", "problem"), [
    ("A" * 73 + "\n", "the subject has 73 characters, more than 72"),
    ("Add the catch22 family.\n", "the subject ends with a period"),
    ("Added the catch22 family\n", "the subject starts with 'Added': use the imperative"),
    ("Fixing the slide window\n", "the subject starts with 'Fixing'"),
    ("Fixes the slide window\n", "the subject starts with 'Fixes'"),
    ("Add the catch22 family\nwithout a blank line\n", "the second line is not blank"),
    ("# only a comment\n\n", "the message is empty"),
])
def test_messages_that_break_it_are_refused_with_the_reason(hook, message, problem):
    assert any(found.startswith(problem) for found in hook.problems(message))


def test_the_hook_exits_non_zero_on_a_bad_message(hook, tmp_path, capsys):
    path = tmp_path / "COMMIT_EDITMSG"
    path.write_text("Added things.\n")
    assert hook.main(str(path)) == 1
    assert "use the imperative" in capsys.readouterr().err
    path.write_text("Add things\n")
    assert hook.main(str(path)) == 0

