"""The report's figures and reading aids, on traces whose answer is known in closed form.

* the tracking figure never clips either controller's peak (matplotlib Agg: every drawn line's
  data lies inside its axes' limits), linear or symmetric-log;
* the PID limit-cycle detector finds a square wave in the dwells and nothing in a settled dwell;
* theta_hat's convergence fraction and the excitation level of the regressor.
"""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")

from commission.cli.plots_validate import LOG_RATIO, tracking_figure  # noqa: E402
from commission.report import excitation_level, pid_limit_cycle, theta_convergence  # noqa: E402
from commission.scenarios import VARIANTS  # noqa: E402
from commission.validate import Trace  # noqa: E402

FS = 1000.0


def _trace(e_arc, e_pid, qd=None, u_pid=None, theta=None, theta_true=(30.0, 8.0, 0.0)):
    n = len(e_arc)
    t = np.arange(n) / FS
    qd = np.zeros(n) if qd is None else qd
    th = np.tile(theta_true, (n, 1)) if theta is None else theta
    return Trace(t=t, qd=qd, y_arc=qd + e_arc, u_arc=np.sin(2 * np.pi * t), y_pid=qd + e_pid,
                 u_pid=np.zeros(n) if u_pid is None else u_pid, theta_hat=th, theta_true=theta_true)


def _result(traces):
    runs = {n: SimpleNamespace(name=n, tags=(n.split("/")[0], n.split("/")[1]), arc=SimpleNamespace(diverged=False),
                               pid=SimpleNamespace(diverged=False)) for n in traces}
    return SimpleNamespace(traces=traces, runs=tuple(runs.values()), run=lambda n: runs[n], quantization=1e-6,
                           units={"u": "V", "q": "m"})


def _lines_inside(fig):
    for ax in fig.axes:
        lo, hi = ax.get_ylim()
        for line in ax.get_lines():
            y = np.asarray(line.get_ydata(), dtype=float)
            y = y[np.isfinite(y)]
            if y.size:
                assert lo <= y.min() and y.max() <= hi, (ax.get_title(), lo, hi, y.min(), y.max())


@pytest.mark.parametrize("pid_peak_um", [11.6, 400.0])  # within LOG_RATIO of the ARC's peak, and far beyond it
def test_tracking_figure_never_clips_a_controller_s_peak(pid_peak_um):
    rng = np.random.default_rng(0)
    traces = {}
    for i, v in enumerate(VARIANTS):
        n = 4000
        e_arc = 0.3e-6 * rng.standard_normal(n)
        e_arc[100] = 6e-6  # the ARC's peak
        e_pid = 1e-6 * rng.standard_normal(n)
        e_pid[200 + i] = -pid_peak_um * 1e-6  # a single-sample PID peak, as at a reversal
        traces[f"case1/{v}"] = _trace(e_arc, e_pid)
    fig = tracking_figure(_result(traces), "case1", with_trajectory=False)
    _lines_inside(fig)
    scales = {ax.get_yscale() for ax in fig.axes}
    assert scales == ({"symlog"} if pid_peak_um / 6.0 > LOG_RATIO else {"linear"})


def test_the_limit_cycle_detector_finds_a_hunting_baseline_and_not_a_settled_one():
    n = 3000
    qd = np.r_[np.linspace(0.0, 0.1, 1000), np.full(2000, 0.1)]  # a move, then a 2 s dwell
    t = np.arange(n) / FS
    hunt = 8e-6 * np.sign(np.sin(2 * np.pi * 7.0 * t))  # +-8 um square wave at 7 Hz
    u_hunt = 0.2 * np.sign(np.sin(2 * np.pi * 7.0 * t))
    settled = np.zeros(n)
    settled[1000:1100] = 5e-6 * np.exp(-np.arange(100) / 20)  # a decaying transient, then still
    res = _result({"case2/nominal": _trace(np.zeros(n), hunt, qd=qd, u_pid=u_hunt),
                   "case2/payload_light": _trace(np.zeros(n), settled, qd=qd)})
    found = pid_limit_cycle(res)
    assert set(found) == {"case2/nominal"}
    e_amp, u_amp = found["case2/nominal"]
    assert e_amp == pytest.approx(8e-6) and u_amp == pytest.approx(0.2)


def test_theta_convergence_is_the_fraction_of_the_initial_error_closed():
    n = 100
    th = np.tile([20.0, 8.0, 1.0], (n, 1))
    th[-1] = [28.0, 8.0, -1.0]  # theta1 closed 80 % of 10; theta2 started at the plant; theta3 moved away
    res = _result({"case1/nominal": _trace(np.zeros(n), np.zeros(n), theta=th, theta_true=(30.0, 8.0, 0.0))})
    f1, f2, f3 = theta_convergence(res)["case1/nominal"]
    assert f1 == pytest.approx(0.8) and math.isnan(f2) and f3 == pytest.approx(0.0)


def test_excitation_level_is_zero_for_collinear_regressors_and_one_for_orthogonal():
    n = 10000
    t = np.arange(n) / FS
    still = _trace(np.zeros(n), np.zeros(n), qd=np.zeros(n))
    still = dataclasses.replace(still, u_arc=np.full(n, 0.3))  # constant u, no motion: [u, -qd, 1] collinear
    assert excitation_level(still) == pytest.approx(0.0, abs=1e-9)
    # u = sin(wt) and qd = -cos(wt) integrate to a velocity in quadrature with u: orthogonal to each other and to 1
    moving = _trace(np.zeros(n), np.zeros(n), qd=-np.sin(2 * np.pi * t) / (2 * np.pi))
    moving = dataclasses.replace(moving, u_arc=np.sin(2 * np.pi * t))
    assert excitation_level(moving) == pytest.approx(1.0, abs=0.01)
