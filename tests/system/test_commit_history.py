"""The message convention of CONTRIBUTING.md checked on the history itself (git in a process): every commit
after :data:`CHECKED_SINCE` keeps the rules of the commit-msg hook, installed or not."""

from __future__ import annotations

import shutil
import subprocess

import pytest
from unit.test_commit_msg import HOOK, load_hook

CHECKED_SINCE = "1e5fc98c2a9becc21b5a5f48368483b82d345bd0"
"""Commits after this one are checked by :func:`test_every_commit_since_the_check_keeps_the_convention`
(the hook was opt-in before; the subjects of that time stay as they are)."""


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=HOOK.parents[1], capture_output=True, text=True, check=True).stdout


def test_every_commit_since_the_check_keeps_the_convention():
    """The convention checked by machine, not by the hook a clone may not have installed: every commit of
    the history after :data:`CHECKED_SINCE` (in a shallow clone, every commit it holds that is not before it)."""
    if shutil.which("git") is None or not (HOOK.parents[1] / ".git").exists():
        pytest.skip("not a git checkout (an unpacked archive): no history to check")
    known = subprocess.run(["git", "cat-file", "-e", f"{CHECKED_SINCE}^{{commit}}"], cwd=HOOK.parents[1],
                           capture_output=True).returncode == 0  # absent from a shallow clone: check all it has
    commits = _git("rev-list", "HEAD", *([f"^{CHECKED_SINCE}"] if known else [])).split()
    assert commits or known, "no commit to check"
    hook, broken = load_hook(), {}
    for commit in commits:
        found = hook.problems(_git("log", "-1", "--format=%B", commit))
        if found:
            broken[commit[:7] + " " + _git("log", "-1", "--format=%s", commit).strip()] = found
    assert not broken, "commits that break CONTRIBUTING.md's message convention: " + "; ".join(
        f"{commit}: {', '.join(found)}" for commit, found in broken.items())
