"""Issue 32's polish: did-you-mean for a mistyped command, rates at their nominal value, units on the
summary's numbers, the Monte-Carlo gate line inside its axes, a caption that mentions legs only when
the log has some, and an ETA on the progress bars."""

from __future__ import annotations

import io
import math
from types import SimpleNamespace

import numpy as np
import pytest
from rich.console import Console

from commission.cli.main import run
from commission.cli.progress import StageProgress
from commission.export import readme
from commission.report import identification_markdown, summary_rows
from commission.units import nominal

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
from matplotlib.figure import Figure  # noqa: E402

from commission.cli.plots_validate import monte_carlo_figure  # noqa: E402


@pytest.mark.parametrize("typed, meant", [("identfy", "identify"), ("valdate", "validate"), ("exprot", "export")])
def test_a_mistyped_command_gets_did_you_mean(capsys, typed, meant):
    assert run([typed]) == 2
    err = capsys.readouterr().err
    assert f"No such command '{typed}'" in err and f"Did you mean '{meant}'?" in err and len(err.splitlines()) == 1


def test_a_command_like_none_gets_no_suggestion(capsys):
    assert run(["zzzz"]) == 2
    assert "Did you mean" not in capsys.readouterr().err


@pytest.mark.parametrize("x, shown", [(0.0003999999999990677, "0.0004"), (1 / 2500, "0.0004"), (2500.0, "2500"),
                                      (1000.0000000001, "1000"), (1000.016000256, "1000.016000256"),
                                      (math.inf, "inf")])
def test_nominal_prints_an_estimate_s_rounding_away_and_nothing_else(x, shown):
    assert nominal(x) == shown


def test_the_export_readme_prints_the_nominal_period_and_the_axis_s_units():
    config = SimpleNamespace(sample_rate=2500.0000000058267, gains=SimpleNamespace(Ts=0.0003999999999990677),
                             units={"u": "Nm", "q": "rad"})
    text = " ".join(readme("arc", config, SimpleNamespace(base="arc_axis"), True).split())
    assert "Sample rate: 2500 Hz (period 0.0004 s;" in text and "every 0.0004 s" in text
    assert "positions in `rad`, velocity `rad`/s, acceleration `rad`/s²" in text
    assert "0.000399999" not in text and " m/s" not in text
    emps = SimpleNamespace(sample_rate=1000.016000256, gains=SimpleNamespace(Ts=1 / 1000.016000256), units={"u": "N"})
    text = " ".join(readme("arc", emps, SimpleNamespace(base="arc_axis"), True).split())
    assert "Sample rate: 1000.016 Hz (period 0.000999984 s;" in text and "positions in `m`" in text


def _score(e_rms):
    return SimpleNamespace(e_rms=e_rms, diverged=False)


@pytest.mark.parametrize("gate_um", [3.0, 2.0, 0.3])  # above every point (the case), at the top one, below all
def test_the_monte_carlo_gate_line_is_inside_its_axes_with_a_margin(tmp_path, monkeypatch, gate_um):
    rng = np.random.default_rng(1)
    pid = rng.uniform(0.8e-6, 2e-6, 20)
    runs = [SimpleNamespace(name=f"mc/{i:03d}", tags=("monte_carlo",), pid=_score(p), arc=_score(0.6 * p))
            for i, p in enumerate(pid)]
    runs[0].arc.e_rms = 2e-6
    result = SimpleNamespace(runs=runs, n_monte_carlo=len(runs), units={"u": "V", "q": "m"},
                             verdict=SimpleNamespace(limits=SimpleNamespace(arc_vs_pid_e_rms=1.0, arc_vs_pid_slack=0.0,
                                                                            e_rms=gate_um * 1e-6)))
    seen = []
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: seen.append(fig))
    monte_carlo_figure(result, tmp_path / "monte_carlo.png")
    (ax,) = seen[0].axes
    lo, hi = ax.get_ylim()
    gate = [ln for ln in ax.get_lines() if ln.get_label().startswith("gate e_rms")]
    (y,) = {float(v) for v in gate[0].get_ydata()}
    assert y == pytest.approx(gate_um)
    # on the log axis, at least a factor 1.2 from either border
    assert lo * 1.2 < y < hi / 1.2, (lo, y, hi)


def _ident(steady_points):
    return SimpleNamespace(identification=SimpleNamespace(
        units={"u": "V", "q": "m"}, parameters={}, relative_error=0.1, condition_number=10.0,
        validation_relative_error=None, theta=None,
        extra={"source": {"path": "a.h5"}, "model": {"friction": "coulomb", "method": "dynamic",
                                                     "steady_points": steady_points}}))


def test_the_friction_curve_caption_mentions_legs_only_when_the_log_has_some():
    with_legs = "\n".join(identification_markdown(_ident(12), ["friction_curve.png"]))
    without = "\n".join(identification_markdown(_ident(0), ["friction_curve.png"]))
    assert "over the constant-velocity legs" in with_legs
    assert "over the constant-velocity legs" not in without and "no constant-velocity leg" in without


def test_the_summary_gives_every_column_its_unit():
    runs = [SimpleNamespace(name="case1/nominal", tags=("case1", "nominal"), arc=SimpleNamespace(
        diverged=False, e_M=2e-6, e_F=1e-6, e_rms=5e-7, c_u=0.3, u_peak=1.5), pid=SimpleNamespace(
        diverged=False, e_rms=9e-7))]
    result = SimpleNamespace(runs=runs, units={"u": "N", "q": "m"}, verdict=SimpleNamespace(failures=()))
    head, rows = summary_rows(result)
    assert head == ["scenario", "ARC e_M um", "ARC e_F um", "ARC e_rms um", "ARC c_u", "ARC peak|u| N",
                    "PID e_rms um", "gate"]
    result.units = {"u": "Nm", "q": "rad"}
    assert summary_rows(result)[0][5] == "ARC peak|u| Nm" and summary_rows(result)[0][1] == "ARC e_M urad"


def test_the_progress_bar_shows_an_eta():
    buf = io.StringIO()
    with StageProgress(Console(file=buf, width=120, force_terminal=False)) as bar:
        for done in (1, 2, 3):
            bar.update("tuning", done, 10)
    assert "eta" in buf.getvalue()
