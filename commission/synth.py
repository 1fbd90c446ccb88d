"""Synthetic excitation logs of a linear-motor axis with known parameters.

A commissioning run, simulated: a closed-loop PID with a rough feedforward
tracks a reference made of

* a **friction ladder**: constant-velocity legs at speeds spaced geometrically
  from ``v_min`` to ``v_max``, each run forward and then back over the same
  stretch of travel (so that position-dependent force ripple and the offset
  cancel between the two directions), with short dwells in between; and
* a **multisine** position excitation about the middle of the travel
  (Schroeder phases, equal velocity amplitude per line) for the inertia, with
  many velocity reversals.

and, optionally, a **broadband injection**: a PRBS added to the command on two
slow constant-velocity legs (``ExcitationPlan.injection_s``), from which
:mod:`commission.identify.frf` measures the frequency response.

The plant is :func:`commission.controllers.plant.plant_step` (Stribeck
friction with a stiction switch model, offset and ripple; optionally a
structural mode and an input delay) under zero-order hold with sub-steps; the encoder quantizes ``round(x / lsb) * lsb`` after optional
Gaussian position noise.  :func:`write_log_h5` and :func:`write_log_csv` write
the result in the excitation-log format of CONTRACT section 1.

Everything random comes from the ``numpy.random.Generator`` passed in.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np
from numba import njit

from commission.controllers.plant import NX, P_DELAY, plant_output, plant_start, plant_vector
from commission.controllers.simulate import _segment as hold_segment
from commission.errors import DataError, UsageError
from commission.jsonio import write_atomic

#: Channel names of an excitation log, in file order (CONTRACT section 1).
LOG_CHANNELS = ("t", "q", "u", "q_ref")
Q_UNITS = ("m", "mm", "um")
U_UNITS = ("V", "N", "A")


def _check_finite(owner: str, **values: float) -> None:
    for name, val in values.items():
        if not math.isfinite(val):
            raise ValueError(f"{owner}: {name} must be finite, got {val!r}")


# --------------------------------------------------------------------------- truth


@dataclass(frozen=True)
class AxisTruth:
    """Known parameters of a simulated axis (the "truth" of a synthetic log).

    Model (CONTRACT section 2 convention)::

        M qdd = u - offset - B qd - Ff(qd) - ripple_amp sin(2 pi q / ripple_pitch)
        Ff(v) = [fc + (fs - fc) exp(-|v/vs|^xi)] sign(v)

    Parameters
    ----------
    M : float
        Mass, u-unit s^2/m (V s^2/m for ``u_unit='V'``).
    B : float
        Viscous coefficient, u-unit s/m.
    fc : float
        Coulomb friction level, u-unit.
    fs : float
        Static friction (stiction) level, u-unit.
    vs : float
        Stribeck velocity, m/s.
    xi : float
        Stribeck exponent, dimensionless.
    offset : float
        Constant force offset, u-unit (``u_equiv = ... + offset``).
    ripple_amp : float
        Force-ripple amplitude, u-unit.
    ripple_pitch : float
        Force-ripple pitch, m.
    lsb : float
        Encoder resolution (quantization step), m.
    sample_rate : float
        Controller and logging rate, Hz.
    u_unit : str
        Unit of the command: ``'V'``, ``'N'`` or ``'A'``.
    noise_std : float
        Standard deviation of Gaussian position noise added before
        quantization, m (0: quantization only).
    u_max : float
        Command rail: the controller output is clipped to ``[-u_max, u_max]``, u-unit.
    mode_hz : float
        Resonance of a structural mode, Hz (0: rigid body; see
        :mod:`commission.controllers.plant` for the two-mass model).
    mode_damping : float
        Damping ratio of the mode, in [0, 1).
    mode_ratio : float
        Load fraction ``m2 / M`` of the moving mass, in (0, 1).
    mode_load_side : bool
        The encoder reads the load (True) or the motor side (False).
    delay : float
        Input delay between the command the controller issues and the force, s
        (fractional samples allowed).
    mode2_hz : float
        Resonance of a second structural mode, Hz (0: none; only beside the first: a second
        load on the motor side, :mod:`commission.controllers.plant`).
    mode2_damping : float
        Damping ratio of the second mode, in [0, 1).
    mode2_ratio : float
        Load fraction of the second mode, in (0, 1).
    mode2_load_side : bool
        The encoder reads the second mode's load (True: this wins over ``mode_load_side``).
    input_gain : float
        Force per command unit, N/u-unit (1 for ``u_unit='N'``; a drive's amplifier and force
        constant for ``'V'``): the moving mass is ``M * input_gain`` kg.  Information only: the
        plant is written in command units.
    """

    M: float
    B: float
    fc: float
    fs: float
    vs: float
    xi: float
    offset: float = 0.0
    ripple_amp: float = 0.0
    ripple_pitch: float = 0.03
    lsb: float = 1e-6
    sample_rate: float = 2500.0
    u_unit: str = "V"
    noise_std: float = 0.0
    u_max: float = 10.0
    mode_hz: float = 0.0
    mode_damping: float = 0.02
    mode_ratio: float = 0.5
    mode_load_side: bool = False
    delay: float = 0.0
    mode2_hz: float = 0.0
    mode2_damping: float = 0.02
    mode2_ratio: float = 0.2
    mode2_load_side: bool = False
    input_gain: float = 1.0

    def __post_init__(self) -> None:
        # JSON carries the encoder side as 0/1 (to_dict): store a bool either way.
        object.__setattr__(self, "mode_load_side", bool(self.mode_load_side))
        object.__setattr__(self, "mode2_load_side", bool(self.mode2_load_side))
        nums = {k: v for k, v in asdict(self).items() if k != "u_unit"}
        _check_finite("AxisTruth", **nums)
        bad = [
            f"{name}={nums[name]!r} (need {rule})"
            for name, ok, rule in (
                ("M", self.M > 0, "> 0"),
                ("B", self.B >= 0, ">= 0"),
                ("fc", self.fc >= 0, ">= 0"),
                ("fs", self.fs >= 0, ">= 0"),
                ("vs", self.vs > 0, "> 0"),
                ("xi", self.xi > 0, "> 0"),
                ("ripple_amp", self.ripple_amp >= 0, ">= 0"),
                ("ripple_pitch", self.ripple_pitch > 0, "> 0"),
                ("lsb", self.lsb > 0, "> 0"),
                ("sample_rate", self.sample_rate > 0, "> 0"),
                ("noise_std", self.noise_std >= 0, ">= 0"),
                ("u_max", self.u_max > 0, "> 0"),
                ("mode_hz", self.mode_hz >= 0, ">= 0"),
                ("mode_damping", 0 <= self.mode_damping < 1, "in [0, 1)"),
                ("mode_ratio", 0 < self.mode_ratio < 1, "in (0, 1)"),
                ("delay", self.delay >= 0, ">= 0"),
                ("mode2_hz", self.mode2_hz >= 0, ">= 0"),
                ("mode2_damping", 0 <= self.mode2_damping < 1, "in [0, 1)"),
                ("mode2_ratio", 0 < self.mode2_ratio < 1, "in (0, 1)"),
                ("input_gain", self.input_gain > 0, "> 0"),
            )
            if not ok
        ]
        if self.mode2_hz > 0 and not (self.mode_hz > 0 and self.mode_ratio + self.mode2_ratio < 1):
            bad.append(f"mode2_hz={self.mode2_hz!r} (needs mode_hz > 0 and mode_ratio + mode2_ratio < 1)")
        if bad:
            raise ValueError("AxisTruth: " + "; ".join(bad))
        if self.u_unit not in U_UNITS:
            raise ValueError(f"AxisTruth: u_unit={self.u_unit!r} (need one of {', '.join(U_UNITS)})")

    @property
    def period(self) -> float:
        """Sample period, s."""
        return 1.0 / self.sample_rate

    @property
    def n_modes(self) -> int:
        """Number of structural modes (0, 1 or 2)."""
        return int(self.mode_hz > 0) + int(self.mode2_hz > 0)

    @property
    def mass_kg(self) -> float:
        """Moving mass, kg (``M * input_gain``)."""
        return self.M * self.input_gain

    def plant(self) -> np.ndarray:
        """Plant vector for :mod:`commission.controllers.plant` (float64[NP]), second mode included."""
        return plant_vector(self.M, self.B, self.fc, self.fs, self.vs, self.xi,
                            self.offset, self.ripple_amp, self.ripple_pitch, mode_hz=self.mode_hz,
                            mode_damping=self.mode_damping, mode_ratio=self.mode_ratio,
                            mode_load_side=self.mode_load_side, delay=self.delay, mode2_hz=self.mode2_hz,
                            mode2_damping=self.mode2_damping, mode2_ratio=self.mode2_ratio,
                            mode2_load_side=self.mode2_load_side)

    def units(self) -> dict[str, str]:
        """Unit of every numeric field (``u`` stands for :attr:`u_unit`)."""
        u = self.u_unit
        return {
            "M": f"{u} s^2/m", "B": f"{u} s/m", "fc": u, "fs": u, "vs": "m/s", "xi": "1",
            "offset": u, "ripple_amp": u, "ripple_pitch": "m", "lsb": "m",
            "sample_rate": "Hz", "noise_std": "m", "u_max": u,
            "mode_hz": "Hz", "mode_damping": "1", "mode_ratio": "1", "mode_load_side": "1", "delay": "s",
            "mode2_hz": "Hz", "mode2_damping": "1", "mode2_ratio": "1", "mode2_load_side": "1",
            "input_gain": f"N/{u}",
        }

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form: ``{"u_unit": ..., "parameters": {name: {"value", "unit"}}}``.

        The second mode's fields are written only with a second mode, and ``input_gain`` only
        when it is not 1, so the truth of a one-mode axis reads as it did before they existed
        (``sample_data/truth.json``); :meth:`from_dict` defaults what is absent.
        """
        units = self.units()
        skip = set()
        if self.mode2_hz == 0:
            skip |= {"mode2_hz", "mode2_damping", "mode2_ratio", "mode2_load_side"}
        if self.input_gain == 1.0:
            skip.add("input_gain")
        return {
            "u_unit": self.u_unit,
            "parameters": {k: {"value": float(getattr(self, k)), "unit": units[k]} for k in units if k not in skip},
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "AxisTruth":
        """Inverse of :meth:`to_dict` (units are implied by ``u_unit``)."""
        params = {k: float(v["value"]) for k, v in d["parameters"].items()}
        return cls(u_unit=str(d["u_unit"]), **params)


def rigid_random_axis(rng: np.random.Generator, sample_rate: float | None = None) -> AxisTruth:
    """Draw a rigid linear-motor axis (V units): the random axes of issues 4-20.

    Kept because tests pin the behaviour of some of its seeds
    (``tests/test_tune_random_axes.py``: ``write_random_axis_log(seed, path, rigid=True)``);
    :func:`random_axis` draws the wider distribution of real machines.

    Ranges (log-uniform where marked): M 0.01-0.2 V s^2/m (log), B = M * 3-30 1/s,
    fc = M * 1-6 m/s^2 (log), fs = fc * 1.1-1.6, vs 3-30 mm/s (log), xi 1-2.5,
    offset +-0.3 fc, ripple 0-10 % of fc with pitch 20-60 mm, encoder LSB
    0.05-1 um (log), noise 0-0.3 LSB, sample rate one of 1, 2, 2.5, 4, 5 kHz,
    rail 10 V.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of every random draw.
    sample_rate : float, optional
        Fix the sample rate (Hz) instead of drawing it.

    Returns
    -------
    AxisTruth
    """

    def logu(lo: float, hi: float) -> float:
        return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))

    M = logu(0.01, 0.2)
    B = M * float(rng.uniform(3.0, 30.0))
    # Friction scales with the moving mass (bearing preload, cable chain):
    # Coulomb deceleration fc / M of 1-6 m/s^2, as on real stages (paper: 3.7).
    fc = M * logu(1.0, 6.0)
    fs = fc * float(rng.uniform(1.1, 1.6))
    vs = logu(0.003, 0.03)
    xi = float(rng.uniform(1.0, 2.5))
    offset = fc * float(rng.uniform(-0.3, 0.3))
    ripple_amp = fc * float(rng.uniform(0.0, 0.1))
    ripple_pitch = float(rng.uniform(0.02, 0.06))
    lsb = logu(0.05e-6, 1e-6)
    noise_std = lsb * float(rng.uniform(0.0, 0.3))
    fs_choice = float(rng.choice(np.array([1000.0, 2000.0, 2500.0, 4000.0, 5000.0])))
    return AxisTruth(M=M, B=B, fc=fc, fs=fs, vs=vs, xi=xi, offset=offset,
                     ripple_amp=ripple_amp, ripple_pitch=ripple_pitch, lsb=lsb,
                     sample_rate=fs_choice if sample_rate is None else float(sample_rate),
                     noise_std=noise_std, u_max=10.0)


#: Controller rates :func:`random_axis` draws from, Hz (1-20 kHz, as drives offer them).
RANDOM_RATES = (1000.0, 2000.0, 2500.0, 4000.0, 5000.0, 8000.0, 10000.0, 16000.0, 20000.0)
#: Range of the moving mass, kg (three decades: a lens stage to a gantry).
RANDOM_MASS_KG = (0.3, 300.0)
#: Range of the structural modes' frequencies, Hz.
RANDOM_MODE_HZ = (200.0, 2000.0)
#: Peak acceleration the drive's rail gives the bare axis, m/s^2.
RANDOM_PEAK_ACCEL = (20.0, 200.0)
#: Probabilities of 0, 1 and 2 structural modes.
RANDOM_MODE_COUNT_P = (0.2, 0.45, 0.35)


def random_axis(rng: np.random.Generator, sample_rate: float | None = None) -> AxisTruth:
    """Draw a linear-motor axis from the spread of real machines (issue 30).

    Ranges (log-uniform where marked):

    * moving mass 0.3-300 kg (log); the drive's peak acceleration at the rail 20-200 m/s^2
      (log);
    * command in V (probability 0.6: a +-10 V amplifier of gain ``input_gain`` = peak force
      / 10 V, N/V) or in N (a force command, ``input_gain`` 1, rail = peak force); every
      force-like field is in the command's unit (``M`` = mass / input_gain);
    * B = M * 3-30 1/s, fc = M * 1-6 m/s^2 (log), fs = fc * 1.1-1.6, vs 3-30 mm/s (log),
      xi 1-2.5, offset +-0.3 fc, ripple 0-10 % of fc with pitch 20-60 mm (as
      :func:`rigid_random_axis`);
    * encoder LSB 0.05-1 um (log), position noise 0-1 LSB rms;
    * rate one of :data:`RANDOM_RATES` (1-20 kHz); input delay 0-2 samples (uniform,
      fractional);
    * 0, 1 or 2 structural modes (probabilities :data:`RANDOM_MODE_COUNT_P`).  The first
      mode's frequency falls with the mass -- ``2000 Hz (0.3 kg / m)^(1/3)``, so 2 kHz at
      0.3 kg and 200 Hz at 300 kg, as a stiffness that grows slower than the mass -- times
      a log-uniform 0.67-1.5 scatter, clipped to 200-2000 Hz; the second is 1.4-3x the
      first (log), at most 2 kHz (dropped when there is no room).  Damping 0.01-0.08 (log);
      load fraction 0.1-0.5 (first), 0.05-0.3 (second).  The encoder reads the motor side
      (collocated) or a load (non-collocated): with one mode each with probability 1/2;
      with two, the second load 1/2, the first load 1/4, the motor 1/4.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of every random draw (a fixed number of draws per axis).
    sample_rate : float, optional
        Fix the sample rate (Hz) instead of drawing it (the delay is then in its samples).

    Returns
    -------
    AxisTruth
    """

    def logu(lo: float, hi: float) -> float:
        return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))

    m_kg = logu(*RANDOM_MASS_KG)
    a_peak = logu(*RANDOM_PEAK_ACCEL)
    in_volts = bool(rng.uniform() < 0.6)
    f_peak = m_kg * a_peak
    gain = f_peak / 10.0 if in_volts else 1.0
    u_max = 10.0 if in_volts else f_peak
    M = m_kg / gain
    B = M * float(rng.uniform(3.0, 30.0))
    fc = M * logu(1.0, 6.0)
    fs = fc * float(rng.uniform(1.1, 1.6))
    vs = logu(0.003, 0.03)
    xi = float(rng.uniform(1.0, 2.5))
    offset = fc * float(rng.uniform(-0.3, 0.3))
    ripple_amp = fc * float(rng.uniform(0.0, 0.1))
    ripple_pitch = float(rng.uniform(0.02, 0.06))
    lsb = logu(0.05e-6, 1e-6)
    noise_std = lsb * float(rng.uniform(0.0, 1.0))
    rate = float(rng.choice(np.array(RANDOM_RATES)))
    rate = rate if sample_rate is None else float(sample_rate)
    delay = float(rng.uniform(0.0, 2.0)) / rate
    n_modes = int(rng.choice(3, p=np.array(RANDOM_MODE_COUNT_P)))
    lo, hi = RANDOM_MODE_HZ
    # Every draw is made whatever n_modes is, so one field's distribution does not shift the others'.
    f1 = 2000.0 * (RANDOM_MASS_KG[0] / m_kg) ** (1.0 / 3.0) * logu(1.0 / 1.5, 1.5)
    f1 = min(max(f1, lo), hi)
    f2 = f1 * logu(1.4, 3.0)
    f2 = min(f2, hi) if f1 * 1.4 <= hi else 0.0
    z1, z2 = logu(0.01, 0.08), logu(0.01, 0.08)
    r1, r2 = float(rng.uniform(0.1, 0.5)), float(rng.uniform(0.05, 0.3))
    load1, load2 = bool(rng.uniform() < 0.5), bool(rng.uniform() < 0.5)
    modes = dict(mode_hz=f1 if n_modes >= 1 else 0.0, mode_damping=z1, mode_ratio=r1, mode_load_side=load1,
                 mode2_hz=f2 if n_modes == 2 else 0.0, mode2_damping=z2, mode2_ratio=r2, mode2_load_side=load2)
    return AxisTruth(M=M, B=B, fc=fc, fs=fs, vs=vs, xi=xi, offset=offset, ripple_amp=ripple_amp,
                     ripple_pitch=ripple_pitch, lsb=lsb, sample_rate=rate, u_unit="V" if in_volts else "N",
                     noise_std=noise_std, u_max=u_max, delay=delay, input_gain=gain, **modes)


def excitation_plan(truth: AxisTruth) -> ExcitationPlan:
    """The commissioning run an engineer would record on ``truth``: within its force and stability.

    :class:`ExcitationPlan`'s defaults, with

    * the accelerations (multisine, ladder, moves) at most 30 % of the rail's peak
      acceleration ``u_max / M`` and the fastest ladder speed such that viscous friction plus
      stiction take at most 40 % of the rail, so the feedforward, the friction and the PID's
      correction stay inside it;
    * the commissioning PID's bandwidth at most 40 Hz and a fortieth of the rate, lowered by
      steps of 0.85 until its loop on the true plant (modes and delay, linearised by
      :func:`commission.controllers.margins.loop_margins`) keeps 6 dB and 30 deg, as an
      engineer lowers the gain of a loop that rings (a loop that excites its own mode would
      not be logged); at most 40 steps.  The integral corner stays at most a tenth of the
      bandwidth.

    Parameters
    ----------
    truth : AxisTruth

    Returns
    -------
    ExcitationPlan
    """
    base = ExcitationPlan()
    a_rail = truth.u_max / truth.M
    a_cap = 0.3 * a_rail
    v_cap = (0.4 * truth.u_max - truth.fs) / max(truth.B, 1e-12)
    v_max = float(min(base.v_max, max(v_cap, 4.0 * base.v_min)))
    bw = min(base.bandwidth_hz, truth.sample_rate / 40.0)
    if truth.n_modes or truth.delay > 0:
        bw = _quiet_bandwidth(truth, base, bw)
    return dataclasses.replace(_with_bandwidth(base, bw), ms_accel=min(base.ms_accel, a_cap),
                               ladder_accel=min(base.ladder_accel, a_cap), move_accel=min(base.move_accel, a_cap),
                               v_max=v_max)


def _with_bandwidth(plan: ExcitationPlan, bw: float) -> ExcitationPlan:
    """``plan`` with the PID's bandwidth ``bw`` (Hz) and its integral corner at most a tenth of it."""
    return dataclasses.replace(plan, bandwidth_hz=bw, integral_hz=min(plan.integral_hz, bw / 10.0))


def _quiet_bandwidth(truth: AxisTruth, plan: ExcitationPlan, bw: float) -> float:
    """The largest ``bw * 0.85**k`` (k = 0 .. 40) whose commissioning PID keeps 6 dB and 30 deg, Hz."""
    from commission.controllers.linear import sampled_plant
    from commission.controllers.margins import linearize_pid, loop_margins
    from commission.controllers.pid import PidGains, pid_pack

    plant = sampled_plant(truth.plant(), truth.period)
    for _ in range(40):
        kp, kd, ki = loop_gains(truth, _with_bandwidth(plan, bw))
        g = PidGains(Ts=truth.period, M_hat=0.0, B_hat=0.0, Kp=kp, Ki=ki, Kd=kd)
        m = loop_margins(linearize_pid(pid_pack(g)), plant)
        if m.stable and m.gain_margin_db >= 6.0 and m.phase_margin_deg >= 30.0:
            break
        bw *= 0.85
    return bw


#: Most samples an excite-planned random-axis log may have; above it the plan is shortened
#: with :data:`SHORT_PLAN` (identify on a long high-rate log is slow).
EXCITE_MAX_SAMPLES = 600_000
#: ``[plan]`` options of the shortened plan (fewer ladder speeds and moves, shorter legs and injection).
SHORT_PLAN = {"n_speeds": 5, "leg_time": 0.5, "moves": 4, "injection_s": 4.0}
#: Travel the random axes' limits.toml states, m (the legacy run's stroke, ExcitationPlan.travel).
RANDOM_TRAVEL = 0.3
#: Seeded factor range of the rough mass in the random axes' limits.toml.
RANDOM_MASS_GUESS = (0.7, 1.4)
#: Fraction of the rail's peak acceleration ``u_max / M`` stated as ``[limits] a_max``.
RANDOM_A_MAX_FRACTION = 0.5
LOG_KINDS = ("excite", "legacy")


@dataclass(frozen=True)
class RandomAxisLog:
    """What :func:`record_random_axis_log` wrote: the truth, which log, and why.

    Attributes
    ----------
    truth : AxisTruth
        The axis (not shown to the pipeline).
    log : str
        ``"excite"`` (the plan of ``commission excite`` played on the true axis) or
        ``"legacy"`` (the commissioning run of :func:`excitation_plan`, no broadband injection).
    requested : str
        The log asked for.
    limits : dict or None
        The limits.toml (as a mapping) an engineer of the axis would write; None for the legacy log.
    duration_s : float
        Length of the recorded run, s.
    samples : int
        Rows of the log.
    note : str
        Why the log is the legacy one when the excite log was asked for (the refusal), or
        that the plan was shortened; empty otherwise.
    """

    truth: AxisTruth
    log: str
    requested: str
    limits: Mapping[str, Any] | None
    duration_s: float
    samples: int
    note: str = ""


def random_axis_limits(truth: AxisTruth, rng: np.random.Generator) -> dict[str, Any]:
    """The limits.toml (as a mapping) an engineer of the random axis ``truth`` would write.

    * ``[limits]``: ``travel`` :data:`RANDOM_TRAVEL` (the legacy run's stroke), ``v_max`` the
      legacy run's fastest ladder speed (which keeps viscous friction and stiction within 40 %
      of the rail), ``a_max`` :data:`RANDOM_A_MAX_FRACTION` of the rail's peak acceleration
      ``u_max / M``, ``u_max`` the rail;
    * ``[drive]``: ``sample_rate`` the axis's, ``bandwidth_hz`` the holding loop that the
      legacy generator finds quiet on the true axis (:func:`excitation_plan`: at most 40 Hz and
      rate/40, lowered until its loop keeps 6 dB and 30 deg with the modes and the delay), as a
      drive already holding the axis;
    * ``[axis]``: ``mass`` the truth's M (command unit s^2/m) times a factor drawn from ``rng``
      in :data:`RANDOM_MASS_GUESS` (a rough guess), ``u_unit`` the command's, ``q_unit`` m.

    No friction is stated (an engineer rarely knows it); ``[plan]`` keeps excite's defaults.
    """
    legacy = excitation_plan(truth)
    a_rail = truth.u_max / truth.M
    return {
        "limits": {"travel": RANDOM_TRAVEL, "v_max": float(legacy.v_max),
                   "a_max": float(RANDOM_A_MAX_FRACTION * a_rail), "u_max": float(truth.u_max)},
        "drive": {"sample_rate": float(truth.sample_rate), "bandwidth_hz": float(legacy.bandwidth_hz)},
        "axis": {"mass": float(truth.M * rng.uniform(*RANDOM_MASS_GUESS)), "u_unit": truth.u_unit, "q_unit": "m"},
    }


def record_random_axis_log(seed: int, path: str | os.PathLike[str], *, log: str = "excite") -> RandomAxisLog:
    """Draw random axis ``seed`` and write its log (HDF5) as the tool tells users to record it.

    ``log="excite"`` (the recommended workflow): :func:`random_axis_limits` (mass factor from
    ``default_rng(seed + 2000)``), :func:`commission.excite.plan_run` on it, the plan played on
    the TRUE axis (modes, delay, noise, quantization, rail) by
    :func:`commission.excite.simulate_plan` with ``default_rng(seed + 1000)``.  A plan with
    more than :data:`EXCITE_MAX_SAMPLES` rows is planned again with :data:`SHORT_PLAN`'s
    ``[plan]`` options.  If ``excite`` refuses the limits (an exit-2 :class:`SpecError`),
    the legacy log is written and the record says so (``log="legacy"``, ``note`` = the refusal).

    ``log="legacy"``: the commissioning run of :func:`excitation_plan` (ladder, moves, a low
    multisine; no broadband injection), :func:`simulate_excitation` with
    ``default_rng(seed + 1000)``: the logs of the sweep before excite.

    Raises
    ------
    UsageError
        ``log`` is not one of :data:`LOG_KINDS`.
    """
    if log not in LOG_KINDS:
        raise UsageError(f"log: {log!r} is not one of {', '.join(LOG_KINDS)}")
    return record_axis_log(random_axis(np.random.default_rng(seed)), path, seed=seed, log=log)


def record_axis_log(truth: AxisTruth, path: str | os.PathLike[str], *, seed: int = 0,
                    log: str = "excite") -> RandomAxisLog:
    """Write the log of a given ``truth`` (HDF5) exactly as :func:`record_random_axis_log` records axis ``seed``.

    The same recipe (limits from ``default_rng(seed + 2000)``, the plan played with
    ``default_rng(seed + 1000)``, the shortened plan above :data:`EXCITE_MAX_SAMPLES`, the legacy
    fallback), for a named development axis built by hand rather than drawn.

    Raises
    ------
    UsageError
        ``log`` is not one of :data:`LOG_KINDS`.
    """
    if log not in LOG_KINDS:
        raise UsageError(f"log: {log!r} is not one of {', '.join(LOG_KINDS)}")
    note = ""
    if log == "excite":
        from commission.errors import SpecError
        from commission.excite import excite_spec_from_mapping, plan_run, simulate_plan

        limits = random_axis_limits(truth, np.random.default_rng(seed + 2000))
        try:
            plan = plan_run(excite_spec_from_mapping(limits, f"axis {seed} limits.toml"))
            if plan.t.size > EXCITE_MAX_SAMPLES:
                note = (f"plan of {plan.t.size} samples ({plan.duration:.1f} s) shortened with [plan] "
                        + ", ".join(f"{k} = {v:g}" for k, v in SHORT_PLAN.items()))
                limits = {**limits, "plan": dict(SHORT_PLAN)}
                plan = plan_run(excite_spec_from_mapping(limits, f"axis {seed} limits.toml"))
        except SpecError as exc:
            note = f"excite refused, legacy log written: {exc}"
        else:
            data = simulate_plan(plan, truth, np.random.default_rng(seed + 1000))
            write_log_h5(path, data, u_unit=truth.u_unit)
            return RandomAxisLog(truth, "excite", log, limits, plan.duration, int(plan.t.size), note)
    data = simulate_excitation(truth, excitation_plan(truth), np.random.default_rng(seed + 1000))
    write_log_h5(path, data, u_unit=truth.u_unit)
    n = int(data["t"].size)
    return RandomAxisLog(truth, "legacy", log, None, n / truth.sample_rate, n, note)


def write_random_axis_log(seed: int, path: str | os.PathLike[str], *, rigid: bool = False,
                          log: str = "excite") -> AxisTruth:
    """Draw random axis ``seed`` and write its log (HDF5) to ``path``; return its truth.

    The axis is ``random_axis(default_rng(seed))`` and its log that of
    :func:`record_random_axis_log` with ``log`` (``"excite"``: the plan of ``commission
    excite`` from the axis's limits, played on the true axis, falling back to the legacy run
    when excite refuses; ``"legacy"``: the commissioning run of :func:`excitation_plan`, no
    broadband injection), written in the axis's command unit.  With ``rigid=True`` it is
    ``rigid_random_axis(default_rng(seed))`` with the default :class:`ExcitationPlan`
    whatever ``log`` says: the axes of issues 4-20 that ``tests/test_tune_random_axes.py``
    pins.  This is the numbering of the random-axes tests and of
    ``benchmarks/sweep_random_axes.py`` ("axis 16" is seed 16).

    Returns
    -------
    AxisTruth
        The known truth (not used by the pipeline).
    """
    if rigid:
        truth = rigid_random_axis(np.random.default_rng(seed))
        write_log_h5(path, simulate_excitation(truth, ExcitationPlan(), np.random.default_rng(seed + 1000)),
                     u_unit=truth.u_unit)
        return truth
    return record_random_axis_log(seed, path, log=log).truth


# --------------------------------------------------------------------------- plan


@dataclass(frozen=True)
class Leg:
    """One constant-velocity leg of the friction ladder.

    Attributes
    ----------
    start, stop : float
        Time window of the constant-velocity part, s.
    velocity : float
        Reference velocity, m/s (signed).
    x_start : float
        Reference position at ``start``, m.
    """

    start: float
    stop: float
    velocity: float
    x_start: float


@dataclass(frozen=True)
class Reference:
    """A sampled reference trajectory and where its parts are.

    Attributes
    ----------
    t : ndarray
        Sample times ``k / sample_rate``, s.
    q, qd, qdd : ndarray
        Reference position (m), velocity (m/s), acceleration (m/s^2).
    legs : tuple of Leg
        The friction-ladder legs, in time order.
    multisine : tuple of float
        ``(start, stop)`` of the multisine segment, s.
    injection : tuple of (float, float)
        ``(start, stop)`` of each constant-velocity leg that carries the broadband
        injection, s (empty without one).
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    legs: tuple[Leg, ...]
    multisine: tuple[float, float]
    injection: tuple[tuple[float, float], ...] = ()


# A segment is (kind, t0, T, args); x0 is the position at t0.
_HOLD, _RAMP, _CRUISE, _MULTISINE = 0, 1, 2, 3


@dataclass(frozen=True)
class ExcitationPlan:
    """Design of a commissioning excitation run (reference and loop).

    The run is: dwell; friction ladder; move to the middle of the travel;
    multisine; move back to 0; dwell; and, with ``injection_s > 0``, a
    broadband injection: a leg forward and one back at ``injection_velocity``,
    each cruising ``injection_s / 2`` seconds with a PRBS added to the command
    (the way drive vendors' frequency-response tools record one: the axis
    moves slowly so that friction keeps one sign, and the feedback loop stays
    closed), then a dwell.  The travel used is ``[0, travel]``.

    Parameters
    ----------
    travel : float
        Usable stroke from the start position 0, m.
    v_min, v_max : float
        Slowest and fastest ladder speed, m/s.
    n_speeds : int
        Number of ladder speeds, spaced geometrically from ``v_min`` to ``v_max``.
    leg_travel : float
        Target travel of each constant-velocity leg, m (a few ripple pitches,
        so that fast legs average over ripple).  The leg time is
        ``clip(leg_travel / v, leg_min_time, leg_max_time)``.
    leg_min_time, leg_max_time : float
        Bounds of the constant-velocity time per leg, s.
    ladder_accel : float
        Peak acceleration of the ramps into and out of a leg, m/s^2.
    ramp_min_time : float
        Shortest ramp, s (slow legs ramp gently, not in one sample).
    dwell : float
        Standstill between legs and at both ends of the run, s.
    ms_freqs : tuple of float
        Multisine line frequencies, Hz.
    ms_duration : float
        Multisine segment length including its tapers, s.
    ms_taper : float
        Smooth fade in and out of the multisine, s.
    ms_accel : float
        Peak reference acceleration of the multisine, m/s^2.
    ms_amplitude : float
        Largest excursion of the multisine from the middle of the travel, m.
    move_accel : float
        Peak acceleration of the point-to-point moves, m/s^2.
    bandwidth_hz : float
        Design bandwidth of the PID, Hz (``Kp = M_g w^2``, ``Kd = 2 zeta M_g w``).
    damping : float
        Design damping ratio ``zeta`` of the PID.
    integral_hz : float
        Integral corner, Hz (``Ki = Kp * 2 pi integral_hz``; small, for offset and ripple).
    guess_factor : float
        The loop's rough knowledge of the axis: gains and the feedforward
        ``M_g qdd_ref + B_g qd_ref + fc_g (2/pi) atan(900 qd_ref)`` use
        ``guess_factor`` times the true M, B and fc (as a datasheet guess).
    substeps : int
        Plant sub-steps per sample (zero-order hold).
    injection_s : float
        Total cruise time carrying the broadband injection, s (0: none; the run
        and its log are then exactly those without the option).
    injection_accel : float
        Amplitude of the injected PRBS as an acceleration of the guessed mass,
        m/s^2: the command gets ``+-guess_factor M injection_accel`` (u-unit),
        one maximal-length-sequence bit per sample (flat spectrum up to Nyquist).
    injection_velocity : float
        Speed of the two injection legs, m/s.
    """

    travel: float = 0.3
    v_min: float = 0.001
    v_max: float = 0.25
    n_speeds: int = 9
    leg_travel: float = 0.06
    leg_min_time: float = 0.5
    leg_max_time: float = 1.5
    ladder_accel: float = 2.0
    ramp_min_time: float = 0.1
    dwell: float = 0.15
    ms_freqs: tuple[float, ...] = (1.0, 2.0, 3.0, 5.0, 8.0, 13.0, 20.0)
    ms_duration: float = 12.0
    ms_taper: float = 0.5
    ms_accel: float = 20.0
    ms_amplitude: float = 0.04
    move_accel: float = 4.0
    bandwidth_hz: float = 40.0
    damping: float = 0.8
    integral_hz: float = 4.0
    guess_factor: float = 0.8
    substeps: int = 10
    injection_s: float = 0.0
    injection_accel: float = 20.0
    injection_velocity: float = 0.1

    def __post_init__(self) -> None:
        nums = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "ms_freqs"}
        _check_finite("ExcitationPlan", **nums)
        for name in ("travel", "v_min", "leg_travel", "leg_min_time", "ladder_accel",
                     "ms_duration", "ms_accel", "ms_amplitude", "move_accel",
                     "bandwidth_hz", "damping", "guess_factor"):
            if not getattr(self, name) > 0:
                raise ValueError(f"ExcitationPlan: {name} must be > 0, got {getattr(self, name)!r}")
        for name in ("injection_accel", "injection_velocity"):
            if not getattr(self, name) > 0:
                raise ValueError(f"ExcitationPlan: {name} must be > 0, got {getattr(self, name)!r}")
        for name in ("ramp_min_time", "dwell", "integral_hz", "ms_taper", "injection_s"):
            if getattr(self, name) < 0:
                raise ValueError(f"ExcitationPlan: {name} must be >= 0, got {getattr(self, name)!r}")
        if self.v_max < self.v_min:
            raise ValueError(f"ExcitationPlan: v_max={self.v_max} < v_min={self.v_min}")
        if self.leg_max_time < self.leg_min_time:
            raise ValueError(f"ExcitationPlan: leg_max_time={self.leg_max_time} < leg_min_time={self.leg_min_time}")
        if int(self.n_speeds) != self.n_speeds or self.n_speeds < 1:
            raise ValueError(f"ExcitationPlan: n_speeds must be a positive integer, got {self.n_speeds!r}")
        if int(self.substeps) != self.substeps or self.substeps < 1:
            raise ValueError(f"ExcitationPlan: substeps must be a positive integer, got {self.substeps!r}")
        freqs = np.asarray(self.ms_freqs, dtype=float)
        if freqs.ndim != 1 or freqs.size == 0 or not np.all(np.isfinite(freqs)) or np.any(freqs <= 0):
            raise ValueError(f"ExcitationPlan: ms_freqs must be positive frequencies, got {self.ms_freqs!r}")
        if 2 * self.ms_taper > self.ms_duration:
            raise ValueError(f"ExcitationPlan: 2 * ms_taper = {2 * self.ms_taper} exceeds ms_duration = {self.ms_duration}")
        if 2 * self.ms_amplitude > self.travel:
            raise ValueError(f"ExcitationPlan: 2 * ms_amplitude = {2 * self.ms_amplitude} exceeds travel = {self.travel}")
        object.__setattr__(self, "ms_freqs", tuple(float(f) for f in freqs))
        # Derived, not fields: the piecewise reference (segments), legs, multisine window.
        object.__setattr__(self, "_segments", self._build_segments())

    # -- design ------------------------------------------------------------

    @property
    def speeds(self) -> np.ndarray:
        """Ladder speeds, m/s (geometric from ``v_min`` to ``v_max``)."""
        return np.geomspace(self.v_min, self.v_max, int(self.n_speeds))

    @property
    def duration(self) -> float:
        """Length of the whole run, s."""
        kind, t0, T, _ = self._segments[-1]
        return t0 + T

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form of the plan fields."""
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d["ms_freqs"] = list(self.ms_freqs)
        return d

    def _ramp_time(self, dv: float, accel: float) -> float:
        # Cosine velocity blend: peak acceleration = pi |dv| / (2 T).
        return max(self.ramp_min_time, math.pi * abs(dv) / (2.0 * accel))

    def _build_segments(self) -> tuple:
        segs: list[tuple] = []
        t = 0.0
        x = 0.0

        def add(kind: int, T: float, args: tuple) -> None:
            nonlocal t, x
            segs.append((kind, t, T, (x,) + args))
            if kind == _RAMP:
                v0, v1 = args
                x += v0 * T + (v1 - v0) * T / 2.0
            elif kind == _CRUISE:
                x += args[0] * T
            t += T

        def move(x_to: float) -> None:
            # Rest-to-rest cosine-velocity move of distance D: peak velocity D / Tr.
            D = x_to - x
            if D == 0.0:
                return
            Tr = max(self.ramp_min_time, math.sqrt(math.pi * abs(D) / (2.0 * self.move_accel)))
            vm = D / Tr
            if abs(vm) > self.v_max:  # cap the speed, cruise the rest
                vm = math.copysign(self.v_max, D)
                Tr = self._ramp_time(vm, self.move_accel)
                add(_RAMP, Tr, (0.0, vm))
                add(_CRUISE, (x_to - x - vm * Tr / 2.0) / vm, (vm,))
                add(_RAMP, Tr, (vm, 0.0))
            else:
                add(_RAMP, Tr, (0.0, vm))
                add(_RAMP, Tr, (vm, 0.0))

        legs: list[Leg] = []
        if self.dwell > 0:
            add(_HOLD, self.dwell, ())
        for v in self.speeds:
            v = float(v)
            Tr = self._ramp_time(v, self.ladder_accel)
            Tc = min(max(self.leg_travel / v, self.leg_min_time), self.leg_max_time)
            room = self.travel / v - Tr  # the two ramps cover v * Tr together
            if Tc > room:
                if room < self.leg_min_time:
                    raise ValueError(
                        f"ExcitationPlan: ladder speed {v:.6g} m/s needs "
                        f"{v * (Tr + self.leg_min_time):.6g} m of travel for a {self.leg_min_time} s leg; "
                        f"travel is {self.travel} m")
                Tc = room
            for s in (1.0, -1.0):
                add(_RAMP, Tr, (0.0, s * v))
                legs.append(Leg(start=t, stop=t + Tc, velocity=s * v, x_start=x))
                add(_CRUISE, Tc, (s * v,))
                add(_RAMP, Tr, (s * v, 0.0))
                if self.dwell > 0:
                    add(_HOLD, self.dwell, ())
            x = 0.0  # the pair returns exactly to 0; drop round-off
        centre = self.travel / 2.0
        move(centre)
        if self.dwell > 0:
            add(_HOLD, self.dwell, ())
        ms_start = t
        add(_MULTISINE, self.ms_duration, (self._multisine_scale(),))
        ms_stop = t
        if self.dwell > 0:
            add(_HOLD, self.dwell, ())
        move(0.0)
        if self.dwell > 0:
            add(_HOLD, self.dwell, ())
        injection: list[tuple[float, float]] = []
        if self.injection_s > 0:
            v = self.injection_velocity
            Tr = self._ramp_time(v, self.ladder_accel)
            Tc = self.injection_s / 2.0
            if v * (Tr + Tc) > self.travel:
                raise ValueError(f"ExcitationPlan: the injection legs need {v * (Tr + Tc):.6g} m of travel "
                                 f"(injection_velocity {v} m/s for injection_s / 2 = {Tc} s); travel is {self.travel} m")
            for sgn in (1.0, -1.0):
                add(_RAMP, Tr, (0.0, sgn * v))
                injection.append((t, t + Tc))
                add(_CRUISE, Tc, (sgn * v,))
                add(_RAMP, Tr, (sgn * v, 0.0))
                add(_HOLD, max(self.dwell, 1e-3), ())
        object.__setattr__(self, "_injection", tuple(injection))
        object.__setattr__(self, "_legs", tuple(legs))
        object.__setattr__(self, "_ms_window", (ms_start, ms_stop))
        return tuple(segs)

    # -- multisine ---------------------------------------------------------

    def _multisine_unit(self, tau: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Tapered multisine (excursion, velocity, acceleration) at local times ``tau``.

        Lines have equal velocity amplitude ``scale`` (m/s) and Schroeder
        phases (low crest factor, deterministic).
        """
        f = np.asarray(self.ms_freqs)
        K = f.size
        k = np.arange(1, K + 1)
        phi = -np.pi * k * (k - 1) / K
        w = 2.0 * np.pi * f
        A = scale / w
        arg = np.multiply.outer(tau, w) + phi
        S, C = np.sin(arg), np.cos(arg)
        s = S @ A
        sd = C @ (A * w)
        sdd = -(S @ (A * w * w))
        # Quintic fade (zero slope and curvature at both ends) keeps q_ref C2.
        T, Tt = self.ms_duration, self.ms_taper
        env = np.ones_like(tau)
        denv = np.zeros_like(tau)
        ddenv = np.zeros_like(tau)
        if Tt > 0:
            for mask, r, sgn in ((tau < Tt, tau / Tt, 1.0), (tau > T - Tt, (T - tau) / Tt, -1.0)):
                r = np.clip(r[mask], 0.0, 1.0)
                env[mask] = r**3 * (10 - 15 * r + 6 * r**2)
                denv[mask] = sgn * 30 * r**2 * (1 - r) ** 2 / Tt
                ddenv[mask] = (60 * r - 180 * r**2 + 120 * r**3) / Tt**2
        x = env * s
        v = denv * s + env * sd
        a = ddenv * s + 2 * denv * sd + env * sdd
        return x, v, a

    def _multisine_scale(self) -> float:
        # Scale so the peak acceleration is ms_accel and the excursion at most
        # ms_amplitude, on a fixed 10 kHz grid (independent of the sample rate).
        tau = np.arange(0.0, self.ms_duration, 1e-4)
        x, v, a = self._multisine_unit(tau, 1.0)
        return min(self.ms_accel / np.max(np.abs(a)), self.ms_amplitude / np.max(np.abs(x)))

    # -- sampling ----------------------------------------------------------

    def reference(self, sample_rate: float) -> Reference:
        """Sample the reference on ``t = k / sample_rate``, ``k = 0 .. floor(duration * rate)``.

        Parameters
        ----------
        sample_rate : float
            Hz.

        Returns
        -------
        Reference
        """
        if not (math.isfinite(sample_rate) and sample_rate > 0):
            raise ValueError(f"reference: sample_rate must be > 0, got {sample_rate!r}")
        n = int(math.floor(self.duration * sample_rate + 1e-9)) + 1
        t = np.arange(n) / sample_rate
        q = np.zeros(n)
        qd = np.zeros(n)
        qdd = np.zeros(n)
        edges = np.array([s[1] for s in self._segments] + [np.inf])
        idx = np.searchsorted(edges, t, side="right") - 1
        idx = np.clip(idx, 0, len(self._segments) - 1)
        for i, (kind, t0, T, args) in enumerate(self._segments):
            m = idx == i
            if not np.any(m):
                continue
            tau = np.minimum(t[m] - t0, T)
            x0 = args[0]
            if kind == _HOLD:
                q[m] = x0
            elif kind == _CRUISE:
                vv = args[1]
                q[m] = x0 + vv * tau
                qd[m] = vv
            elif kind == _RAMP:
                v0, v1 = args[1], args[2]
                dv = v1 - v0
                r = np.pi * tau / T
                q[m] = x0 + v0 * tau + dv * (tau / 2.0 - T / (2.0 * np.pi) * np.sin(r))
                qd[m] = v0 + dv * (1.0 - np.cos(r)) / 2.0
                qdd[m] = dv * np.pi / (2.0 * T) * np.sin(r)
            else:
                xs, vs_, as_ = self._multisine_unit(tau, args[1])
                q[m], qd[m], qdd[m] = x0 + xs, vs_, as_
        return Reference(t=t, q=q, qd=qd, qdd=qdd, legs=self._legs, multisine=self._ms_window,
                         injection=self._injection)

    def injection_signal(self, t: np.ndarray) -> np.ndarray:
        """Unit PRBS (+-1) on the injection legs and 0 elsewhere, at the sample times ``t`` (s).

        One bit per sample of a maximal-length sequence (``scipy.signal.max_len_seq``,
        deterministic), continued from one leg to the next.
        """
        from scipy.signal import max_len_seq

        out = np.zeros(t.size)
        masks = [(t >= a) & (t < b) for a, b in self._injection]
        n = sum(int(np.count_nonzero(m)) for m in masks)
        if n == 0:
            return out
        bits = max_len_seq(max(int(math.ceil(math.log2(n + 1))), 4))[0][:n]
        seq = 2.0 * bits.astype(float) - 1.0
        i = 0
        for m in masks:
            k = int(np.count_nonzero(m))
            out[m] = seq[i:i + k]
            i += k
        return out


# --------------------------------------------------------------------------- simulation


@njit(cache=True)
def _closed_loop(p, q_ref, qd_ref, u_ff, noise, lsb, T, nsub, kp, kd, ki, u_max, q_out, u_out):
    """PID + feedforward around the sub-stepped plant; fills q_out, u_out in place.

    The logged ``u`` is the command the controller issues; the plant receives it
    ``p[P_DELAY]`` later, switching the held command inside the sample as the
    sampled loop of :func:`commission.controllers.simulate.closed_loop_kernel`
    does (with its hold helper, so both loops apply a delay the same way).
    """
    tau = p[P_DELAY] / T
    n_d = int(math.floor(tau + 1e-9))
    f = tau - n_d
    if f < 1e-9:
        f = 0.0
    nh = n_d + 2
    hist = np.zeros(nh)  # hist[j % nh] = command issued at sample j
    st = np.empty(NX)
    plant_start(p, st, q_ref[0])
    integ = 0.0
    q_prev = math.floor(plant_output(p, st) / lsb + 0.5) * lsb
    for k in range(q_ref.size):
        qm = math.floor((plant_output(p, st) + noise[k]) / lsb + 0.5) * lsb
        e = q_ref[k] - qm
        vel = (qm - q_prev) / T if k > 0 else 0.0  # backward difference, as on a drive
        integ_new = integ + e * T
        u_lin = kp * e + kd * (qd_ref[k] - vel) + ki * integ_new + u_ff[k]
        u = min(max(u_lin, -u_max), u_max)
        if u == u_lin:
            integ = integ_new  # conditional integration: no wind-up on the rail
        q_out[k] = qm
        u_out[k] = u
        hist[k % nh] = u
        u_late = hist[(k - n_d) % nh] if k >= n_d else 0.0
        u_early = hist[(k - n_d - 1) % nh] if k >= n_d + 1 else 0.0
        hold_segment(p, st, u_early, u_max, 0.0, f * T, nsub, T)
        hold_segment(p, st, u_late, u_max, 0.0, (1.0 - f) * T, nsub, T)
        q_prev = qm


def loop_gains(truth: AxisTruth, plan: ExcitationPlan) -> tuple[float, float, float]:
    """PID gains the simulated commissioning loop uses.

    Designed on the guessed mass ``M_g = plan.guess_factor * truth.M`` for the
    bandwidth ``w = 2 pi plan.bandwidth_hz`` and damping ``plan.damping``.

    Parameters
    ----------
    truth : AxisTruth
        The simulated axis (only ``M`` is used).
    plan : ExcitationPlan
        Loop design fields ``bandwidth_hz``, ``damping``, ``integral_hz``, ``guess_factor``.

    Returns
    -------
    kp : float
        u-unit/m.
    kd : float
        u-unit s/m.
    ki : float
        u-unit/(m s).
    """
    Mg = plan.guess_factor * truth.M
    w = 2.0 * math.pi * plan.bandwidth_hz
    kp = Mg * w * w
    return kp, 2.0 * plan.damping * Mg * w, kp * 2.0 * math.pi * plan.integral_hz


def simulate_excitation(truth: AxisTruth, plan: ExcitationPlan,
                        rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Simulate a closed-loop excitation run and return its log.

    A discrete PID (derivative on the backward-difference velocity, integral
    with anti-windup, gains from :func:`loop_gains`) plus a rough feedforward
    tracks ``plan.reference(truth.sample_rate)``; on the injection legs a PRBS
    of ``+-guess_factor M injection_accel`` is added to the command (and to the
    logged ``u``).  The command is held over each sample period, ``truth.delay``
    late, while :func:`~commission.controllers.plant.plant_step` advances
    ``plan.substeps`` sub-steps per sample.  The encoder reads
    ``round((x + n) / lsb) * lsb`` with ``n ~ N(0, noise_std^2)`` from ``rng``.

    Parameters
    ----------
    truth : AxisTruth
        The simulated axis.
    plan : ExcitationPlan
        Reference and loop design.
    rng : numpy.random.Generator
        Source of the position noise (drawn only when ``truth.noise_std > 0``).

    Returns
    -------
    dict of str to ndarray
        ``t`` (s), ``q`` (m, on the LSB grid), ``u`` (u-unit, within
        ``+-u_max``), ``q_ref`` (m); float64, one length.
    """
    ref = plan.reference(truth.sample_rate)
    n = ref.t.size
    noise = rng.normal(0.0, truth.noise_std, n) if truth.noise_std > 0 else np.zeros(n)
    g = plan.guess_factor
    u_ff = (g * truth.M * ref.qdd + g * truth.B * ref.qd
            + g * truth.fc * (2.0 / np.pi) * np.arctan(900.0 * ref.qd))
    if ref.injection:
        u_ff = u_ff + g * truth.M * plan.injection_accel * plan.injection_signal(ref.t)
    kp, kd, ki = loop_gains(truth, plan)
    q = np.empty(n)
    u = np.empty(n)
    _closed_loop(truth.plant(), ref.q, ref.qd, u_ff, noise, truth.lsb, truth.period,
                 int(plan.substeps), kp, kd, ki, truth.u_max, q, u)
    return {"t": ref.t, "q": q, "u": u, "q_ref": ref.q.copy()}


# --------------------------------------------------------------------------- writers


def _checked_channels(data: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """Validate a log against CONTRACT section 1; return float64 arrays in file order."""
    unknown = sorted(set(data) - set(LOG_CHANNELS))
    if unknown:
        raise DataError(f"log: unknown channel {unknown[0]!r} (contract names: {', '.join(LOG_CHANNELS)})")
    for name in ("t", "q", "u"):
        if name not in data:
            raise DataError(f"log: required channel {name!r} is missing")
    out: dict[str, np.ndarray] = {}
    for name in LOG_CHANNELS:
        if name not in data:
            continue
        a = np.asarray(data[name], dtype=np.float64)
        if a.ndim != 1:
            raise DataError(f"{name}: expected a 1-D array, got shape {a.shape}")
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise DataError(f"{name}: sample {bad[0]} is {float(a[bad[0]])!r}")
        out[name] = a
    n = out["t"].size
    for name, a in out.items():
        if a.size != n:
            raise DataError(f"{name}: {a.size} samples, but t has {n}")
    if n < 2:
        raise DataError(f"t: need at least 2 samples, got {n}")
    t = out["t"]
    dec = np.flatnonzero(np.diff(t) <= 0)
    if dec.size:
        i = int(dec[0]) + 1
        raise DataError(f"t: not strictly increasing at index {i} (t[{i}]={float(t[i])!r} <= t[{i - 1}]={float(t[i - 1])!r})")
    return out


def write_log_h5(path: str | os.PathLike[str], data: Mapping[str, Any], *,
                 q_unit: str = "m", u_unit: str = "V") -> None:
    """Write an excitation log as HDF5 (CONTRACT section 1).

    1-D float64 datasets ``t``, ``q``, ``u`` and, if present, ``q_ref`` at the
    root (gzip + shuffle, transparent to any HDF5 reader); root attributes
    ``q_unit`` and ``u_unit``.  Written to a temporary file and renamed, so
    a failure leaves nothing behind.

    Parameters
    ----------
    path : path-like
        Output file (``.h5`` or ``.hdf5``).
    data : mapping of str to array
        Channels ``t`` (s), ``q`` (``q_unit``), ``u`` (``u_unit``), optional ``q_ref``.
    q_unit : {'m', 'mm', 'um'}
        Unit of ``q`` and ``q_ref``.
    u_unit : {'V', 'N', 'A'}
        Unit of ``u``.

    Raises
    ------
    DataError
        A channel is missing, unknown, not 1-D, non-finite, of another length,
        or ``t`` is not strictly increasing.
    UsageError
        An unknown unit.
    """
    import h5py  # pipeline layer only

    if q_unit not in Q_UNITS:
        raise UsageError(f"q_unit: {q_unit!r} is not one of {', '.join(Q_UNITS)}")
    if u_unit not in U_UNITS:
        raise UsageError(f"u_unit: {u_unit!r} is not one of {', '.join(U_UNITS)}")
    chans = _checked_channels(data)

    def write(tmp: str) -> None:
        with h5py.File(tmp, "w") as f:
            for name, a in chans.items():
                f.create_dataset(name, data=a, dtype="f8", compression="gzip",
                                 compression_opts=4, shuffle=True)
            f.attrs["q_unit"] = q_unit
            f.attrs["u_unit"] = u_unit

    write_atomic(path, write)


def write_log_csv(path: str | os.PathLike[str], data: Mapping[str, Any], *, digits: int = 12) -> None:
    """Write an excitation log as CSV (CONTRACT section 1).

    A header row ``t,q,u[,q_ref]`` then one row per sample, each value with
    ``digits`` significant digits (``%.12g`` keeps 0.01 nm on a 1 m stroke
    and prints grid values such as 0.0004 or 1.5e-06 exactly).

    Parameters
    ----------
    path : path-like
        Output file (``.csv``).
    data : mapping of str to array
        Channels ``t`` (s), ``q`` (m), ``u`` (u-unit), optional ``q_ref`` (m).
    digits : int
        Significant digits per value (1-17).

    Raises
    ------
    DataError
        As :func:`write_log_h5`.
    UsageError
        ``digits`` out of range.
    """
    if not (isinstance(digits, int) and 1 <= digits <= 17):
        raise UsageError(f"digits: need an integer 1-17, got {digits!r}")
    chans = _checked_channels(data)
    cols = np.column_stack(list(chans.values()))

    def write(tmp: str) -> None:
        with open(tmp, "w", newline="\n") as fh:
            np.savetxt(fh, cols, fmt=f"%.{digits}g", delimiter=",",
                       header=",".join(chans), comments="")

    write_atomic(path, write)
