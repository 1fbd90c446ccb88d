"""The frequency-response step: what the rigid model lacks, measured, and what the log lacks, said.

The measured response ``u -> q`` against the fitted M and B (:mod:`commission.identify.frf`):
on the injection windows of an excitation plan when one is given or lies beside the log,
else on the broadband segments the command's level shows.  The encoder's noise is read off
the same log, and a log without a broadband segment gets the ``commission excite`` run that
would supply one (``evidence``).
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from commission.controllers.linear import rigid_frequency_response
from commission.errors import UsageError
from commission.identification.inputs import plan_beside
from commission.identify.fit import AxisFit
from commission.identify.frf import MAX_MODES, EncoderNoise, FrequencyResponse, encoder_noise, frequency_response
from commission.logs import ExcitationLog


def _frequency_of(logs: Sequence[ExcitationLog], M: float, B: float,
                  max_modes: int = MAX_MODES) -> tuple[FrequencyResponse, ExcitationLog]:
    """The frequency response of the first log that holds a broadband segment, else of the longest log.

    The response is estimated within one recording (windows never span a join);
    several logs of one axis rarely all carry a broadband injection.  Returns the log used too.
    """
    if len(logs) == 1:
        return frequency_response(logs[0].t, logs[0].q, logs[0].u, M, B, max_modes=max_modes), logs[0]
    out = None
    for lg in sorted(logs, key=lambda lg: -lg.n):
        fr = frequency_response(lg.t, lg.q, lg.u, M, B, max_modes=max_modes)
        if fr.source == "broadband":
            return fr, lg
        out = out or (fr, lg)
    return out  # type: ignore[return-value]


def _encoder_noise(fr: FrequencyResponse, lg: ExcitationLog, quantization: float | None) -> EncoderNoise | None:
    """Encoder noise and quantization's share (:func:`commission.identify.frf.encoder_noise`) of the log ``fr`` used.

    The command's effect is taken out with the fitted model (modes and delay) where the log
    has a broadband segment, else with the rigid body.
    """
    Ts = 1.0 / fr.sample_rate
    if fr.fit is not None:
        def response(f: np.ndarray) -> np.ndarray:
            return fr.fit.response(fr.M, fr.B, Ts, f)  # type: ignore[union-attr]
    else:
        def response(f: np.ndarray) -> np.ndarray:
            return rigid_frequency_response(fr.M, fr.B, Ts, f)
    segs = [(int(np.searchsorted(lg.t, a)), int(np.searchsorted(lg.t, b)) + 1) for a, b in fr.segments]
    return encoder_noise(lg.q, lg.u, fr.sample_rate, response, quantization, segs)


def _evidence(logs: Sequence[ExcitationLog], freq: FrequencyResponse | None, fit: AxisFit, u_max: float | None,
              units: Mapping[str, str]) -> dict[str, object] | None:
    """ident.json's ``evidence``: what the log lacks and the ``excite`` run that supplies it (None: nothing).

    The machine's limits in the sketch are what the logs show (span, peak speed, peak
    acceleration from a cubic Savitzky-Golay fit over 20 ms) and the drive's command limit:
    ``--u-max``, else, for a command in volts scaled by ``--input-gain``, the usual +-10 V
    analog range times that gain (said as an assumption), else the logs' peak |u|.
    """
    from scipy.signal import savgol_filter

    from commission.next_steps import ANALOG_COMMAND_RANGE_V, excite_advice

    if freq is not None and freq.source == "broadband":
        return None
    first = logs[0]
    fs = float(first.sample_rate)
    travel = max(float(np.max(lg.q) - np.min(lg.q)) for lg in logs)
    win = max(7, int(round(0.02 * fs)) | 1)
    a_peak = max(float(np.max(np.abs(savgol_filter(lg.q, win, 3, deriv=2, delta=1.0 / fs)))) if lg.q.size > win else 0.0
                 for lg in logs)
    v_peak = max(float(np.max(np.abs(savgol_filter(lg.q, win, 3, deriv=1, delta=1.0 / fs)))) if lg.q.size > win else 0.0
                 for lg in logs)
    u_peak = max(float(np.max(np.abs(lg.u))) for lg in logs)
    u_unit = units["u"]
    if u_max is not None:
        source = "the drive's command limit (--u-max)"
    elif first.u_unit == "V" and first.input_gain != 1.0:
        u_max = ANALOG_COMMAND_RANGE_V * first.input_gain
        source = (f"assumed: the drive's +-{ANALOG_COMMAND_RANGE_V:g} V command range x --input-gain "
                  f"{first.input_gain:.6g} {u_unit}/V (the log peaks at {u_peak:.4g} {u_unit}; --u-max sets it)")
    else:
        source = f"the log's peak |u| (the drive may allow more: --u-max sets it)"
    p = fit.parameters
    rate = float(round(fs)) if abs(fs - round(fs)) <= 1e-3 * fs else fs  # 1000.016 Hz measured: a 1 kHz drive
    adv = excite_advice(freq.to_dict() if freq is not None else None, travel=travel, v_peak=v_peak,
                        a_peak=a_peak, u_peak=u_peak, u_max=u_max, u_max_source=source, sample_rate=rate,
                        M=p["M"][0] if "M" in p else None, B=p["B"][0] if "B" in p else None,
                        fc=p["fc"][0] if "fc" in p else None, q_unit=units["q"], u_unit=u_unit)
    return None if adv is None else adv.to_dict()


def _frequency_step(logs: Sequence[ExcitationLog], paths: Sequence[str], fit: AxisFit, quantization: float | None, *,
                    max_modes: int | None, plan: Mapping[str, Any] | None, plan_path: str | None,
                    notes: list[str]) -> tuple[FrequencyResponse, EncoderNoise | None, str | None]:
    """The frequency response of a fit with M, the encoder noise, and the plan's path (identify_log's step).

    A given plan (``--plan``) says where its injection is; without one, a plan.json beside the
    one log is used when the log is a recording of it (:func:`plan_beside`; why one is not used
    goes to ``notes``); else the broadband segments of the logs (:func:`_frequency_of`).

    Returns
    -------
    (freq, noise, plan_path)
        ``plan_path`` is where the plan used was read (None: no plan).
    """
    modes = MAX_MODES if max_modes is None else max_modes
    if plan is None and len(logs) == 1:
        # A log recorded from an excite plan, kept beside its plan.json: the plan says where the
        # injection is even where the command's level does not show it (a noisy encoder's feedback).
        plan, plan_path, note = plan_beside(paths[0], logs[0])
        if note:
            notes.append(note)
    if plan is not None:
        # The excitation plan says where its injection is (commission excite; identify --plan).
        from commission.excite import injection_ranges

        if len(logs) != 1:
            raise UsageError(f"--plan: takes one log recorded from the plan, got {len(logs)}")
        freq, freq_log = frequency_response(logs[0].t, logs[0].q, logs[0].u, fit.parameters["M"][0],
                                            fit.parameters["B"][0], max_modes=modes,
                                            ranges=injection_ranges(plan, logs[0].t)), logs[0]
    else:
        freq, freq_log = _frequency_of(logs, fit.parameters["M"][0], fit.parameters["B"][0], modes)
    return freq, _encoder_noise(freq, freq_log, quantization), plan_path
