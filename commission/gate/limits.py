"""The gate resolved for one axis: :class:`GateLimits`, every limit in SI units (:func:`resolve_gate`).

The defaults are the rows of :data:`~commission.formats.gate_toml.GATE_KEYS`; what they mean
(LSB = encoder resolution, travel = the spec's envelope stroke):

* ``e_F``, ``e_M``, ``e_rms``: max(k LSB, f x travel, 4 x the spec's ``[targets]`` value where it has
  one) (:class:`~commission.formats.gate_toml.ErrorDefault`).  A DEFAULTED error limit also depends
  on the axis's PID yardstick (:func:`absolute_mode`, :func:`scenario_error_limit`): where the
  yardstick is the fastest PID the margin floors admit, the limit on a scenario is at least that
  PID's own value there (a trajectory asking more than the floors allow any fixed-gain loop on this
  axis does not refuse the ARC; the comparison criteria judge it against the yardstick); where no
  PID keeps the floors, the error limits are reported, not gated.  Safety criteria and the floors
  never move; a limit gate.toml gives never moves.
* ``c_u`` 1: input increments as large as the input itself mean a chattering command.
* ``u_max``: the tuning spec's ``controller.u_max``.  A command that *reaches* the limit counts as
  a violation: the controller then relied on clipping, i.e. its demand exceeded the actuator.
* ``arc_vs_pid_e_rms``: off by default; when given, the ARC must be no worse than factor x the PID
  baseline (the yardstick, :func:`commission.tune.baseline.pid_yardstick`) on every scenario, up to
  ``arc_vs_pid_slack``: by default the rms of the encoder's quantization noise, LSB / sqrt(12).
  Errors are measured on the encoder, whose quantization alone gives e_rms = LSB / sqrt(12) to an
  error-free loop; when both controllers track within a fraction of an encoder step, which one is
  "better" by less than that noise is not observable on the machine.  Set it to 0 for the strict
  comparison.

Why these: the quantization floor of any encoder-fed loop is a few LSB, so each error limit allows
a fixed number of encoder steps; and the tracking error of a sampled loop grows with the speed and
acceleration demanded, which the envelope's stroke carries (the spec scales Case 1 and Case 2 to
it), so each limit also allows a fixed fraction of the stroke.  The larger of the two applies.
The fractions sit above the worst values that sound tunings reach over the whole matrix, and
broken controllers exceed them on the identified plant itself (docs/robustness.md, "Why the
default limits", has the measurements).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

from commission.errors import SpecError
from commission.formats.gate_toml import ARC_VS_PID_AIM, ERROR_KEYS, GATE, QUANTIZATION_RMS_LSB
from commission.gate.check import um
from commission.gate.spec import ErrorLimit, GateSpec
from commission.controllers.metrics import Indexes

#: The defaults below are the table's (:data:`commission.formats.gate_toml.GATE_KEYS`), named here for
#: the code that reads them.
DEFAULT_C_U = GATE["c_u"].default
DEFAULT_ARC_VS_PID = ARC_VS_PID_AIM
#: Default limits of the ARC-vs-PID judgement by quantiles
#: (:func:`commission.gate.comparison.arc_vs_pid_quantile_checks`): the median and the 90th percentile
#: of the per-scenario factor, in each group (fixed, Monte-Carlo).
DEFAULT_ARC_VS_PID_MEDIAN = GATE["arc_vs_pid_median"].default
DEFAULT_ARC_VS_PID_P90 = GATE["arc_vs_pid_p90"].default
#: Default limit of the ARC-vs-PID judgement on the identified plant
#: (:func:`commission.gate.comparison.arc_vs_pid_nominal_checks`).
DEFAULT_ARC_VS_PID_NOMINAL = GATE["arc_vs_pid_nominal"].default
#: A default error limit is also at least this many times the spec's ``[targets]`` value (e_rms,
#: e_f): the paper's targets 5 um and 10 um give the 20 um and 40 um of its 0.4 m envelope, so a user
#: who states looser targets gets limits that follow them instead of a constant.
TARGET_FACTOR = GATE["e_rms"].rule.factor
#: How a defaulted absolute error limit applies on a scenario (:func:`scenario_error_limit`): as
#: resolved (the search's strict reading, and a validation without a yardstick record) ...
ABSOLUTE_FIXED = "fixed"
#: ... at least the PID yardstick's own value on the same scenario (an admissible yardstick) ...
ABSOLUTE_YARDSTICK = "yardstick"
#: ... or reported only, the safety criteria staying (no PID keeps the margin floors on this axis).
ABSOLUTE_REPORTED = "reported"
#: Default slack of the ARC-vs-PID comparison: the rms of uniform quantization noise, 1/sqrt(12) LSB.
DEFAULT_ARC_VS_PID_SLACK_LSB = QUANTIZATION_RMS_LSB
#: Relative tolerance below u_max at which a command counts as having reached the limit.
SATURATION_TOL = 1e-9


@dataclass(frozen=True)
class GateLimits:
    """The gate resolved for one axis: every limit in SI units.

    Attributes
    ----------
    e_F, e_M, e_rms : float
        Error limits, m.
    c_u : float
        Chattering limit.
    u_max : float
        Input limit, u-unit.
    no_divergence : bool
    arc_vs_pid_e_rms : float
    arc_vs_pid_slack : float
        Slack of the ARC-vs-PID comparison, m.
    arc_vs_pid_every : bool
        The scenario-by-scenario comparison is part of the verdict (gate.toml gave ``arc_vs_pid_e_rms``).
    arc_vs_pid_median, arc_vs_pid_p90 : float
        Limits of the median and 90th percentile of the per-scenario factor, per group.
    arc_vs_pid_nominal : float
        Limit of the ARC/PID e_rms ratio on the identified plant, per case (strict: a tie fails).
    basis : dict
        Criterion -> how its limit was set (e.g. ``"default max(30 LSB, 0.01 % travel)"``).
    lsb, travel : float
        The encoder resolution and the envelope stroke the limits were resolved with, m.
    absolute : str
        How the DEFAULTED error limits (``defaulted``) apply on a scenario
        (:func:`scenario_error_limit`): :data:`ABSOLUTE_FIXED` (as resolved),
        :data:`ABSOLUTE_YARDSTICK` (at least the PID yardstick's value on the same scenario) or
        :data:`ABSOLUTE_REPORTED` (no admissible yardstick: measured and reported, not gated).
    defaulted : tuple of str
        The error keys (``e_F``, ``e_M``, ``e_rms``) that gate.toml left at their default.
    comparison_reported : tuple of str
        The comparison criteria (``arc_vs_pid_median``, ``arc_vs_pid_p90``, ``arc_vs_pid_nominal``)
        measured and reported, not gated (:func:`comparison_reported`): their pole was defaulted and no
        PID of (57) keeps the floors, so there is no yardstick to beat.  Empty: all gated.
    """

    e_F: float
    e_M: float
    e_rms: float
    c_u: float
    u_max: float
    no_divergence: bool
    arc_vs_pid_e_rms: float
    basis: Mapping[str, str]
    lsb: float
    travel: float
    arc_vs_pid_slack: float = 0.0
    arc_vs_pid_every: bool = True
    arc_vs_pid_median: float = DEFAULT_ARC_VS_PID_MEDIAN
    arc_vs_pid_p90: float = DEFAULT_ARC_VS_PID_P90
    arc_vs_pid_nominal: float = DEFAULT_ARC_VS_PID_NOMINAL
    absolute: str = ABSOLUTE_FIXED
    defaulted: tuple[str, ...] = ()
    comparison_reported: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        return {"e_F": self.e_F, "e_M": self.e_M, "e_rms": self.e_rms, "c_u": self.c_u, "u_max": self.u_max,
                "no_divergence": self.no_divergence, "arc_vs_pid_e_rms": self.arc_vs_pid_e_rms,
                "arc_vs_pid_slack": self.arc_vs_pid_slack, "arc_vs_pid_every": self.arc_vs_pid_every,
                "arc_vs_pid_median": self.arc_vs_pid_median, "arc_vs_pid_p90": self.arc_vs_pid_p90,
                "arc_vs_pid_nominal": self.arc_vs_pid_nominal, "basis": dict(self.basis), "lsb": self.lsb,
                "travel": self.travel, "absolute_limits": self.absolute, "defaulted_limits": list(self.defaulted),
                "comparison_reported": list(self.comparison_reported)}



def absolute_mode(yardstick: Mapping[str, Any] | None) -> str:
    """How the defaulted absolute error limits apply, from tuning.json's ``pid_yardstick`` record.

    * :data:`ABSOLUTE_YARDSTICK` -- the yardstick is the fastest PID of (57) that the margin floors
      admit (``method`` ``"margin_search"``, admissible, and the first candidate simulated -- the
      candidates are simulated one at a time from the fastest, ``TuneSettings.yardstick_batch`` = 1 -- was kept):
      its bandwidth is what this axis's modes, delay and evidence allow a fixed-gain loop under the
      floors, so its error on a scenario is a level this axis can be asked for;
    * :data:`ABSOLUTE_REPORTED` -- no PID of (57) keeps the floors (``is_yardstick`` false): there is
      no achievable level to hold the ARC to;
    * :data:`ABSOLUTE_FIXED` otherwise: no record (older tuning.json), ``[pid] pole`` given, or a
      yardstick slowed below the floors' bandwidth by its simulated check (chattering or unbounded
      faster PIDs: the PID family's noise, not the axis, set its level).  The limits as resolved.
    """
    if not yardstick or "is_yardstick" not in yardstick:
        return ABSOLUTE_FIXED
    if not yardstick["is_yardstick"]:
        return ABSOLUTE_REPORTED
    if yardstick.get("method") == "margin_search" and int(yardstick.get("simulated", 0)) == 1:
        return ABSOLUTE_YARDSTICK
    return ABSOLUTE_FIXED


#: The comparison criteria whose defaulted limit :func:`comparison_reported` may turn into a report.
REPORTABLE_COMPARISONS = ("arc_vs_pid_median", "arc_vs_pid_p90", "arc_vs_pid_nominal")


def comparison_reported(yardstick: Mapping[str, Any] | None, gate: GateSpec) -> tuple[str, ...]:
    """The comparison criteria reported, not gated, for tuning.json's ``pid_yardstick`` record.

    The ARC is judged against a PID only when that PID is a yardstick: one a drive vendor's auto-tuner
    could deliver, keeping the margin floors on the identified plant, stable with one more sample of
    delay and within the evidence (:func:`commission.tune.baseline.pid_yardstick`).  When the pole was
    defaulted and no PID of (57) does (``method`` ``"none_admissible"``, ``is_yardstick`` false), the
    PID that tune simulated is one nobody could certify -- faster than the evidence or the floors
    allow -- and losing to it says nothing about the machine: the defaulted comparison criteria are
    measured and reported, not gated; the safety criteria, the floors and the margins over the box
    stay.  A limit gate.toml gives, and a ``[pid] pole`` the user set, keep the comparison gated.
    """
    if not yardstick or yardstick.get("method") != "none_admissible" or yardstick.get("is_yardstick", True):
        return ()
    return tuple(k for k in REPORTABLE_COMPARISONS if getattr(gate, k) is None)


def _given_metres(source: str, key: str, given: ErrorLimit, lsb: float, travel: float, what: str) -> float:
    """A length gate.toml gave, in metres; an LSB-relative one needs the tuning's encoder (``lsb`` > 0, m)."""
    if given.unit == "lsb" and lsb <= 0:
        raise SpecError(f"{source}: gate.{key} = {given.text!r}: the tuning has no encoder "
                        f"quantization, so an LSB-relative {what} is undefined")
    return given.metres(lsb, travel)


def resolve_gate(gate: GateSpec, *, lsb: float, travel: float, u_max: float,
                 targets: Mapping[str, float] | None = None,
                 yardstick: Mapping[str, Any] | None = None) -> GateLimits:
    """Resolve a gate for one axis.

    Parameters
    ----------
    gate : GateSpec
    lsb : float
        Encoder resolution used in validation, m (0: none; LSB terms vanish).
    travel : float
        Envelope stroke (the spec's ``trajectory.travel``), m.
    u_max : float
        The tuning spec's input limit, u-unit (used unless the gate sets one).
    targets : mapping, optional
        The spec's ``[targets]`` (``e_rms``, ``e_f``, m): a defaulted e_rms or e_F limit is at
        least :data:`TARGET_FACTOR` times the target (None: not used).
    yardstick : mapping, optional
        tuning.json's ``pid_yardstick`` record (None: the search, or a tuning.json without it):
        :func:`absolute_mode` decides whether a defaulted error limit is at least the yardstick's
        value on the same scenario (:data:`ABSOLUTE_YARDSTICK`), reported, not gated
        (:data:`ABSOLUTE_REPORTED`), or as resolved (:data:`ABSOLUTE_FIXED`).  A limit gate.toml
        gives is never moved (:func:`scenario_error_limit`).

    Returns
    -------
    GateLimits
    """
    if not (lsb >= 0 and math.isfinite(lsb)):
        raise ValueError(f"lsb: must be >= 0 m, got {lsb}")
    if not (travel > 0 and math.isfinite(travel)):
        raise ValueError(f"travel: must be > 0 m, got {travel}")
    limits: dict[str, float] = {}
    basis: dict[str, str] = {}
    for key in ERROR_KEYS:
        given: ErrorLimit | None = getattr(gate, key)
        if given is None:
            rule = GATE[key].rule
            limits[key] = max(rule.lsb * lsb, rule.travel * travel)
            tgt = (targets or {}).get(rule.target or "")
            with_target = tgt is not None and math.isfinite(tgt) and tgt > 0
            if with_target:
                limits[key] = max(limits[key], rule.factor * tgt)
            basis[key] = f"default: {rule.formula(with_target)}"
        else:
            limits[key] = _given_metres(gate.source, key, given, lsb, travel, "limit")
            basis[key] = f"{gate.source}: {given.text}"
    c_u = DEFAULT_C_U if gate.c_u is None else gate.c_u
    basis["c_u"] = f"default: {DEFAULT_C_U:g}" if gate.c_u is None else f"{gate.source}: {gate.c_u:g}"
    um = u_max if gate.u_max is None else gate.u_max
    basis["u_max"] = "default: the tuning spec's controller.u_max" if gate.u_max is None else f"{gate.source}: {um:g}"
    basis["no_divergence"] = f"{'default' if gate.source == 'defaults' else gate.source}: {str(gate.no_divergence).lower()}"
    every = gate.arc_vs_pid_e_rms is not None
    factor = DEFAULT_ARC_VS_PID if gate.arc_vs_pid_e_rms is None else gate.arc_vs_pid_e_rms
    basis["arc_vs_pid_e_rms"] = (f"{gate.source}: {factor:g}, scenario by scenario" if every else
                                 f"default: off (tune aims at {factor:g}; the quantiles judge)")
    q_lim = {}
    for key, default in (("arc_vs_pid_median", DEFAULT_ARC_VS_PID_MEDIAN), ("arc_vs_pid_p90", DEFAULT_ARC_VS_PID_P90),
                         ("arc_vs_pid_nominal", DEFAULT_ARC_VS_PID_NOMINAL)):
        given = getattr(gate, key)
        q_lim[key] = default if given is None else given
        basis[key] = f"default: {default:g}" if given is None else f"{gate.source}: {given:g}"
    if gate.arc_vs_pid_slack is None:
        slack = DEFAULT_ARC_VS_PID_SLACK_LSB * lsb
        basis["arc_vs_pid_slack"] = "default: LSB / sqrt(12) (quantization noise rms)"
    else:
        slack = _given_metres(gate.source, "arc_vs_pid_slack", gate.arc_vs_pid_slack, lsb, travel, "slack")
        basis["arc_vs_pid_slack"] = f"{gate.source}: {gate.arc_vs_pid_slack.text}"
    defaulted = tuple(k for k in ERROR_KEYS if getattr(gate, k) is None)
    absolute = absolute_mode(yardstick) if defaulted else ABSOLUTE_FIXED
    for key in defaulted:
        if absolute == ABSOLUTE_YARDSTICK:
            basis[key] += ", or the PID yardstick's value on the same scenario where larger"
        elif absolute == ABSOLUTE_REPORTED:
            basis[key] += "; reported, not gated: no PID keeps the margin floors (no yardstick)"
    reported = comparison_reported(yardstick, gate)
    for key in reported:
        basis[key] += "; reported, not gated: no PID of (57) keeps the margin floors (no yardstick)"
    return GateLimits(e_F=limits["e_F"], e_M=limits["e_M"], e_rms=limits["e_rms"], c_u=c_u, u_max=um,
                      no_divergence=gate.no_divergence, arc_vs_pid_e_rms=factor, basis=basis,
                      lsb=lsb, travel=travel, arc_vs_pid_slack=slack, arc_vs_pid_every=every,
                      arc_vs_pid_median=q_lim["arc_vs_pid_median"], arc_vs_pid_p90=q_lim["arc_vs_pid_p90"],
                      arc_vs_pid_nominal=q_lim["arc_vs_pid_nominal"], absolute=absolute, defaulted=defaulted,
                      comparison_reported=reported)


def scenario_error_limit(limits: GateLimits, key: str, pid: Indexes) -> tuple[float, str]:
    """The absolute error limit ``key`` (``e_F``, ``e_M``, ``e_rms``) on one scenario, and how it was set.

    A limit the user set (gate.toml) applies as given.  A DEFAULTED limit is the axis's default
    (encoder steps, % of travel, :data:`TARGET_FACTOR` x ``[targets]``, :func:`resolve_gate`), and:

    * with a yardstick at the margin floors (:data:`ABSOLUTE_YARDSTICK`, :func:`absolute_mode`), at
      least the yardstick's own value on the same scenario.  That yardstick is the fastest PID the
      margin floors admit on the identified plant: where it cannot meet the default, the trajectory
      asks more than this axis's modes and delay allow a loop under the floors, and the default
      measures the trajectory, not the controller.
      Whether the ARC beats the yardstick is then the comparison criteria's question
      (``arc_vs_pid_*``), and a safe ARC that loses is flagged, never certified;
    * without one (:data:`ABSOLUTE_REPORTED`: no PID keeps the floors), measured and reported, not
      gated: there is no achievable level to hold it to; every safety criterion stays.

    Returns
    -------
    limit : float
        m (inf: reported only).
    note : str
        Appended to the check's detail ("" for a limit as resolved).
    """
    base = float(getattr(limits, key))
    if key not in limits.defaulted or limits.absolute == ABSOLUTE_FIXED:
        return base, ""
    if limits.absolute == ABSOLUTE_REPORTED:
        return math.inf, f"; reported: no PID yardstick keeps the floors (default {um(base)})"
    v = float(getattr(pid, key))
    if pid.diverged or not math.isfinite(v) or v <= base:
        return base, ""
    return v, f"; the PID yardstick's {key} here (default {um(base)})"

