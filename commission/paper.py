"""Reproduction of Table 1 of Xu & Yao (2001) on the agreed reference plant (CONTRACT sec. 5).

Scenarios (2.5 kHz, zero-order hold, 1 um encoder, 10 plant sub-steps):

* ``set1``  -- Case 1 sinusoid ``0.05 sin(4 t)`` through filter (58), 10 s, M = 0.027;
* ``set2``  -- the same with the 9.1 kg payload, M = 0.1;
* ``set3``  -- Set 1 plus a +0.5 V input step disturbance on 2.2 s <= t < 7.2 s;
* ``case2`` -- Case 2 back-and-forth trapezoidal moves, 8 s, M = 0.027.

Controllers: the paper's PID (57) and the ARC with
``paper_gains_implementable()``.  Indexes use the measured (encoder) error.
The paper publishes numbers for Sets 1-3 only (:data:`PAPER_TABLE1`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from commission.artifacts import Estimate, Identification, ThetaBox
from commission.controllers.arc import arc_pack, paper_gains_implementable
from commission.controllers.metrics import INDEX_NAMES, INDEX_TABLE, Indexes, IndexRow
from commission.controllers.pid import PidGains, pid_pack, pid_place_poles
from commission.controllers.plant import plant_vector
from commission.controllers.simulate import KIND_ARC, KIND_PID, simulate, step_disturbance
from commission.controllers.trajectory import Trajectory, back_and_forth, sinusoid

TS = 1.0 / 2500.0  # s
SUBSTEPS = 10
QUANT = 1e-6  # m
SCENARIOS = ("set1", "set2", "set3", "case2")
CONTROLLERS = ("PID", "ARC")

#: Table 1 of the paper: errors in um, inputs in V (Sets 1-3; Case 2 has no table).
PAPER_TABLE1: dict[str, dict[str, dict[str, float]]] = {
    "set1": {"PID": {"e_M": 51.2, "e_F": 15.1, "e_rms": 2.99, "u_rms": 0.19, "du_rms": 0.05, "c_u": 0.28},
             "ARC": {"e_M": 14.4, "e_F": 6.88, "e_rms": 1.88, "u_rms": 0.20, "du_rms": 0.06, "c_u": 0.32}},
    "set2": {"PID": {"e_M": 156.0, "e_F": 21.2, "e_rms": 8.04, "u_rms": 0.21, "du_rms": 0.06, "c_u": 0.28},
             "ARC": {"e_M": 113.0, "e_F": 6.71, "e_rms": 4.32, "u_rms": 0.21, "du_rms": 0.06, "c_u": 0.30}},
    "set3": {"PID": {"e_M": 85.8, "e_F": 16.1, "e_rms": 4.35, "u_rms": 0.40, "du_rms": 0.04, "c_u": 0.11},
             "ARC": {"e_M": 55.9, "e_F": 6.30, "e_rms": 3.26, "u_rms": 0.42, "du_rms": 0.08, "c_u": 0.19}},
}


#: The rows of Table 1: the six indexes of :data:`commission.controllers.metrics.INDEX_TABLE`
#: (errors in um, inputs in V, the reference plant's units).
_ROWS = INDEX_TABLE[:len(INDEX_NAMES)]


def _grid_fmt(row: IndexRow) -> str:
    """An input is printed with two decimals, as the published table prints it."""
    return "{:.2f}" if row.unit == "u" else row.fmt


def reference_plant(M: float = 0.027, **dynamics: float) -> np.ndarray:
    """The CONTRACT sec. 5 stand-in plant with mass ``M`` (V s^2/m).

    B = 0.273 V s/m; Stribeck fc = 0.10 V, fs = 0.12 V, vs = 0.01 m/s, xi = 2;
    ripple 0.01 V sin(2 pi q / 0.03 m); no offset.  ``dynamics``: a structural
    mode or input delay (keywords of :func:`plant_vector`); rigid by default, as in the contract.
    """
    return plant_vector(M=M, B=0.273, fc=0.10, fs=0.12, vs=0.01, xi=2.0, offset=0.0,
                        ripple_amp=0.01, ripple_pitch=0.03, **dynamics)  # type: ignore[arg-type]


def reference_identification(*, delta_d: float = 0.5 / 0.027, **extra: object) -> Identification:
    """The reference plant as an exact identification (not fitted), with the paper's box (53).

    Parameters
    ----------
    delta_d : float
        Bound on |d~|, m/s^2 (default: Set 3's 0.5 V step over M = 0.027).
    **extra
        Additional, non-contract ident.json fields (e.g. ``source``).
    """
    return Identification(
        units={"u": "V", "q": "m"},
        parameters={k: Estimate(v, 0.0) for k, v in
                    dict(M=0.027, B=0.273, fc=0.10, fs=0.12, vs=0.01, xi=2.0, offset=0.0).items()},
        relative_error=0.0, condition_number=1.0, validation_relative_error=None,
        theta=ThetaBox((37.0, 10.1, 0.0), (8.3, 2.4, -50.0), (50.0, 17.5, 50.0)),
        delta_d=delta_d, fric_level=0.1, fric_slope=900.0, extra=extra)


@dataclass(frozen=True)
class Scenario:
    """One reference-plant experiment.

    Attributes
    ----------
    name : str
    plant_p : ndarray, shape (NP,)
        Plant vector.
    traj : Trajectory
        Desired motion at the controller rate.
    disturbance : ndarray or None
        Input disturbance per sample, V.
    y0 : float
        Initial position, m.
    """

    name: str
    plant_p: np.ndarray
    traj: Trajectory
    disturbance: np.ndarray | None
    y0: float = 0.0


def scenario(name: str, Ts: float = TS) -> Scenario:
    """Build scenario ``name`` (one of :data:`SCENARIOS`) at sample period ``Ts`` (s)."""
    if name not in SCENARIOS:
        raise ValueError(f"scenario: unknown {name!r}; expected one of {', '.join(SCENARIOS)}")
    if name == "case2":
        return Scenario(name, reference_plant(0.027), back_and_forth(8.0, Ts), None)
    traj = sinusoid(10.0, Ts, amplitude=0.05, omega=4.0, beta1=100.0, beta2=2500.0, y0=0.0)
    if name == "set2":
        return Scenario(name, reference_plant(0.1), traj, None)
    dist = step_disturbance(traj.t, [(2.2, 7.2, 0.5)]) if name == "set3" else None
    return Scenario(name, reference_plant(0.027), traj, dist)


def paper_pid_gains(Ts: float = TS) -> PidGains:
    """The PID of (57): M_hat 0.05, B_hat 0.24, (0.2/pi) atan(900 v), poles at -300 for M = 0.02."""
    Kp, Ki, Kd = pid_place_poles(0.02, -300.0)
    return PidGains(Ts=Ts, M_hat=0.05, B_hat=0.24, Kp=Kp, Ki=Ki, Kd=Kd,
                    fric_level=0.1, fric_slope=900.0)


def paper_controller(controller: str, Ts: float = TS) -> tuple[int, np.ndarray]:
    """``(kind, packed parameters)`` of the paper's ``"PID"`` or ``"ARC"``."""
    if controller == "PID":
        return KIND_PID, pid_pack(paper_pid_gains(Ts))
    if controller == "ARC":
        return KIND_ARC, arc_pack(paper_gains_implementable(Ts))
    raise ValueError(f"controller: unknown {controller!r}; expected PID or ARC")


@dataclass(frozen=True)
class TableCell:
    """One (scenario, controller) run: indexes in SI units, or None if it diverged."""

    scenario: str
    controller: str
    indexes: Indexes | None
    diverged: bool

    def as_json(self) -> dict[str, float | bool | None]:
        """Indexes in the table's units (errors um, inputs V) plus ``diverged``."""
        out: dict[str, float | bool | None] = {"diverged": self.diverged}
        for k in INDEX_NAMES:
            out[k] = None
        if self.indexes is not None:
            for row in _ROWS:
                v = getattr(self.indexes, row.name) * row.scale
                out[row.name] = v if math.isfinite(v) else None
        return out


@dataclass(frozen=True)
class PaperTable:
    """Results of :func:`run_paper_table`, keyed ``cells[scenario][controller]``."""

    cells: dict[str, dict[str, TableCell]]

    def as_json(self) -> dict[str, dict[str, dict[str, float | bool | None]]]:
        """``{scenario: {controller: {e_M, e_F, e_rms (um), u_rms, du_rms (V), c_u, diverged}}}``."""
        return {s: {c: cell.as_json() for c, cell in row.items()} for s, row in self.cells.items()}


def run_paper_table(*, scenarios: tuple[str, ...] = SCENARIOS, controllers: tuple[str, ...] = CONTROLLERS,
                    substeps: int = SUBSTEPS, quant: float = QUANT, Ts: float = TS,
                    pid: PidGains | None = None) -> PaperTable:
    """Simulate every (scenario, controller) pair on the reference plant.

    Parameters
    ----------
    scenarios, controllers : tuple of str
        Subsets of :data:`SCENARIOS` and :data:`CONTROLLERS`.
    substeps : int
        Plant sub-steps per sample.
    quant : float
        Encoder resolution, m.
    Ts : float
        Sample period, s.
    pid : PidGains, optional
        Replace the paper's PID gains (e.g. the paper's -320 rad/s design).

    A diverged run becomes a cell with ``indexes=None, diverged=True``.
    """
    for c in controllers:
        if c not in CONTROLLERS:
            raise ValueError(f"controller: unknown {c!r}; expected PID or ARC")
    cells: dict[str, dict[str, TableCell]] = {}
    for name in scenarios:
        sc = scenario(name, Ts)
        cells[name] = {}
        for ctrl in controllers:
            if ctrl == "PID" and pid is not None:
                kind, p = KIND_PID, pid_pack(pid)
            else:
                kind, p = paper_controller(ctrl, Ts)
            r = simulate(sc.plant_p, kind, p, sc.traj, substeps=substeps, quant=quant,
                         disturbance=sc.disturbance, y0=sc.y0)
            cells[name][ctrl] = TableCell(name, ctrl, r.indexes, r.diverged)
    return PaperTable(cells)


def _fmt_grid(title: str, values: dict[str, dict[str, dict[str, float | None]]],
              scenarios: tuple[str, ...], controllers: tuple[str, ...]) -> str:
    labels = {"set1": "Set 1", "set2": "Set 2", "set3": "Set 3", "case2": "Case 2"}
    w0, w = 15, 8
    head1 = f"{'Controller':<{w0}}" + "".join(f"{labels.get(s, s):^{w * len(controllers)}}" for s in scenarios)
    head2 = " " * w0 + "".join(f"{c:>{w}}" for _ in scenarios for c in controllers)
    lines = [title, head1, head2]
    for ix in _ROWS:
        fmt = _grid_fmt(ix)
        row = f"{ix.heading('um', 'V', ascii=True):<{w0}}"
        for s in scenarios:
            for c in controllers:
                v = values.get(s, {}).get(c, {}).get(ix.name)
                row += f"{(fmt.format(v) if v is not None else '-'):>{w}}"
        lines.append(row)
    return "\n".join(lines)


def format_table(table: PaperTable, *, with_paper: bool = True) -> str:
    """Text table in the layout of the paper's Table 1 (a diverged run shows ``-``).

    With ``with_paper``, the published Table 1 follows for comparison.
    """
    scen = tuple(table.cells)
    ctrls = tuple(next(iter(table.cells.values()))) if table.cells else CONTROLLERS
    out = _fmt_grid("Simulated (reference plant, CONTRACT sec. 5)", table.as_json(), scen, ctrls)
    failed = [f"{s}/{c}" for s, row in table.cells.items() for c, cell in row.items() if cell.diverged]
    if failed:
        out += "\nDIVERGED (failed): " + ", ".join(failed)
    if with_paper:
        out += "\n\n" + _fmt_grid("Paper, Table 1 (experiments)", PAPER_TABLE1,
                                  tuple(s for s in SCENARIOS if s in PAPER_TABLE1), CONTROLLERS)
    return out
