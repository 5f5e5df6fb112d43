"""The one interface to where work runs (scanner.runtime): chosen once, asked everywhere, the same results
in this process as the serial loop. Worker processes and Dask clusters are the system tests' (test_runtime,
test_cluster)."""

from __future__ import annotations

import threading

import pytest

from scanner import runtime
from scanner.runtime.executors import LOCAL, LocalRuntime, Runtime


def _power(base: int, exponent: int) -> int:
    return base**exponent


class Recording(LocalRuntime):
    """The local runtime, counting the calls that reach it."""

    def __init__(self) -> None:
        self.calls = 0

    def map_unordered(self, fn, calls, **kwargs):
        self.calls += len(calls)
        return super().map_unordered(fn, calls, **kwargs)


def test_processes_here_are_current_until_another_runtime_is_chosen():
    assert runtime.current() is LOCAL and isinstance(LOCAL, Runtime)
    chosen = Recording()
    with runtime.using(chosen) as used:
        assert used is chosen and runtime.current() is chosen
        seen = []
        thread = threading.Thread(target=lambda: seen.append(runtime.current()))  # the choice is the process's
        thread.start()
        thread.join()
        assert seen == [chosen]
        with runtime.using(LOCAL):
            assert runtime.current() is LOCAL
        assert runtime.current() is chosen
    assert runtime.current() is LOCAL


def test_a_runtime_left_by_an_error_is_no_longer_current():
    with pytest.raises(ZeroDivisionError), runtime.using(Recording()):
        1 / 0  # noqa: B018
    assert runtime.current() is LOCAL


def test_map_unordered_in_this_process_gives_every_call_with_its_index():
    calls = [(2, k) for k in range(6)]
    ticks = []
    got = dict(LOCAL.map_unordered(_power, calls, workers=1, tick=ticks.append))
    assert got == {k: 2**k for k in range(6)} and ticks == [1] * 6
    assert LOCAL.share(calls) == calls  # nothing to send: the calls carry their data


def test_the_code_that_runs_work_asks_the_current_runtime():
    # The related methods' scoring takes no cluster argument: the current runtime runs its splits.
    import numpy as np
    from sklearn.neighbors import KNeighborsClassifier

    from taxonomy.related.scoring import score

    X = np.array([[0.0], [0.1], [0.2], [1.0], [1.1], [1.2]])
    y = np.array(["a", "a", "a", "b", "b", "b"])
    splits = [(np.array([0, 1, 3, 4]), np.array([2, 5])), (np.array([1, 2, 4, 5]), np.array([0, 3]))]
    counting = Recording()
    with runtime.using(counting):
        scores = score(lambda k, y_train: KNeighborsClassifier(1), X, y, splits)
    assert counting.calls == 2 and scores.accuracy.tolist() == [1.0, 1.0]



def test_dask_is_asked_for_a_scheduler_only_where_it_could_be_configured(tmp_path, monkeypatch):
    from scanner.runtime import cluster

    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.setattr(cluster.sys, "prefix", str(tmp_path / "prefix"))
    monkeypatch.setattr(cluster.site, "PREFIXES", [str(tmp_path / "site")])
    root = tmp_path / "etc-dask"  # stands for /etc/dask, which this machine may have
    monkeypatch.setattr(cluster.os.path, "isfile", lambda path: False)
    real_listdir = cluster.os.listdir
    monkeypatch.setattr(cluster.os, "listdir", lambda path: real_listdir(root if path == "/etc/dask" else path))
    assert not cluster.dask_configuration_exists({})
    assert cluster.dask_configuration_exists({"DASK_SCHEDULER_ADDRESS": "tcp://10.0.0.5:8786"})
    assert cluster.dask_configuration_exists({"DASK_DISTRIBUTED__WORKER__MEMORY__TARGET": "0.6"})
    for folder in (tmp_path / ".config" / "dask", tmp_path / "prefix" / "etc" / "dask", root):
        folder.mkdir(parents=True)
        (folder / "notes.txt").write_text("not configuration")
        assert not cluster.dask_configuration_exists({})
        (folder / "scheduler.yaml").write_text("scheduler-address: tcp://10.0.0.5:8786\n")
        assert cluster.dask_configuration_exists({})
        (folder / "scheduler.yaml").unlink()


def test_workers_choose_processes_here_whatever_dask_is_configured(monkeypatch):
    """``--workers`` (a command's or the web app's) means this machine's processes, even where Dask's
    configuration names a scheduler; together with a scheduler it is refused in one line."""
    from scanner.runtime.cluster import ClusterError
    from scanner.runtime.executors import chosen

    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "tcp://127.0.0.1:9")  # nothing listens: asking would fail
    with chosen(None, workers=1) as where:
        assert where is LOCAL and runtime.current() is LOCAL
    with pytest.raises(ClusterError, match="^--workers sets processes on this machine, --scheduler a Dask "
                       "cluster: give one$"), chosen("tcp://127.0.0.1:9", workers=1):
        pass
    assert runtime.current() is LOCAL
