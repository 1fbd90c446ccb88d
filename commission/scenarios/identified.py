"""The identified plant as a :mod:`commission.controllers.plant` vector: its parameters, force
ripple, structural modes and input delay, read from ident.json (and the spec's ``[plant]``)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from commission.artifacts import Identification
from commission.controllers.plant import plant_vector
from commission.spec import Spec


def finite_number(x: Any) -> float | None:
    """``x`` (or ``x["value"]``) as a float when it is a finite number, else None (an ident.json field read leniently)."""
    if isinstance(x, dict):  # {"value": ..., "std": ...}
        x = x.get("value")
    if isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x):
        return float(x)
    return None


def _ripple(ident: Identification) -> tuple[float, float]:
    """Force ripple (amplitude u-unit, pitch m) recorded in ident.json's extra fields, if any.

    Read from ``extra["model"]["ripple_amp"]`` / ``["ripple_pitch"]`` (what
    ``commission identify`` writes) or ``extra["ripple"] = {"amplitude", "pitch"}``.
    """
    model = ident.extra.get("model")
    if isinstance(model, dict):
        amp, pitch = finite_number(model.get("ripple_amp")), finite_number(model.get("ripple_pitch"))
        if amp is not None and pitch is not None and pitch > 0:
            return abs(amp), pitch
    r = ident.extra.get("ripple")
    if isinstance(r, dict):
        amp, pitch = finite_number(r.get("amplitude", r.get("amp"))), finite_number(r.get("pitch"))
        if amp is not None and pitch is not None and pitch > 0:
            return abs(amp), pitch
    return 0.0, 0.0


def _spec_states_mode(spec: Spec) -> bool:
    """The spec's ``[plant]`` states its own mode (frequency, load fraction or encoder side)."""
    return any(v is not None for v in (spec.plant_mode_hz, spec.plant_mode_ratio, spec.plant_encoder))


def plant_dynamics(ident: Identification, spec: Spec | None) -> dict[str, float]:
    """The structural modes and input delay of the plant (:func:`plant_vector` keywords).

    From ident.json's ``frequency_response.model`` (what ``commission identify``
    found in the log's broadband content: one mode, or two as two appendages on the motor,
    ``mode2_*``); without a delay there, the input delay of ``model.inverse_dynamics`` when
    its ``delay`` term was chosen (a negative one counts as none); each entry overridden by
    the spec's ``[plant]`` section when given there (a spec that states the mode's frequency,
    load fraction or encoder drops the log's second mode: it belonged to the log's first);
    rigid and delay-free when neither says
    otherwise.  Every scenario plant of ``tune`` and ``validate`` carries them (a
    payload moves the mass, not the mode: its frequency and load fraction are kept).
    """
    out: dict[str, float] = {}
    fr = ident.extra.get("frequency_response")
    model = fr.get("model") if isinstance(fr, dict) else None
    if isinstance(model, dict):
        for m in ("mode", "mode2"):  # the second mode only beside the first
            f = finite_number(model.get(f"{m}_hz"))
            if f is None or f <= 0:
                break
            out[f"{m}_hz"] = f
            for key in (f"{m}_damping", f"{m}_ratio"):
                v = finite_number(model.get(key))
                if v is not None:
                    out[key] = v
            out[f"{m}_load_side"] = bool(model.get(f"{m}_load_side"))
        d = finite_number(model.get("delay_s"))
        if d is not None and d > 0:
            out["delay"] = d
    if "delay" not in out:
        # No delay from a broadband segment: the one the delay-aware least squares chose, if any.
        m = ident.extra.get("model")
        inv = m.get("inverse_dynamics") if isinstance(m, dict) else None
        if isinstance(inv, dict) and "delay" in (inv.get("terms") or []):
            d = finite_number(inv.get("delay_s"))
            if d is not None and d > 0:
                out["delay"] = d
    if spec is not None:
        if _spec_states_mode(spec):
            # The spec states its own mode: the log's second mode belonged to the log's first.
            for key in ("mode2_hz", "mode2_damping", "mode2_ratio", "mode2_load_side"):
                out.pop(key, None)
        if spec.plant_mode_hz is not None:
            out["mode_hz"] = spec.plant_mode_hz
        if spec.plant_mode_damping is not None:
            out["mode_damping"] = spec.plant_mode_damping
        if spec.plant_mode_ratio is not None:
            out["mode_ratio"] = spec.plant_mode_ratio
        if spec.plant_encoder is not None:
            out["mode_load_side"] = spec.plant_encoder == "load"
        if spec.plant_delay_samples is not None:
            out["delay"] = spec.plant_delay_samples * spec.period
    return out


def plant_holds_fit(ident: Identification, spec: Spec | None = None) -> bool:
    """The plant of :func:`plant_dynamics` holds every structural mode the log's response was fitted with.

    The simulator's plant holds one mode, or two as two appendages on the motor.  A fit with more
    modes, or two that no such plant shows (``frequency_response.model.n_modes`` above the modes
    ``mode_hz``/``mode2_hz`` keep; identify's ``note`` says which it kept), leaves a plant that is
    neither the data nor the fit: a margin it misses may be the dropped modes' absence, not the
    machine's.  True without a fitted response (nothing dropped) and where the spec's ``[plant]``
    states the mode (the user's plant, not the log's).
    """
    if spec is not None and _spec_states_mode(spec):
        return True
    fr = ident.extra.get("frequency_response")
    model = fr.get("model") if isinstance(fr, dict) else None
    fitted = finite_number(model.get("n_modes")) if isinstance(model, dict) else None
    if fitted is None:
        return True
    held = sum(1 for m in ("mode", "mode2") if f"{m}_hz" in plant_dynamics(ident, spec))
    return held >= fitted


def identified_plant(ident: Identification, spec: Spec | None = None) -> np.ndarray:
    """The plant vector of the identified model (CONTRACT §2 parameters).

    A Coulomb-only model (``fs`` absent) gets ``fs = fc`` (vs, xi then
    irrelevant).  Ripple comes from ``ident.extra["ripple"]`` =
    ``{"amplitude": u-unit, "pitch": m}`` when present.  The mode and the input
    delay are :func:`plant_dynamics` of ``ident`` and ``spec``.
    """
    par = ident.parameters
    fc = max(ident.value("fc"), 0.0)
    fs = par["fs"].value if par.get("fs") is not None else fc  # type: ignore[union-attr]
    vs = par["vs"].value if par.get("vs") is not None else 0.01  # type: ignore[union-attr]
    xi = par["xi"].value if par.get("xi") is not None else 2.0  # type: ignore[union-attr]
    amp, pitch = _ripple(ident)
    return plant_vector(M=ident.value("M"), B=max(ident.value("B"), 0.0), fc=fc, fs=max(fs, 0.0),
                        vs=vs if vs > 0 else 0.01, xi=xi if xi > 0 else 2.0,
                        offset=ident.value("offset"), ripple_amp=amp, ripple_pitch=pitch,
                        **plant_dynamics(ident, spec))  # type: ignore[arg-type]
