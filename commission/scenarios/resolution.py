"""How finely a scenario is simulated and what its encoder shows: the plant's sub-steps per
controller sample (:func:`plant_substeps`), the encoder's resolution (:func:`resolve_quantization`)
and its noise (:func:`resolve_encoder_noise`), the same in ``tune`` and ``validate``."""

from __future__ import annotations

import math

from commission.artifacts import Identification
from commission.scenarios.identified import finite_number
from commission.spec import DEFAULT_QUANTIZATION, Spec

#: Plant sub-steps per controller sample at and below the paper's 2.5 kHz (a 40 us plant step there).
PLANT_SUBSTEPS = 10
#: Longest plant integration step above 2.5 kHz, s: the paper's 10 sub-steps of 400 us.
PLANT_STEP = 4e-5


def plant_substeps(sample_rate: float) -> int:
    """Plant sub-steps per controller sample in tune's and validate's simulations.

    :data:`PLANT_SUBSTEPS` (10) at and below the paper's 2.5 kHz, where the paper's Table 1
    is reproduced with them; above, as many as keep the plant step at or below the paper's
    40 us (:data:`PLANT_STEP`): 7 at 4 kHz, 5 at 5 kHz.  A finer step there buys no accuracy
    the encoder shows (measured: docs/robustness.md, "The plant step above 2.5 kHz").

    Parameters
    ----------
    sample_rate : float
        Controller sample rate, Hz.
    """
    if sample_rate <= 2500.0:
        return PLANT_SUBSTEPS
    return max(1, math.ceil(1.0 / (sample_rate * PLANT_STEP) - 1e-9))


def resolve_quantization(ident: Identification, spec: Spec) -> float:
    """Encoder resolution used in simulation, m.

    The spec's ``controller.quantization``; else ident.json's
    ``extra["encoder"]["quantization"]`` (what ``commission identify`` writes) or
    ``extra["quantization"]``; else :data:`commission.spec.DEFAULT_QUANTIZATION` (1 um).
    """
    if spec.quantization is not None:
        return float(spec.quantization)
    enc = ident.extra.get("encoder")
    for q in ((enc.get("quantization") if isinstance(enc, dict) else None), ident.extra.get("quantization")):
        v = finite_number(q)
        if v is not None and v >= 0:
            return v
    return DEFAULT_QUANTIZATION


def resolve_encoder_noise(ident: Identification, spec: Spec) -> float:
    """Encoder noise simulated, m rms: the spec's ``[plant] noise_std``, else ident.json's
    ``extra["encoder"]["noise_std"]``, else 0 (quantization only)."""
    if spec.plant_noise_std is not None:
        return float(spec.plant_noise_std)
    enc = ident.extra.get("encoder")
    v = finite_number(enc.get("noise_std")) if isinstance(enc, dict) else None
    return v if v is not None and v >= 0 else 0.0
