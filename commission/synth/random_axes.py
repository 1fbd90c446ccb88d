"""Random axes with known truth: :func:`random_axis` (the spread of real machines) and
:func:`rigid_random_axis` (the rigid axes some tests pin).
"""

from __future__ import annotations

import math

import numpy as np

from commission.synth.truth import AxisTruth


def _friction_and_encoder(rng: np.random.Generator, M: float) -> tuple[float, ...]:
    """Viscous and friction terms scaled by the mass ``M`` (u-unit s^2/m), and the encoder step, in draw order.

    Friction scales with the moving mass (bearing preload, cable chain): Coulomb deceleration
    fc / M of 1-6 m/s^2, as on real stages (paper: 3.7).  Returns ``(B, fc, fs, vs, xi, offset,
    ripple_amp, ripple_pitch, lsb)``.
    """

    def logu(lo: float, hi: float) -> float:
        return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))

    B = M * float(rng.uniform(3.0, 30.0))
    fc = M * logu(1.0, 6.0)
    fs = fc * float(rng.uniform(1.1, 1.6))
    vs = logu(0.003, 0.03)
    xi = float(rng.uniform(1.0, 2.5))
    offset = fc * float(rng.uniform(-0.3, 0.3))
    ripple_amp = fc * float(rng.uniform(0.0, 0.1))
    ripple_pitch = float(rng.uniform(0.02, 0.06))
    lsb = logu(0.05e-6, 1e-6)
    return B, fc, fs, vs, xi, offset, ripple_amp, ripple_pitch, lsb


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
    B, fc, fs, vs, xi, offset, ripple_amp, ripple_pitch, lsb = _friction_and_encoder(rng, M)
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
    B, fc, fs, vs, xi, offset, ripple_amp, ripple_pitch, lsb = _friction_and_encoder(rng, M)
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
