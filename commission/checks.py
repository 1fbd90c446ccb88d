"""Pre-fit data checks on an :class:`~commission.logs.ExcitationLog`.

:func:`check_log` runs before any identification.  A log that cannot give a
trustworthy fit is refused with a :class:`~commission.errors.DataError` whose
one-line message names the file, the channel and the first bad sample; a log
that passes yields a :class:`CheckReport` describing what the data show
(sample rate, timing jitter, encoder resolution, command range) plus warnings.

Checks, in order (the first failure is reported):

1. every sample of t, q, u and q_ref is finite;
2. ``t`` is strictly increasing (with finite steps), and uniformly sampled: every step
   ``dt[k] = t[k] - t[k-1]`` is within ``dt_tolerance`` (1 %) of the median
   step.  The identification filters (zero-phase Butterworth, central
   differences, decimation) assume a fixed rate; a dropped sample doubles one
   step and shows up here with its index;
3. the log is long enough: ``min_samples`` (500) samples and ``min_duration``
   (1 s).  The EMPS-style pipeline drops ~50 edge samples at each end and
   decimates by 10, so 500 samples leave ~40 regression rows, a floor for a
   4-7 parameter fit; one second covers at least one motion at the usual
   0.5-5 kHz rates;
4. the axis moves (``q`` not constant) and the command varies (``u`` not
   constant);
5. the command is not saturated: at most ``saturation_fraction`` (5 %) of the
   samples sit exactly at max(u) or min(u) in runs of at least
   ``saturation_min_run`` (3) consecutive samples.  A saturated drive does not
   deliver the recorded command, so the fit would be biased.  Commands with
   few distinct levels (steps, PRBS, square waves: at most 16 values) sit at
   their extremes by design; for them this check is skipped with a warning.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from commission.errors import DataError, UsageError
from commission.identify.signals import encoder_grid
from commission.logs import ExcitationLog

__all__ = ["CheckReport", "check_log"]

#: A command with at most this many distinct values is a designed
#: piecewise-constant excitation, exempt from the saturation check.
FEW_LEVELS = 16

@dataclass(frozen=True)
class CheckReport:
    """What the pre-fit checks found in a log that passed them.

    Only a log that passes builds one (a failed check raises instead), so every field
    describes data the fit will use; what does not stop the fit is in ``warnings``.

    Attributes
    ----------
    source : str
        The log's file name.
    n : int
        Number of samples.
    sample_rate : float
        ``1 / median(dt)`` [Hz].
    duration : float
        ``n / sample_rate`` [s], the span the samples cover.
    dt_max_deviation : float
        ``max |dt - median(dt)| / median(dt)`` (fraction; 0.01 is 1 %).
    dt_relative_std : float
        ``std(dt) / median(dt)`` (fraction).
    quantization_step : float or None
        Encoder step [m] if every ``q`` sample lies on a regular grid (within
        1 % of a step), refined by least squares over all samples; None when
        ``q`` is not on a grid (resampled, filtered or converted data).
    apparent_resolution : float
        Smallest nonzero ``|q[k] - q[k-1]|`` [m], reported in both cases.
    q_range : tuple of float
        ``(min q, max q)`` [m].
    u_range : tuple of float
        ``(min u, max u)`` in the log's command unit (after ``input_gain``).
    u_rail_fraction : float
        Fraction of samples sitting at max(u) or min(u) in runs of at least
        ``saturation_min_run``; 0 when the saturation check was skipped.
    warnings : tuple of str
        Things to tell the user that do not stop the fit.
    """

    source: str
    n: int
    sample_rate: float
    duration: float
    dt_max_deviation: float
    dt_relative_std: float
    quantization_step: float | None
    apparent_resolution: float
    q_range: tuple[float, float]
    u_range: tuple[float, float]
    u_rail_fraction: float
    warnings: tuple[str, ...]


def check_log(
    log: ExcitationLog,
    *,
    min_samples: int = 500,
    min_duration: float = 1.0,
    dt_tolerance: float = 0.01,
    saturation_fraction: float = 0.05,
    saturation_min_run: int = 3,
) -> CheckReport:
    """Refuse a log unfit for identification; describe one that is fit.

    Parameters
    ----------
    log : ExcitationLog
        The loaded log.
    min_samples : int
        Fewest samples accepted (>= 2).
    min_duration : float
        Shortest span accepted [s], measured as ``n / sample_rate``.
    dt_tolerance : float
        Largest accepted ``|dt - median(dt)| / median(dt)`` (fraction).
    saturation_fraction : float
        Largest accepted fraction of samples at the command's rails.
    saturation_min_run : int
        Consecutive samples at a rail needed to count as a flat top (>= 1).

    Returns
    -------
    CheckReport

    Raises
    ------
    DataError
        One line naming the file, the channel and the first bad sample index
        (see the module docstring for the list of checks).
    UsageError
        A threshold argument out of range.
    """
    if min_samples < 2:
        raise UsageError(f"min_samples: expected at least 2, got {min_samples}")
    if not (dt_tolerance > 0 and 0 < saturation_fraction < 1 and saturation_min_run >= 1):
        raise UsageError(
            "check thresholds: need dt_tolerance > 0, 0 < saturation_fraction < 1, "
            f"saturation_min_run >= 1 (got {dt_tolerance}, {saturation_fraction}, {saturation_min_run})"
        )
    src = log.source
    t, q, u = log.t, log.q, log.u
    n = log.n

    _check_finite(log, src)  # 1. finite samples
    rate, dt_max_dev, dt_rel_std = _check_time_base(t, n, src, dt_tolerance)  # 2. time base

    # 3. Length.
    duration = n / rate if n >= 2 else 0.0
    if n < min_samples or duration < min_duration:
        raise DataError(
            f"{src}: log too short: {n} samples over {duration:.4g} s; identification needs at "
            f"least {min_samples} samples and {min_duration:g} s (the zero-phase filters and the "
            "decimation lose samples at both ends)"
        )

    # 4. Motion and excitation.
    q_unit = "rad" if log.q_unit_in_file == "rad" else "m"  # q is in m once read, unless rotary
    q_min, q_max = float(q.min()), float(q.max())
    if q_min == q_max:
        raise DataError(f"{src}: channel q: constant (all {n} samples = {q_min!r} {q_unit}); the axis never moved")
    u_min, u_max = float(u.min()), float(u.max())
    if u_min == u_max:
        raise DataError(
            f"{src}: channel u: constant command (all {n} samples = {u_min!r}); nothing excites the axis"
        )

    warns: list[str] = []
    if log.q_ref is None:
        warns.append("q_ref absent: tracking error cannot be reported")

    # 5. Saturation.
    rail_fraction = _check_saturation(u, n, u_min, u_max, src, saturation_fraction, saturation_min_run, warns)

    step, resolution = encoder_grid(q)
    if step is None:
        warns.append(
            f"q is not on a regular grid (smallest nonzero |dq| = {resolution:.3g} {q_unit}): the record may be "
            "resampled or filtered, so the encoder resolution is unknown"
        )

    warns += plausibility_warnings(t, q, step, rotary=log.q_unit_in_file == "rad", u_unit=log.u_unit)

    return CheckReport(
        source=src, n=n, sample_rate=rate, duration=duration,
        dt_max_deviation=dt_max_dev, dt_relative_std=dt_rel_std,
        quantization_step=step, apparent_resolution=resolution,
        q_range=(q_min, q_max), u_range=(u_min, u_max), u_rail_fraction=rail_fraction,
        warnings=tuple(warns),
    )


def _check_finite(log: ExcitationLog, src: str) -> None:
    """Step 1: every sample of t, q, u and q_ref finite (the first bad one named)."""
    t, q, u = log.t, log.q, log.u
    for name, arr in (("t", t), ("q", q), ("u", u), ("q_ref", log.q_ref)):
        if arr is None:
            continue
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            k = int(bad[0])
            what = "NaN" if math.isnan(arr[k]) else ("+inf" if arr[k] > 0 else "-inf")
            more = f" ({bad.size} non-finite samples in all)" if bad.size > 1 else ""
            raise DataError(f"{src}: channel {name}: sample {k} is {what}{more}")


def _check_time_base(t: np.ndarray, n: int, src: str, dt_tolerance: float) -> tuple[float, float, float]:
    """Step 2: strictly increasing, uniform time; returns (rate [Hz], max and relative std deviation of dt)."""
    with np.errstate(over="ignore", invalid="ignore"):
        dt = np.diff(t)
    dt_max_dev = dt_rel_std = 0.0
    rate = math.nan
    if n >= 2:
        nonpos = np.flatnonzero(dt <= 0)
        if nonpos.size:
            k = int(nonpos[0]) + 1
            raise DataError(
                f"{src}: channel t: not strictly increasing at index {k} "
                f"(t[{k}]={float(t[k])!r} <= t[{k - 1}]={float(t[k - 1])!r})"
            )
        overflow = np.flatnonzero(~np.isfinite(dt))
        if overflow.size:  # finite samples whose difference exceeds float64 (|t| ~ 1e308)
            k = int(overflow[0]) + 1
            raise DataError(f"{src}: channel t: step t[{k}]-t[{k - 1}] overflows (t[{k}]={float(t[k])!r})")
        dt_med = float(np.median(dt))
        rate = 1.0 / dt_med
        dev = np.abs(dt - dt_med) / dt_med
        dt_max_dev = float(dev.max())
        dt_rel_std = float(np.std(dt) / dt_med)
        if dt_max_dev > dt_tolerance:
            k = int(np.flatnonzero(dev > dt_tolerance)[0]) + 1
            raise DataError(
                f"{src}: channel t: non-uniform sampling at index {k}: t[{k}]-t[{k - 1}] = "
                f"{float(dt[k - 1]):.6g} s is {100 * float(dev[k - 1]):.3g} % off the median step "
                f"{dt_med:.6g} s (tolerance {100 * dt_tolerance:g} %; max deviation "
                f"{100 * dt_max_dev:.3g} %, relative std {100 * dt_rel_std:.3g} %); --resample HZ puts the log "
                f"on a uniform grid by linear interpolation (its median rate is {rate:.6g} Hz)"
            )
    return rate, dt_max_dev, dt_rel_std


def _check_saturation(u: np.ndarray, n: int, u_min: float, u_max: float, src: str, saturation_fraction: float,
                      saturation_min_run: int, warns: list[str]) -> float:
    """Step 5: refuse a command at its rails too long (warn when near); returns the fraction at the rails."""
    rail_fraction = 0.0
    levels = np.unique(u).size
    if levels <= FEW_LEVELS:
        warns.append(
            f"u takes only {levels} distinct values (steps/PRBS-like command); saturation check skipped"
        )
    else:
        rails = []
        count = 0
        for label, rail in (("max", u_max), ("min", u_min)):
            c, first = _rail_runs(u, rail, saturation_min_run)
            if c:
                rails.append(f"{label} u = {rail!r}: {c} samples from index {first}")
                count += c
        rail_fraction = count / n
        if rail_fraction > saturation_fraction:
            raise DataError(
                f"{src}: channel u: saturated: {count} samples ({100 * rail_fraction:.3g} %) sit at the rails "
                f"in runs of >= {saturation_min_run} ({'; '.join(rails)}); limit "
                f"{100 * saturation_fraction:g} %"
            )
        if rail_fraction > saturation_fraction / 5:
            warns.append(
                f"u near saturation: {100 * rail_fraction:.3g} % of samples at the rails ({'; '.join(rails)})"
            )
    return rail_fraction


def _rail_runs(u: np.ndarray, rail: float, min_run: int) -> tuple[int, int | None]:
    """Samples of ``u`` equal to ``rail`` in runs of >= ``min_run``, and the first run's start."""
    mask = np.concatenate(([0], (u == rail).astype(np.int8), [0]))
    edges = np.diff(mask)
    starts = np.flatnonzero(edges == 1)
    lengths = np.flatnonzero(edges == -1) - starts
    keep = lengths >= min_run
    if not keep.any():
        return 0, None
    return int(lengths[keep].sum()), int(starts[keep][0])


#: Speed [m/s] above which a linear axis's log is implausible: positioning axes stay well below it,
#: while a log in mm read as metres reads 1000 times too fast.
PLAUSIBLE_SPEED = 10.0
#: Encoder step [m] above which the declared unit is implausible for a precision axis.
PLAUSIBLE_STEP = 1e-4
#: Travel [m] above which a linear log is more likely a rotary angle in rad read as metres
#: (one revolution is 6.3 "m"); precision linear axes have strokes of a few metres at most.
PLAUSIBLE_TRAVEL = 5.0
#: Speed [rad/s] above which a rotary log is implausible (about 19 000 rpm): an angle in
#: degrees or encoder counts read as rad reads 57 or thousands of times too fast.
PLAUSIBLE_ROTARY_SPEED = 2000.0
#: Mass [kg] (M with u in N, q in m) below which a linear axis is implausible: a log in mm or um
#: read as metres makes the mass 1e3 or 1e6 times too small.
PLAUSIBLE_MASS_KG = 1e-3


def plausibility_warnings(t: np.ndarray, q: np.ndarray, step: float | None, *, rotary: bool = False,
                          u_unit: str | None = None) -> list[str]:
    """Warnings, with the figure and the likely unit, when the log's q cannot be in its declared unit.

    Linear axis (q in m): a peak speed or an encoder step implausible for a positioning axis
    (the usual cause: a log in mm or um read as m), or a travel or a torque command (u in Nm)
    that says the axis is rotary (q an angle in rad).  Rotary axis (q in rad): a peak speed
    no motor reaches (an angle in degrees or counts).  The peak speed is the 99.9th percentile
    of ``|dq/dt|`` (a single glitch does not count).  The remedy named is ``--q-unit``.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = np.abs(np.diff(q) / np.diff(t))
    speed = speed[np.isfinite(speed)]
    out = []
    if rotary:
        if speed.size and (peak := float(np.percentile(speed, 99.9))) > PLAUSIBLE_ROTARY_SPEED:
            out.append(f"q: peak speed {peak:.3g} rad/s ({peak * 30 / math.pi:.3g} rpm) is implausible for a "
                       f"motor (> {PLAUSIBLE_ROTARY_SPEED:g} rad/s); q is probably in degrees or encoder counts, "
                       "not rad: convert it to rad")
        return out
    travel = float(q.max() - q.min()) if q.size else 0.0
    if travel > PLAUSIBLE_TRAVEL:
        out.append(f"q: travel {travel:.3g} m is implausible for a linear positioning axis (> {PLAUSIBLE_TRAVEL:g} "
                   "m); if q is a rotary axis's angle in rad, pass --q-unit rad (in mm: --q-unit mm)")
    elif u_unit == "Nm":
        out.append("u is a torque (Nm) but q is read in m: if q is a rotary axis's angle in rad, pass --q-unit rad")
    if speed.size and (peak := float(np.percentile(speed, 99.9))) > PLAUSIBLE_SPEED:
        out.append(f"q: peak speed {peak:.3g} m/s is implausible for a positioning axis (> {PLAUSIBLE_SPEED:g} "
                   "m/s); if the file's q is in mm or um, pass --q-unit mm (or um)")
    if step is not None and step > PLAUSIBLE_STEP:
        out.append(f"q: encoder step {step:.3g} m is implausibly coarse (> {PLAUSIBLE_STEP:g} m); if the file's "
                   "q is in mm or um, pass --q-unit mm (or um)")
    return out


def mass_plausibility_warnings(units: dict[str, str], mass: float | None) -> list[str]:
    """A warning naming the likely unit when the identified M is implausible for a linear axis in N and m.

    Only the linear axis with a command in newtons has a mass in kg to judge
    (:data:`PLAUSIBLE_MASS_KG`); other command units carry an unknown gain.
    """
    if mass is None or units.get("u") != "N" or units.get("q") != "m" or not mass < PLAUSIBLE_MASS_KG:
        return []
    return [f"M = {mass:.3g} kg is implausibly light for a linear axis (< {PLAUSIBLE_MASS_KG:g} kg): q is probably "
            "in mm or um read as m; pass --q-unit mm (or um)"]
