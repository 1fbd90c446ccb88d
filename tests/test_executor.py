"""The executor interface (commission.infra.executor) and validate's answer on every engine.

Issue 33, must show 1: validate's Monte Carlo on the local executor, on a Dask LocalCluster of
2 worker processes, and on a LocalCluster of 1 worker whose process is killed mid-run gives
the same validation.json, up to the wall time and the executor's description.
"""

from __future__ import annotations

import json
import os
import signal
import threading
import time

import numpy as np
import pytest

from commission.infra.executor import (ENV_SCHEDULER, LocalExecutor, SchedulerError, compute_scheduler, make_executor,
                                 resolve_scheduler)
from commission.montecarlo import WORST_KEPT, MonteCarloSummary
from commission.controllers.metrics import Indexes


def _slow_square(shared, x):
    # later items finish first: the map must still yield in item order
    time.sleep(shared * (10 - x % 10))
    return x * x


def test_local_map_yields_in_task_order_whatever_finishes_first():
    items = list(range(23))
    seen = []
    with LocalExecutor(4) as ex:
        out = list(ex.map(_slow_square, 0.002, items, progress=seen.append))
    assert out == [x * x for x in items]
    assert sorted(seen) == items
    assert list(LocalExecutor(1).map(_slow_square, 0.0, items)) == out


def test_local_map_keeps_a_bounded_window_in_flight():
    started = []
    lock = threading.Lock()

    def task(_shared, x):
        with lock:
            started.append(x)
        return x

    ex = LocalExecutor(2)
    it = ex.map(task, None, list(range(100)))
    assert next(it) == 0
    time.sleep(0.05)
    with lock:
        assert len(started) <= 2 * 4 + 1  # WINDOW_PER_WORKER x workers (+ the one yielded)
    assert list(it) == list(range(1, 100))


def test_a_task_error_reaches_the_caller():
    def boom(_s, x):
        if x == 3:
            raise ValueError("task 3 failed")
        return x

    with pytest.raises(ValueError, match="task 3"):
        list(LocalExecutor(2).map(boom, None, list(range(8))))


def test_scheduler_precedence_flag_env_spec():
    env = {ENV_SCHEDULER: "tcp://env:8786"}
    assert resolve_scheduler("tcp://flag:1", "tcp://spec:2", env) == "tcp://flag:1"
    assert resolve_scheduler(None, "tcp://spec:2", env) == "tcp://env:8786"
    assert resolve_scheduler(None, "tcp://spec:2", {}) == "tcp://spec:2"
    assert resolve_scheduler(None, None, {}) is None
    with pytest.raises(SchedulerError, match="--scheduler"):
        resolve_scheduler("localhost", None, {})
    assert isinstance(make_executor(None, 3), LocalExecutor) and make_executor(None, 3).workers == 3


def test_compute_section_is_strict():
    assert compute_scheduler({"compute": {"scheduler": "tcp://h:8786"}}) == "tcp://h:8786"
    assert compute_scheduler({"tune": {}}) is None
    with pytest.raises(SchedulerError, match=r"compute\.workers: unknown key"):
        compute_scheduler({"compute": {"workers": 4}})
    with pytest.raises(SchedulerError, match=r"compute\.scheduler"):
        compute_scheduler({"compute": {"scheduler": 8786}})


def test_local_default_imports_no_dask():
    import subprocess
    import sys

    code = ("import sys, commission.validate, commission.infra.executor as e; e.make_executor(None, 2);"
            "print(any(m.split('.')[0] in ('dask', 'distributed') for m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))) + "/tests")
    assert out.stdout.strip() == "False"


def _score(e_rms, diverged=False):
    return Indexes(2 * e_rms, e_rms / 2, e_rms, 1.0, 0.1, 0.5, 2.0, diverged)


def test_monte_carlo_summary_against_numpy_and_ties_in_plant_order():
    rng = np.random.default_rng(3)
    vals = rng.uniform(1e-6, 1e-5, 200)
    vals[[17, 40]] = 9e-5  # a tie: the earlier plant ranks worse
    s = MonteCarloSummary({"q": "m"})
    for i, v in enumerate(vals):
        s.add(f"mc/{i:03d}", _score(v, diverged=(i == 99)), _score(2 * v))
    d = s.to_dict()
    assert d["plants"] == 200 and d["diverged"] == {"arc": 1, "pid": 0}
    assert d["quantiles"]["pid"]["e_rms"]["p90"] == pytest.approx(np.quantile(2 * vals, 0.9))
    assert d["quantiles"]["arc"]["e_rms"]["max"] == pytest.approx(vals.max())
    names = [w["name"] for w in d["worst"]]
    assert len(names) == WORST_KEPT and names[:3] == ["mc/099", "mc/017", "mc/040"]


def test_unreachable_scheduler_is_a_usage_error_naming_it():
    pytest.importorskip("distributed")
    t0 = time.perf_counter()
    with pytest.raises(SchedulerError, match=r"tcp://127\.0\.0\.1:9"):
        make_executor("tcp://127.0.0.1:9")
    assert time.perf_counter() - t0 < 60


# --------------------------------------------------------------------------- must show 1


def _validation(tmp_path, tuning, name, executor, n_mc, on_progress=None):
    from commission.jsonio import write_json_atomic
    from commission.validate import run_validate

    tpath = tmp_path / "tuning.json"
    if not tpath.exists():
        write_json_atomic(tpath, tuning.to_dict())
    out = tmp_path / name
    run_validate(tpath, out, seed=5, n_monte_carlo=n_mc, executor=executor, progress=on_progress)
    doc = json.loads((out / "validation.json").read_text())
    return doc


def _comparable(doc):
    doc = dict(doc)
    doc.pop("elapsed_s")  # the only key that varies: validation.json names no host or executor
    return doc


@pytest.mark.slow
def test_validation_identical_local_dask_and_dask_with_a_killed_worker(tmp_path):
    distributed = pytest.importorskip("distributed")
    from reference_tuning import reference_tuning

    tuning = reference_tuning()
    n_mc = 48  # 3 Monte-Carlo tasks of 16 plants, and the fixed scenarios one task each
    local = _validation(tmp_path, tuning, "local", LocalExecutor(2), n_mc)
    assert local["monte_carlo_summary"]["plants"] == n_mc

    from commission.infra.executor import DaskExecutor

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as c, \
            distributed.Client(c) as client:
        two = _validation(tmp_path, tuning, "dask2", DaskExecutor(client=client), n_mc)
    assert _comparable(two) == _comparable(local)

    killed = []
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as c, \
            distributed.Client(c) as client:
        ex = DaskExecutor(client=client)

        def kill_once(done, total):
            if not killed and done > 0:  # the first task is back: kill the only worker's process
                pids = client.run(os.getpid)
                for pid in pids.values():
                    os.kill(pid, signal.SIGKILL)
                killed.extend(pids.values())

        one = _validation(tmp_path, tuning, "dask1-killed", ex, n_mc, on_progress=kill_once)
        assert killed, "the worker was never killed"
        assert set(client.run(os.getpid).values()).isdisjoint(killed)  # a new worker process finished the run
    assert _comparable(one) == _comparable(local)


def test_validate_with_an_unreachable_scheduler_is_exit_2_and_writes_nothing(tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    from typer.testing import CliRunner

    from commission.cli.main import app
    from commission.jsonio import write_json_atomic
    from reference_tuning import reference_tuning

    tpath = tmp_path / "tuning.json"
    write_json_atomic(tpath, reference_tuning().to_dict())
    runner = CliRunner()
    r = runner.invoke(app, ["validate", str(tpath), "--out-dir", str(tmp_path / "a"), "--monte-carlo", "2",
                            "--scheduler", "tcp://127.0.0.1:9"])
    assert r.exit_code == 2 and "tcp://127.0.0.1:9" in r.output and "cannot be reached" in r.output
    monkeypatch.setenv(ENV_SCHEDULER, "tcp://127.0.0.1:7")
    r = runner.invoke(app, ["validate", str(tpath), "--out-dir", str(tmp_path / "a"), "--monte-carlo", "2"])
    assert r.exit_code == 2 and "tcp://127.0.0.1:7" in r.output
    assert not (tmp_path / "a").exists()


def test_run_reads_the_compute_section_and_the_flag_overrides_it(tmp_path):
    pytest.importorskip("distributed")
    from pathlib import Path

    from typer.testing import CliRunner

    from commission.cli.main import app

    sample = Path(__file__).resolve().parents[1] / "sample_data" / "axis_excitation.h5"
    spec = tmp_path / "spec.toml"
    spec.write_text('[tune]\nbudget = 8\n\n[compute]\nscheduler = "tcp://127.0.0.1:9"\n')
    runner = CliRunner()
    r = runner.invoke(app, ["run", str(sample), "--out-dir", str(tmp_path / "a"), "--spec", str(spec)])
    assert r.exit_code == 2 and "tcp://127.0.0.1:9" in r.output
    r = runner.invoke(app, ["run", str(sample), "--out-dir", str(tmp_path / "a"), "--spec", str(spec),
                            "--scheduler", "tcp://127.0.0.1:7"])
    assert r.exit_code == 2 and "tcp://127.0.0.1:7" in r.output
    spec.write_text('[compute]\nscheduler = "tcp://127.0.0.1:9"\nworkers = 2\n')
    r = runner.invoke(app, ["run", str(sample), "--out-dir", str(tmp_path / "a"), "--spec", str(spec)])
    assert r.exit_code == 2 and "compute.workers: unknown key" in r.output
    assert not (tmp_path / "a").exists()


def test_dask_executor_by_address_maps_in_order_with_its_own_client():
    distributed = pytest.importorskip("distributed")
    from commission.infra.executor import DaskExecutor

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as c:
        with DaskExecutor(c.scheduler_address) as ex:  # a client of its own, not the process default
            assert ex.describe() == {"kind": "dask", "workers": 2, "scheduler": c.scheduler_address}
            items = list(range(13))
            seen = []
            assert list(ex.map(_slow_square, 0.002, items, progress=seen.append)) == [x * x for x in items]
            assert sorted(seen) == items
