"""Feature extraction and evaluation on a Dask cluster (scanner.runtime.cluster), on loopback only: a LocalCluster
of two worker processes, and a scheduler and workers started as ``dask scheduler`` / ``dask worker``
subprocesses. Every result is compared bit for bit with the serial run; a worker is killed mid-run; Ctrl-C
cancels the cluster's work; workers that do not see the database get its bytes from the client."""

from __future__ import annotations

import _thread
import dataclasses
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
import types
import warnings
from pathlib import Path

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")
psutil = pytest.importorskip("psutil")  # installed with distributed (its nanny uses it)

from unit.test_evaluation import labelled_space  # noqa: E402

from features import FeatureSpace, ScanSource, code_version, extract_many  # noqa: E402
from scanner.runtime import executors  # noqa: E402
from scanner.runtime.cluster import (  # noqa: E402
    NO_WORKERS_ENV,
    ClusterError,
    DataShipped,
    connect,
    local_workers,
    no_workers_timeout,
    scheduler_address,
)
from scanner.runtime.executors import DaskRuntime, using  # noqa: E402
from scanner.simulation import recordings as sim  # noqa: E402
from scanner.simulation.database import synthetic_database  # noqa: E402
from scanner.storage.database import Database  # noqa: E402
from taxonomy.learning.evaluation import evaluate, evaluate_grid  # noqa: E402
from taxonomy.related import Dataset, compare  # noqa: E402

# A hung cluster fails the test instead of hanging CI; all tests of this file share one xdist worker.
pytestmark = [pytest.mark.timeout(300), pytest.mark.xdist_group("dask"), pytest.mark.slow]

MATERIALS = ["polyurethane-foam", "mild-steel-brushed", "float-glass"]
DASK = Path(sys.executable).with_name("dask")


def sources_of(db: Database) -> list[ScanSource]:
    """The sources ``texplorer features`` extracts: stored scans with their catalogued hashes."""
    records = db.records()
    return [ScanSource(r.scan_id, r.label, r.sample_id, stored, cache_key=r.content_hash)
            for r, stored in zip(records, db.stored_scans(records), strict=True)]


def on_dask(client, fn, *args, ship_data: bool = False, **kwargs):
    """``fn(*args, **kwargs)`` with the Dask cluster of ``client`` as the current runtime (as a command with
    ``--scheduler`` runs it)."""
    with using(DaskRuntime(client, ship_data=ship_data)) as runtime:
        assert executors.current() is runtime
        return fn(*args, **kwargs)


def same_bits(a: FeatureSpace, b: FeatureSpace) -> bool:
    """Equal bit for bit (NaN payloads included), in the same order, with the same failures."""
    return (a.X.tobytes() == b.X.tobytes() and a.scan_ids == b.scan_ids and a.label_text == b.label_text
            and a.groups == b.groups and a.failed == b.failed and a.columns == b.columns)


@pytest.fixture(scope="module")
def pristine(tmp_path_factory) -> Path:
    """Six simulated scans (three materials, two samples), 320 px photos."""
    root = tmp_path_factory.mktemp("cluster") / "db"
    synthetic_database(root, MATERIALS, scans_per_material=2, seed=4, image_size=(320, 320), progress=False,
                       workers=1)
    return root


@pytest.fixture(scope="module")
def damaged(pristine, tmp_path_factory) -> Path:
    """A copy whose first scan's .mat is truncated and whose third scan lost a photo after cataloguing."""
    root = tmp_path_factory.mktemp("damaged") / "db"
    shutil.copytree(pristine, root)
    db = Database(root)
    records = db.records()
    mat = root / records[0].path
    mat.write_bytes(mat.read_bytes()[:300])
    photo = next(root / e.path for e in db.files(records[2].scan_id) if e.role == "I_macro")
    photo.unlink()
    return root


@pytest.fixture(scope="module")
def serial(damaged) -> FeatureSpace:
    space = extract_many(sources_of(Database(damaged)), workers=1, progress=False)
    assert len(space) == 4 and [scan_id for scan_id, _ in space.failed] == [
        r.scan_id for r in Database(damaged).records()[0:3:2]]
    return space


def fresh_copy(source: Path, tmp_path: Path, name: str = "db") -> Path:
    """A copy of a database with an empty feature cache."""
    root = tmp_path / name
    shutil.copytree(source, root)
    return root


@pytest.fixture(scope="module")
def local_cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  host="127.0.0.1") as cluster, distributed.Client(cluster) as client:
        client.wait_for_workers(2, timeout=120)
        yield client


# -- choosing where the work runs ---------------------------------------------------------------------

def test_scheduler_comes_from_the_option_then_from_dask_configuration():
    import dask.config

    assert scheduler_address("tcp://10.0.0.5:8786") == "tcp://10.0.0.5:8786"
    with dask.config.set({"scheduler-address": "tcp://127.0.0.1:9999"}):
        assert scheduler_address(None) == "tcp://127.0.0.1:9999"
        assert scheduler_address("local:2") == "local:2"
    with dask.config.set({"scheduler-address": None}), connect(None) as client:
        assert client is None  # the embedded default: processes on this machine
    with dask.config.set({"scheduler-address": None}), executors.connect(None) as runtime:
        assert runtime is executors.LOCAL is executors.current()
    assert local_workers("local") is None and local_workers("local:3") == 3
    for bad in ("local:0", "local:x", "local:-1"):
        with pytest.raises(ClusterError, match="expected local:N with N >= 1"):
            local_workers(bad)


def test_the_wait_for_a_worker_comes_from_the_environment(monkeypatch):
    monkeypatch.delenv(NO_WORKERS_ENV, raising=False)
    assert no_workers_timeout() == 30.0
    monkeypatch.setenv(NO_WORKERS_ENV, "2.5")
    assert no_workers_timeout() == 2.5
    for text in ("0", "-1", "nan", "inf", "soon"):
        monkeypatch.setenv(NO_WORKERS_ENV, text)
        with pytest.raises(ClusterError, match=rf"^\$TEXPLORER_DASK_NO_WORKERS_TIMEOUT must be a positive number of "
                                               rf"seconds, got '{text}'$"):
            no_workers_timeout()


def test_cli_refuses_both_workers_and_scheduler_and_an_unreachable_scheduler(pristine, capsys):
    from scanner.cli import main

    for command in ("features", "serve"):
        assert main([command, "--db", str(pristine), "--workers", "2", "--scheduler", "local:2"]) == 1
        assert "--workers sets processes on this machine, --scheduler a Dask cluster" in capsys.readouterr().err
    assert not (pristine / ".gui").exists()  # the refused server made nothing in the database
    env = {**os.environ, "DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "1s"}
    run = subprocess.run([sys.executable, "-m", "scanner.cli", "features", "--db", str(pristine), "--scheduler",
                          "tcp://127.0.0.1:9"], capture_output=True, text=True, env=env, timeout=120)
    assert run.returncode == 1
    assert run.stderr.strip().splitlines()[-1].startswith(
        "texplorer: error: cannot connect to the Dask scheduler at tcp://127.0.0.1:9: ")


def test_local_n_starts_a_local_cluster_with_the_dashboard(pristine, tmp_path, capsys):
    from scanner.cli import main

    with connect("local:1") as client:
        assert len(client.nthreads()) == 1 and client.scheduler.address.startswith("tcp://127.0.0.1:")
        # Its workers leave the terminal's Ctrl-C to texplorer, which closes them with the cluster.
        assert list(client.run(lambda: signal.getsignal(signal.SIGINT) == signal.SIG_IGN).values()) == [True]
    root = fresh_copy(pristine, tmp_path)
    assert main(["features", "--db", str(root), "--scheduler", "local:1"]) == 0
    err = capsys.readouterr().err
    assert "dask: 1 worker(s) (1 threads) at tcp://127.0.0.1:" in err and ", dashboard http://127.0.0.1:" in err
    reference = extract_many(sources_of(Database(pristine)), workers=1, progress=False)
    assert same_bits(FeatureSpace.from_csv(root / "features.csv"), reference)


# -- a LocalCluster of two worker processes -----------------------------------------------------------

def test_local_cluster_equals_the_serial_run_and_reports_failures_as_the_pool(local_cluster, damaged, serial):
    sources = sources_of(Database(damaged))
    pool = extract_many(sources, workers=2, progress=False)
    assert same_bits(pool, serial)
    with pytest.warns(DataShipped) as shipped:  # no worker sees the truncated first .mat as catalogued
        on_cluster = on_dask(local_cluster, extract_many, sources, progress=False)
    assert "2 Dask worker(s) do not see" in str(shipped[0].message)
    assert same_bits(on_cluster, serial)
    truncated, photo_lost = (reason for _, reason in on_cluster.failed)
    # A catalogued file cut short is not the bytes the catalog recorded: refused before it is parsed.
    assert truncated.startswith("ChangedSinceStored: ") and "changed since it was stored" in truncated
    assert photo_lost.endswith("_macro.png cannot be read (No such file or directory)")


def test_local_cluster_reads_shared_storage_or_gets_the_bytes(local_cluster, pristine):
    sources = sources_of(Database(pristine))
    reference = extract_many(sources, workers=1, progress=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataShipped)  # the workers see the pristine files: nothing is sent
        assert same_bits(on_dask(local_cluster, extract_many, sources, progress=False), reference)
    assert same_bits(on_dask(local_cluster, extract_many, sources, progress=False, ship_data=True), reference)
    in_memory = [Database(pristine).get(s.scan_id) for s in sources[:2]]
    assert same_bits(on_dask(local_cluster, extract_many, in_memory, progress=False),
                     extract_many(in_memory, workers=1, progress=False))


def test_cache_is_resolved_and_written_by_the_client_only(local_cluster, pristine, tmp_path):
    db = Database(fresh_copy(pristine, tmp_path))
    sources = sources_of(db)
    first = on_dask(local_cluster, extract_many, sources[:3], cache=db, progress=False)
    for source, row in zip(sources[:3], first.X, strict=True):
        assert np.array(list(db.cached_features(source.cache_key, code_version()).values())).tobytes() == row.tobytes()
    # Cached scans are never submitted: their loaders would fail on any machine.
    unloadable = [dataclasses.replace(s, load=_unloadable) if i < 3 else s for i, s in enumerate(sources)]
    again = on_dask(local_cluster, extract_many, unloadable, cache=db, progress=False)
    assert again.failed == () and again.X[:3].tobytes() == first.X.tobytes()
    assert same_bits(again, extract_many(sources, workers=1, progress=False))


def _unloadable():
    raise OSError("this scan was read from the cache, not loaded")


def test_evaluation_and_compare_on_the_cluster_equal_the_local_run(local_cluster):
    space = labelled_space(materials=6, samples=2, scans=2)
    args = dict(classifiers=["rf", "lda", "knn"], levels=["coarse", "fine"], set_sizes=[3], folds=3)
    here = evaluate_grid(space, workers=1, **args)
    there = on_dask(local_cluster, evaluate_grid, space, **args)
    assert [r.to_dict() for r in there] == [r.to_dict() for r in here]
    one = on_dask(local_cluster, evaluate, space, "svm", "medium", folds=3, protocol="paper")
    assert one.to_dict() == evaluate(space, "svm", "medium", folds=3, protocol="paper").to_dict()

    soft = Dataset.from_recordings("sim:soft3axis", sim.soft3axis_recordings(
        materials=["aluminium", "rubber", "denim"], trials=8))
    alone = compare(soft, ["chathuranga"], repeats=4)
    spread = on_dask(local_cluster, compare, soft, ["chathuranga"], repeats=4)
    assert [(r.classifier, r.accuracy.tolist(), r.f1.tolist(), r.confusion.tolist(), r.notes) for r in spread] == \
        [(r.classifier, r.accuracy.tolist(), r.f1.tolist(), r.confusion.tolist(), r.notes) for r in alone]


def test_a_recording_set_on_the_cluster_equals_the_local_run(local_cluster):
    from unit.test_recording_features import recording

    from features import recordings
    from features.recordings import Windowing

    rs = [recording(1.0, f"r{i}", object=f"o{i // 2}") for i in range(4)]
    here, notes = recordings.feature_space(rs, Windowing(0.5, "rows"), workers=1)
    there, cluster_notes = on_dask(local_cluster, recordings.feature_space, rs, Windowing(0.5, "rows"))
    assert same_bits(there, here) and cluster_notes == notes and len(notes) == 4


def test_ctrl_c_cancels_the_submitted_work_and_leaves_the_cache_consistent(local_cluster, pristine, tmp_path):
    db = Database(fresh_copy(pristine, tmp_path))
    sources = sources_of(db) * 4  # duplicates share a cache key: enough work to be interrupted
    reference = extract_many(sources[:6], workers=1, progress=False)

    class InterruptedAfterFirstStore:
        stored = 0

        def cached_features(self, key, version):
            return db.cached_features(key, version)

        def store_features(self, key, version, values):
            db.store_features(key, version, values)
            self.stored += 1
            if self.stored == 1:
                threading.Timer(0.05, _thread.interrupt_main).start()  # Ctrl-C while the cluster works

    cache = InterruptedAfterFirstStore()
    with pytest.raises(KeyboardInterrupt):
        on_dask(local_cluster, extract_many, sources, cache=cache, progress=False)
    deadline = time.monotonic() + 60
    while local_cluster.run_on_scheduler(_tasks_left) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert local_cluster.run_on_scheduler(_tasks_left) == 0, "the submitted tasks were not cancelled"
    cached = {s.cache_key: db.cached_features(s.cache_key, code_version()) for s in sources[:6]}
    done = [i for i, s in enumerate(sources[:6]) if cached[s.cache_key] is not None]
    assert 1 <= len(done) < 6
    for i in done:  # every stored row is complete and right
        assert np.array(list(cached[sources[i].cache_key].values())).tobytes() == reference.X[i].tobytes()
    resumed = on_dask(local_cluster, extract_many, sources[:6], cache=db, progress=False)
    assert same_bits(resumed, reference)


def _tasks_left(dask_scheduler) -> int:
    return len(dask_scheduler.tasks)


@pytest.mark.parametrize("ship_data", [False, True], ids=["shared-storage", "shipped"])
def test_a_worker_killed_mid_run_costs_a_retry_not_the_run(local_cluster, pristine, ship_data):
    local_cluster.wait_for_workers(2, timeout=120)
    sources = sources_of(Database(pristine)) * 3
    reference = extract_many(sources[:6], workers=1, progress=False)
    pids = local_cluster.run(os.getpid)
    outcome = {}
    run = threading.Thread(target=lambda: outcome.update(space=on_dask(
        local_cluster, extract_many, sources, progress=False, ship_data=ship_data)))
    run.start()
    victim = None
    deadline = time.monotonic() + 60
    while victim is None and run.is_alive() and time.monotonic() < deadline:
        busy = [w for w, tasks in local_cluster.processing().items() if tasks and w in pids]
        if busy:
            victim = busy[0]
            os.kill(pids[victim], signal.SIGKILL)
        time.sleep(0.02)
    run.join(timeout=240)
    assert victim is not None, "no worker was busy to be killed"
    assert not run.is_alive() and "space" in outcome
    space = outcome["space"]
    assert space.failed == ()
    assert space.X.tobytes() == np.vstack([reference.X] * 3).tobytes() and space.scan_ids == reference.scan_ids * 3
    assert victim not in local_cluster.scheduler_info()["workers"]  # it really died (the nanny starts a new one)


def test_a_scan_that_kills_every_worker_it_meets_is_reported_and_the_others_kept(pristine):
    import dask.config

    sources = sources_of(Database(pristine))[:2]
    # One scan in memory (sent with its task) and one read from storage by the worker, each killing it
    # after a while: Dask counts a death against every task the worker held, and the two scans before them
    # (run first, in the order submitted) must be done by then to be innocent of it.
    in_memory = ScanSource("killer-001", "C1S1M1P1X1", "killer", lambda: (time.sleep(2), os._exit(1)))
    stored = types.SimpleNamespace(path=Path("killer-002.mat"), visible=lambda: True, shipped=lambda: None,
                                   load_seen=lambda: (time.sleep(2), os._exit(1)))
    killers = [in_memory, ScanSource("killer-002", "C1S1M1P1X1", "killer", stored)]
    with dask.config.set({"distributed.scheduler.allowed-failures": 1}), distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, dashboard_address=None, host="127.0.0.1") as cluster, \
            distributed.Client(cluster) as client:
        space = on_dask(client, extract_many, [*sources, *killers], progress=False)
    reference = extract_many(sources, workers=1, progress=False)
    assert same_bits(space, dataclasses.replace(reference, failed=space.failed))
    assert [scan_id for scan_id, _ in space.failed] == ["killer-001", "killer-002"]
    # The worker that dies may hold the scattered scan (it is sent again) or only run the task (Dask reruns it).
    assert re.fullmatch(r"KilledWorker: 2 Dask workers (died while extracting its features \(the last "
                        r"tcp://127\.0\.0\.1:\d+\)|holding its data died before its features came "
                        r"back); see their logs", space.failed[0][1])
    assert re.fullmatch(r"KilledWorker: 2 Dask workers died while extracting its features \(the last "
                        r"tcp://127\.0\.0\.1:\d+\); see their logs", space.failed[1][1])


# -- scheduler and workers started as `dask scheduler` / `dask worker` ----------------------------------

def _start(argv: list[str], cwd: Path, log: Path) -> subprocess.Popen:
    return subprocess.Popen(argv, cwd=cwd, stdout=subprocess.DEVNULL, stderr=log.open("wb"),
                            start_new_session=True)


@pytest.fixture(scope="module")
def dask_commands(tmp_path_factory):
    """``dask scheduler`` and two ``dask worker`` processes on 127.0.0.1, working in a folder of their own."""
    home = tmp_path_factory.mktemp("workers")
    scheduler_file = home / "scheduler.json"
    processes = [_start([str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                         "--scheduler-file", str(scheduler_file)], home, home / "scheduler.log")]
    try:
        deadline = time.monotonic() + 120
        while not scheduler_file.is_file() and time.monotonic() < deadline:
            assert processes[0].poll() is None, (home / "scheduler.log").read_text()
            time.sleep(0.1)
        address = json.loads(scheduler_file.read_text())["address"]
        for n in range(2):
            processes.append(_start([str(DASK), "worker", address, "--host", "127.0.0.1", "--nthreads", "1",
                                     "--no-dashboard", "--name", f"w{n}", "--local-directory", str(home / f"w{n}")],
                                    home, home / f"worker{n}.log"))
        with distributed.Client(address) as client:
            client.wait_for_workers(2, timeout=120)
        yield address, home
    finally:
        for process in reversed(processes):
            process.terminate()
        for process in processes:
            try:
                process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()


def texplorer(args: list[str], cwd: Path, **env: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "scanner.cli", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=240, env={**os.environ, **env})


def test_cli_on_dask_commands_reads_shared_storage(dask_commands, pristine, tmp_path):
    address, _ = dask_commands
    root = fresh_copy(pristine, tmp_path)
    run = texplorer(["features", "--db", str(root), "--scheduler", address], tmp_path)
    assert run.returncode == 0, run.stderr
    assert f"dask: 2 worker(s) (2 threads) at {address}" in run.stderr and "warning" not in run.stderr
    reference = extract_many(sources_of(Database(pristine)), workers=1, progress=False)
    assert same_bits(FeatureSpace.from_csv(root / "features.csv"), reference)
    db = Database(root)  # the client wrote the cache
    assert all(db.cached_features(r.content_hash, code_version()) is not None for r in db.records())


def test_cli_honours_dask_scheduler_address_and_ships_to_workers_that_cannot_see_the_db(
        dask_commands, pristine, tmp_path):
    address, home = dask_commands
    fresh_copy(pristine, tmp_path, "lab-db")
    assert not (home / "lab-db").exists()  # the workers' folder: the relative path leads nowhere there
    run = texplorer(["features", "--db", "lab-db"], tmp_path, DASK_SCHEDULER_ADDRESS=address)
    assert run.returncode == 0, run.stderr
    assert f"dask: 2 worker(s) (2 threads) at {address}" in run.stderr
    assert "texplorer: warning: 2 Dask worker(s) do not see lab-db/scans/" in run.stderr
    assert "this machine sends each scan's files" in run.stderr
    reference = extract_many(sources_of(Database(pristine)), workers=1, progress=False)
    assert same_bits(FeatureSpace.from_csv(tmp_path / "lab-db" / "features.csv"), reference)


def extract_keys_run(address: str) -> set[str]:
    """The keys of feature-extraction tasks the cluster's scheduler has moved through its states (its
    transition log)."""
    with distributed.Client(address) as client:  # a lambda travels by value: the scheduler cannot import tests
        return set(client.run_on_scheduler(lambda dask_scheduler: sorted(
            {str(entry[0]) for entry in dask_scheduler.transition_log
             if str(entry[0]).startswith("texplorer-extract-")})))


@pytest.mark.parametrize("chosen_by", ["option", "environment"])
def test_the_web_app_extracts_on_the_cluster_its_settings_name(dask_commands, pristine, tmp_path, chosen_by):
    """``texplorer serve --scheduler ADDRESS`` or ``DASK_SCHEDULER_ADDRESS``: the server says where its work
    runs, starts no workers of its own, and the features it serves were extracted by the cluster's workers,
    bit for bit the serial run's."""
    import urllib.request

    address, _ = dask_commands
    root = fresh_copy(pristine, tmp_path)
    before = extract_keys_run(address)
    option = ["--scheduler", address] if chosen_by == "option" else []
    env = {**os.environ, "DASK_SCHEDULER_ADDRESS": address} if chosen_by == "environment" else None
    process = subprocess.Popen([sys.executable, "-m", "scanner.cli", "serve", "--db", str(root), "--port", "0",
                                *option], stderr=subprocess.PIPE, text=True, cwd=tmp_path, env=env)
    try:
        lines = []
        for line in process.stderr:
            lines.append(line.strip())
            if " at http://" in line:
                break
        url = lines[-1].split(" at ", 1)[1].split("/ ", 1)[0]
        assert lines[0].startswith(
            f"texplorer: extraction, exports and trainings run on dask: 2 worker(s) (2 threads) at {address}"), lines
        with urllib.request.urlopen(url + "/db/export/features.csv", timeout=200) as answer:
            (tmp_path / "served.csv").write_bytes(answer.read())
        assert psutil.Process(process.pid).children() == [], "a server on a cluster forks no workers of its own"
    finally:
        process.send_signal(signal.SIGINT)
        process.wait(30)
    reference = extract_many(sources_of(Database(pristine)), workers=1, progress=False)
    assert same_bits(FeatureSpace.from_csv(tmp_path / "served.csv"), reference)
    assert len(extract_keys_run(address) - before) == len(reference)


def test_ship_data_and_a_worker_that_sees_another_database_at_the_path(dask_commands, pristine, damaged,
                                                                      serial, tmp_path, monkeypatch):
    address, home = dask_commands
    fresh_copy(pristine, tmp_path, "other-db")
    theirs = home / "other-db"  # the workers see a database at the same relative path ...
    shutil.copytree(pristine, theirs)
    db = Database(theirs)
    fifth, sixth = (next(theirs / e.path for e in db.files(r.scan_id) if e.role == "I_illu")
                    for r in db.records()[4:6])
    fifth.write_bytes(sixth.read_bytes())  # ... whose fifth scan has another (valid) photo: the client sends it
    monkeypatch.chdir(tmp_path)
    sources = sources_of(Database("other-db"))
    reference = extract_many(sources, workers=1, progress=False)
    with distributed.Client(address) as client:
        with warnings.catch_warnings():
            warnings.simplefilter("error", DataShipped)  # the first scan is seen as catalogued
            assert same_bits(on_dask(client, extract_many, sources, progress=False), reference)
        assert same_bits(on_dask(client, extract_many, sources, progress=False, ship_data=True), reference)
        damaged_sources = sources_of(Database(damaged))
        with pytest.warns(DataShipped):
            assert same_bits(on_dask(client, extract_many, damaged_sources, progress=False), serial)
    replayed = texplorer(["replay", "other-db/scans", "--ship-data", "--scheduler", address], tmp_path)
    assert replayed.returncode == 0, replayed.stderr
    assert f"{len(sources)} scan(s) replayed" in replayed.stdout


def test_modern_families_on_the_cluster_equal_the_local_run(local_cluster):
    """An opt-in family travels by name: the workers compute catch22 and the signals of the scan (and of a
    recording set) as this process does, and check the same code version (families and parameters)."""
    pytest.importorskip("pycatch22", reason="the modern families need texplorer[modern]")
    from unit.test_recording_features import recording

    from features import extract_many, feature_sets
    from features.recordings import feature_space
    from scanner.storage.matfile import load_scan

    scan = load_scan(Path(__file__).parents[1] / "regression" / "scans" / "granite-polished-01-001.mat")
    here = extract_many([scan], workers=1, progress=False, families=["catch22"])
    there = on_dask(local_cluster, extract_many, [scan], progress=False, families=["catch22"])
    assert same_bits(there, here) and "catch22.v_ts.CO_FirstMin_ac" in here.columns
    rs = [recording(1.0, f"r{i}", object=f"o{i // 2}") for i in range(2)]
    chosen = feature_sets.role_families_for(["catch22"])
    local, _ = feature_space(rs, workers=1, chosen=chosen)
    remote, _ = on_dask(local_cluster, feature_space, rs, chosen=chosen)
    assert same_bits(remote, local) and any(c.startswith("catch22.") for c in local.columns)


def test_a_run_whose_workers_all_died_stops_naming_the_scheduler(pristine, tmp_path):
    """``dask scheduler`` with one ``dask worker`` (nanny and worker process), both SIGKILLed while a
    ``texplorer features`` run waits for their results: the run must stop with one line naming the scheduler
    once it has had no worker for ``$TEXPLORER_DASK_NO_WORKERS_TIMEOUT`` s, not wait for a worker for good."""
    home = tmp_path / "cluster"
    home.mkdir()
    scheduler_file = home / "scheduler.json"
    scheduler = _start([str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                        "--scheduler-file", str(scheduler_file)], home, home / "scheduler.log")
    processes = [scheduler]
    try:
        deadline = time.monotonic() + 120
        while not scheduler_file.is_file() and time.monotonic() < deadline:
            assert scheduler.poll() is None, (home / "scheduler.log").read_text()
            time.sleep(0.1)
        address = json.loads(scheduler_file.read_text())["address"]
        worker = _start([str(DASK), "worker", address, "--host", "127.0.0.1", "--nthreads", "1", "--no-dashboard",
                         "--local-directory", str(home / "w")], home, home / "worker.log")
        processes.append(worker)
        root = fresh_copy(pristine, tmp_path)
        with distributed.Client(address) as client:
            client.wait_for_workers(1, timeout=120)
            run = subprocess.Popen([sys.executable, "-m", "scanner.cli", "features", "--db", str(root),
                                    "--scheduler", address], cwd=tmp_path, stdout=subprocess.PIPE,
                                   stderr=subprocess.PIPE, text=True, start_new_session=True,
                                   env={**os.environ, "TEXPLORER_DASK_NO_WORKERS_TIMEOUT": "3"})
            processes.append(run)
            while not any(client.processing().values()) and run.poll() is None and time.monotonic() < deadline:
                time.sleep(0.02)
            assert run.poll() is None, run.communicate()
            os.killpg(worker.pid, signal.SIGKILL)  # the nanny and its worker: nothing restarts it
            worker.wait()
        try:
            _, stderr = run.communicate(timeout=90)
        except subprocess.TimeoutExpired:
            pytest.fail("texplorer still waits 90 s after the cluster's only worker died")
        last = stderr.strip().splitlines()[-1]
        assert run.returncode == 1, stderr
        assert re.fullmatch(rf"texplorer: error: the Dask scheduler at {re.escape(address)} has had no worker for "
                            r"\d+ s \(they died or left\) and [1-6] task\(s\) wait: start workers, or run without "
                            r"--scheduler", last), stderr
        assert not (root / "features.csv").exists()
    finally:
        for process in reversed(processes):  # each started in a session of its own
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()
