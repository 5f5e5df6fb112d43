"""The commit-msg check of CONTRIBUTING.md (.githooks/commit-msg) on messages that keep or break the rules."""

from __future__ import annotations

import importlib.machinery
import importlib.util
import shutil
import subprocess
from pathlib import Path

import pytest

HOOK = Path(__file__).resolve().parents[2] / ".githooks" / "commit-msg"


@pytest.fixture(scope="module")
def hook():
    loader = importlib.machinery.SourceFileLoader("commit_msg", str(HOOK))
    module = importlib.util.module_from_spec(importlib.util.spec_from_loader("commit_msg", loader))
    loader.exec_module(module)
    return module


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


CHECKED_SINCE = "1e5fc98c2a9becc21b5a5f48368483b82d345bd0"
"""Commits after this one are checked by :func:`test_every_commit_since_the_check_keeps_the_convention`
(the hook was opt-in before; the subjects of that time stay as they are)."""


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=HOOK.parents[1], capture_output=True, text=True, check=True).stdout


def test_every_commit_since_the_check_keeps_the_convention(hook):
    """The convention checked by machine, not by the hook a clone may not have installed: every commit of
    the history after :data:`CHECKED_SINCE` (in a shallow clone, every commit it holds that is not before it)."""
    if shutil.which("git") is None or not (HOOK.parents[1] / ".git").exists():
        pytest.skip("not a git checkout (an unpacked archive): no history to check")
    known = subprocess.run(["git", "cat-file", "-e", f"{CHECKED_SINCE}^{{commit}}"], cwd=HOOK.parents[1],
                           capture_output=True).returncode == 0  # absent from a shallow clone: check all it has
    commits = _git("rev-list", "HEAD", *([f"^{CHECKED_SINCE}"] if known else [])).split()
    assert commits or known, "no commit to check"
    broken = {}
    for commit in commits:
        found = hook.problems(_git("log", "-1", "--format=%B", commit))
        if found:
            broken[commit[:7] + " " + _git("log", "-1", "--format=%s", commit).strip()] = found
    assert not broken, "commits that break CONTRIBUTING.md's message convention: " + "; ".join(
        f"{commit}: {', '.join(found)}" for commit, found in broken.items())
