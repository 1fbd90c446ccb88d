"""The runtime guards of the deployed ARC and the gains as controller.json holds them.

:func:`runtime_guards` chooses the guard limits from the envelope and the gate; :func:`deployable_gains`
returns the ARC gains read back through the controller.json layout, so that validate simulates
exactly what is deployed.
"""

from __future__ import annotations

import json
import math
import dataclasses
from typing import Any, Mapping

import numpy as np

from commission.artifacts import Identification
from commission.controller_config import ControllerConfig, ControllerProvenance
from commission.controllers.arc import ArcGains, arc_pack
from commission.controllers.plant import P_DELAY, P_FS, P_RIPPLE_AMP
from commission.gate import GateLimits
from commission.scenarios import FRICTION_SCALE, case1_trajectory, case2_trajectory, force_range, resolve_encoder_noise
from commission.spec import Spec
from commission.tuning import Tuning


#: Speed margin of the plausibility guard: the axis is taken to move at most this
#: many times the envelope's v_max in one sample.
GUARD_SPEED_MARGIN = 2.0
#: Acceleration margin of the plausibility guard: the axis is taken to accelerate at most this
#: many times the largest acceleration of the validated trajectories.
GUARD_ACCEL_MARGIN = 3.0
#: Encoder noise peaks counted in the error of one measurement, in standard deviations.
GUARD_NOISE_SIGMAS = 4.0
#: Fewest still samples (command at u_max, or an implausible y) that latch the frozen-encoder fault.
GUARD_FROZEN_MIN = 3
#: The tracking-error watchdog trips at this many times the gate's e_M.
GUARD_E_M_FACTOR = 2.0
#: Rejected samples in a row that latch a fault span at least this long, s.
GUARD_REJECT_TIME = 2e-3


def runtime_guards(tuning: Tuning, limits: GateLimits) -> dict[str, Any]:
    """The runtime guards of the deployed ARC (ArcGains fields), from the envelope and the gate.

    * ``dy_max = 2 v_max Ts + 2 LSB``: the axis moves at most
      :data:`GUARD_SPEED_MARGIN` x the envelope's v_max in one sample, and the
      encoder rounds each end by half a step (doubled).
    * ``accel_max = 3 a_env``, ``y_err = LSB/2 + 4 sigma``: the innovation bound
      of the prediction (:mod:`commission.controllers.arc`, "Runtime guards").
      a_env is the largest acceleration of the validated trajectories (Case 1's
      filter starts above the spec's a_max) or the spec's a_max if larger; the
      closed loop adds its own transients to it, hence :data:`GUARD_ACCEL_MARGIN`.
      y_err bounds the error of one reading: half an encoder step and
      :data:`GUARD_NOISE_SIGMAS` standard deviations of the simulated encoder noise.
    * ``u_free`` (:func:`holding_force`): the largest command that may leave the
      axis at rest -- friction, ripple, the box's constant forces, the disturbance step.
    * ``n_frozen_max = max(3, ceil(sqrt(64 y_err / a_rail) / Ts) + delay samples)``
      with a_rail = theta1_min (u_max - u_free): under a command at the rail the
      axis accelerates at least a_rail (the lightest-accelerating plant of the
      box, every holding force against it), so within that many samples after
      the plant's input delay its readings must spread over more than the 8 y_err
      a still run allows (a constant acceleration a spreads positions over at
      least a T^2/8 in a time T, whatever the initial speed).  A smaller push
      counts sqrt of its fraction of the rail's (the same spread takes 1/sqrt(a)
      as long); a rejected reading counts 1.  The delay counted is the identified one plus one
      sample: the gate certifies the loop with one more sample of delay (``<case>/delay+1``), so
      the guard must not take the later answer of such a drive for a frozen encoder.
    * ``dy_fault = travel``: no reading can move by the whole stroke in one sample.
    * ``n_reject_max = max(2, ceil(GUARD_REJECT_TIME / Ts))``: the prediction
      (tracking error held) carries the loop through at most 2 ms of glitches.
    * ``e_max = min(2 e_M, travel)`` with e_M the gate's resolved limit: a run
      in which the watchdog trips has already failed the gate's e_M by a factor
      2, so the watchdog never turns a passing validation into a failing one;
      it only stops a run-away on the machine.
    * ``freeze_on_saturation = True``: the gate fails a command that reaches
      u_max, so in a passing validation this never acts; on the machine it keeps
      theta_hat out of the box's corners while the drive is at its limit.

    None of them acts in a validation that passes: the speed bound is twice the
    envelope's, the acceleration bound three times the trajectories' (plus what the
    drive's own command steps explain), and the frozen count needs an implausible y
    or a command that must move the axis, held while the readings stay put.
    ``validate`` simulates with them (see :func:`deployable_gains`), so what it
    proved is what runs.
    """
    spec, Ts = tuning.spec, tuning.arc.Ts
    return guard_values(Ts, tuning.quantization, spec.v_max, spec.travel, limits.e_M,
                        a_max=envelope_acceleration(spec, Ts), u_free=holding_force(tuning.identification, tuning.plant),
                        noise_std=resolve_encoder_noise(tuning.identification, spec),
                        theta1_min=tuning.arc.theta_min[0], u_max=tuning.arc.u_max,
                        delay=float(tuning.plant[P_DELAY]) + Ts)  # the +1 sample the certificate covers


def holding_force(ident: Identification, plant: np.ndarray) -> float:
    """The largest command that may leave the axis at rest in the validated scenarios, u-unit.

    Static friction and force ripple of the identified plant at the friction scenarios' +20 %
    (:data:`commission.scenarios.FRICTION_SCALE`), plus the largest constant force the theta
    box admits at every mass (:func:`commission.scenarios.force_range`), plus the
    Assumption-1 disturbance step delta_d M.  A command beyond it accelerates the axis.

    Parameters
    ----------
    ident : Identification
    plant : numpy.ndarray
        The identified plant vector (:func:`commission.scenarios.identified_plant`).
    """
    lo, hi = force_range(ident)
    step = abs(ident.delta_d * ident.value("M")) if ident.delta_d is not None else 0.0
    return ((1.0 + FRICTION_SCALE) * (abs(float(plant[P_FS])) + abs(float(plant[P_RIPPLE_AMP])))
            + max(abs(lo), abs(hi)) + step)


def envelope_acceleration(spec: Spec, Ts: float) -> float:
    """Largest |q_d''| of the validated trajectories (Case 1, Case 2) sampled at ``Ts``, or the
    spec's a_max if larger, m/s^2 (Case 1's filter starts above a_max)."""
    a_env = float(spec.a_max)
    for traj in (case1_trajectory(spec), case2_trajectory(spec)):
        a_env = max(a_env, float(np.max(np.abs(traj.render(Ts, 0.0).ddqd))))
    return a_env


def guard_values(Ts: float, lsb: float, v_max: float, travel: float, e_M: float, *, a_max: float | None = None,
                 theta1_min: float | None = None, u_max: float | None = None, u_free: float = 0.0,
                 noise_std: float = 0.0, delay: float = 0.0) -> dict[str, Any]:
    """:func:`runtime_guards` from the numbers it uses.

    Parameters
    ----------
    Ts : float
        Sample period, s.
    lsb : float
        Encoder resolution, m.
    v_max : float
        Envelope speed, m/s.
    travel : float
        Envelope stroke, m.
    e_M : float
        The gate's resolved transient limit, m (inf: none).
    a_max : float, optional
        Largest acceleration of the validated trajectories, m/s^2
        (:func:`envelope_acceleration`).  Without it, and without ``theta1_min`` and
        ``u_max``, the innovation and frozen-encoder guards are left out (off).
    theta1_min : float, optional
        Lower bound of theta1 = 1/M, m/(u-unit s^2).
    u_max : float, optional
        Output limit, u-unit.
    u_free : float
        Largest command that may leave the axis at rest, u-unit (:func:`holding_force`).
    noise_std : float
        Encoder noise simulated, m rms.
    delay : float
        The plant's input delay, s.
    """
    e_max = min(GUARD_E_M_FACTOR * e_M, travel) if math.isfinite(e_M) else travel
    guards: dict[str, Any] = {
        "dy_max": GUARD_SPEED_MARGIN * v_max * Ts + 2.0 * lsb,
        "dy_fault": travel,
        "n_reject_max": float(max(2, math.ceil(GUARD_REJECT_TIME / Ts - 1e-9))),
        "e_max": e_max,
        "freeze_on_saturation": True,
    }
    if a_max is None or theta1_min is None or u_max is None:
        return guards
    y_err = 0.5 * lsb + GUARD_NOISE_SIGMAS * noise_std
    guards.update(accel_max=GUARD_ACCEL_MARGIN * a_max, y_err=y_err)
    push = 0.0 < u_free < u_max  # else no command is known to move the axis: only rejected readings count
    a_rail = theta1_min * (u_max - u_free if push else u_max)
    n_frozen = math.ceil(math.sqrt(64.0 * y_err / a_rail) / Ts - 1e-9) + math.ceil(delay / Ts - 1e-9)
    guards.update(n_frozen_max=float(max(GUARD_FROZEN_MIN, n_frozen)), u_free=u_free if push else 0.0)
    return guards


def deployable_gains(arc: ArcGains, guards: Mapping[str, Any] | None = None) -> ArcGains:
    """``arc`` with the runtime ``guards`` (:func:`runtime_guards`), after a round trip
    through the controller.json layout (what the runtime will run)."""
    if guards:
        arc = dataclasses.replace(arc, **guards)
    probe = ControllerConfig(gains=arc, sample_rate=1.0 / arc.Ts, units={"u": "V", "q": "m"}, validated={},
                             provenance=ControllerProvenance(None, "0" * 64, "0" * 64, "", ""))
    doc = json.loads(json.dumps(probe.to_dict()))
    # Infinite limits pass the round trip here; the floors (commission.gate.FLOORS) then refuse to emit them.
    back = ControllerConfig.from_dict(doc, "controller.json (round trip)", allow_unbounded=True).gains
    if not np.array_equal(arc_pack(back), arc_pack(arc)):  # pragma: no cover - a layout bug
        raise RuntimeError("controller.json layout does not reproduce the tuned ARC exactly")
    return back
