"""A structural mode above Nyquist is identified where it is, not at its alias (known truth).

A sampled log shows a mode at ``f > fs / 2`` as a resonance near its alias ``fs - f``, and a
mode the encoder reads on one side looks like one on the other.  Fitted below Nyquist only, such
a mode landed as a compromise near Nyquist that the data departed from, which cut the backed
band (and the loops bounded by it) to about half the coherent one.  The exact sampled model
tells the two apart: here simulated axes at 2 kHz, each recording a commissioning log with a
broadband injection, must come back with the true coupled mode
(:func:`commission.controllers.linear.structural_modes`), on the true side of the encoder, with
the band backed up to the coherent top; a real mode high below Nyquist stays where it is.
"""

from __future__ import annotations

import numpy as np
import pytest

from commission.controllers.linear import structural_modes
from commission.identification import identify_log
from commission.synth import AxisTruth, ExcitationPlan, simulate_excitation, write_log_h5

#: The shortened commissioning run of tests/test_frf.py (about 23 s, 3 s of PRBS on two slow legs).
PLAN = ExcitationPlan(n_speeds=5, ms_duration=6.0, leg_max_time=0.8, injection_s=3.0)


def _axis(mode_hz: float, load_side: bool, ratio: float, damping: float) -> AxisTruth:
    return AxisTruth(M=0.3, B=1.0, fc=0.2, fs=0.25, vs=0.01, xi=2.0, offset=0.01, lsb=0.1e-6, sample_rate=2000.0,
                     noise_std=0.1e-6, mode_hz=mode_hz, mode_damping=damping, mode_ratio=ratio,
                     mode_load_side=load_side, delay=0.6 / 2000.0)


AXES = {
    # Above Nyquist (1 kHz), the encoder on the motor: its alias looks like a load-side mode near 950 Hz.
    "motor_1050": _axis(1050.0, False, 0.2, 0.025),
    # Above Nyquist, the encoder on the load: its alias looks like a motor-side mode near 880 Hz.
    "load_1120": _axis(1120.0, True, 0.4, 0.04),
    # Below Nyquist, high: stays where it is (its mirror, 1.18 kHz, is within the fit's reach too).
    "load_820": _axis(820.0, True, 0.4, 0.04),
}


@pytest.fixture(scope="module")
def identified(tmp_path_factory) -> dict[str, dict]:
    out = {}
    for name, truth in AXES.items():
        path = tmp_path_factory.mktemp(name) / f"{name}.h5"
        write_log_h5(path, simulate_excitation(truth, PLAN, np.random.default_rng(5)))
        out[name] = identify_log(str(path)).ident.to_dict()["frequency_response"]
    return out


@pytest.mark.parametrize("name", sorted(AXES))
def test_the_mode_is_found_where_it_is_on_its_side_and_backs_the_band(identified, name):
    truth = AXES[name]
    fr = identified[name]
    (f_true, z_true), = structural_modes(truth.plant())
    q = fr["fit_quality"]
    assert q["n_modes"] == 1
    assert fr["model"]["mode_hz"] == pytest.approx(f_true, rel=0.02)
    assert fr["model"]["mode_damping"] == pytest.approx(z_true, rel=0.35)
    assert q["structure"] == ("load_side_mode" if truth.mode_load_side else "motor_side_mode")
    # The fit explains the data: no departure, and the band the model is backed in reaches the coherent top.
    assert not fr["departures"]
    assert fr["evidence_band_hz"][1] >= 0.9 * fr["coherent_up_to_hz"]
