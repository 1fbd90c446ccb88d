"""The loop of ``benchmarks/bench_frozen_encoder.py`` is validate's simulator, input delay included.

The benchmark steps the compiled ARC step in its own Python loop (it must corrupt the reading
between the encoder and the step, which the compiled simulator cannot express), so it restates
the simulator's input-delay schedule.  Here, with a clean reading, that loop and
:func:`commission.controllers.simulate.simulate` run the same guarded controller (the axis of
``tests/test_runtime_guards.py``) on the paper's identified plant given an input delay (a
fraction of a sample, as on the sample, and more than one sample) and a structural mode read
on the load side (as the sample's identified plant): the readings, the true positions and the
held commands must agree sample by sample.
"""

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from commission.controllers import arc as A
from commission.controllers.plant import P_DELAY, P_MODE_DAMPING, P_MODE_HZ, P_MODE_LOAD_SIDE, P_MODE_RATIO
from commission.controllers.simulate import KIND_ARC, simulate
from commission.scenarios import plant_substeps
from test_runtime_guards import LSB, axis  # noqa: F401  (the guarded paper axis: a fixture used below)

N = 3000  # samples compared: the start, the first acceleration and the cruise of Case 2's first move


def _bench():
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_frozen_encoder.py"
    spec = importlib.util.spec_from_file_location("bench_frozen_encoder", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def bench():
    return _bench()


@pytest.mark.parametrize("delay_samples", [0.4665, 1.3])
def test_bench_loop_is_the_simulator_on_a_delayed_plant(axis, bench, delay_samples):
    g, traj = axis["g"], axis["trajs"]["case2"]
    plant = axis["plant"].copy()
    plant[P_DELAY] = delay_samples * g.Ts
    plant[P_MODE_HZ], plant[P_MODE_DAMPING], plant[P_MODE_RATIO], plant[P_MODE_LOAD_SIDE] = 500.0, 0.05, 0.5, 1.0
    n_d, f = bench.delay_schedule(plant, g.Ts)
    assert n_d == math.floor(delay_samples) and f == pytest.approx(delay_samples - n_d, abs=1e-12)
    sim = simulate(plant, KIND_ARC, A.arc_pack(g), traj, substeps=plant_substeps(1.0 / g.Ts), quant=LSB,
                   y0=float(traj.qd[0]), u_sat=g.u_max)
    assert not sim.diverged
    r = bench.closed_loop(g, plant, traj, LSB, lambda k, y: y, N)
    assert np.all(r["fault"] == 0) and np.max(np.abs(traj.dqd[:N])) == pytest.approx(1.0)  # moving at v_max
    np.testing.assert_allclose(r["y"], sim.y[:N], rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(r["q"], sim.q[:N], rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(r["u_held"], sim.u[:N], rtol=0.0, atol=1e-12)
    # the plant holds the issued command n_d samples late at the end of each sample
    np.testing.assert_array_equal(r["u_held"][n_d:], r["u"][:N - n_d])
    np.testing.assert_array_equal(r["u_held"][:n_d], 0.0)


def test_bench_loop_delay_matters(axis, bench):
    """The comparison can fail: the delay-free loop departs from the delayed simulation."""
    g, traj = axis["g"], axis["trajs"]["case2"]
    plant = axis["plant"].copy()
    plant[P_DELAY] = 0.4665 * g.Ts
    sim = simulate(plant, KIND_ARC, A.arc_pack(g), traj, substeps=plant_substeps(1.0 / g.Ts), quant=LSB,
                   y0=float(traj.qd[0]), u_sat=g.u_max)
    plant[P_DELAY] = 0.0
    r = bench.closed_loop(g, plant, traj, LSB, lambda k, y: y, N)
    assert np.max(np.abs(r["u_held"] - sim.u[:N])) > 1e-6
