"""Sampled-data plant of a linear-motor axis (paper eq. 1-4), sub-stepped.

Model, in command units (the contract's sign convention)::

    M qdd = u + d(t) - offset - B qd - Ff(qd) - ripple(q)
    Ff(v) = [fc + (fs - fc) exp(-|v/vs|^xi)] sign(v)
    ripple(q) = A_r sin(2 pi q / pitch)

Stiction scheme (stated because a naive integrator chatters at v = 0): a
switch model (Karnopp/Leine) on a fixed-step semi-implicit Euler integrator.

* Sliding (v != 0): integrate with the friction of the current velocity.  If a
  step would carry v through zero, the axis stops exactly at v = 0 and enters
  the stuck state, instead of reversing with the wrong friction sign.
* Stuck (v == 0): the axis stays stuck while the net non-friction force is at
  most the static level fs (friction balances it); otherwise it breaks away
  with acceleration (F - fs sign F) / M.

With h a small fraction of the sample period (default 10 sub-steps), this
keeps stick-slip, reversals and break-away physical and bounded.

The ripple is evaluated at every sub-step, where a ``sin`` each time is a large
part of a run's cost (docs/scaling.md, "Tenth pass").  The state therefore
carries an anchor: a position
``x_a`` with ``A_r sin(k x_a)`` and ``A_r cos(k x_a)`` (``k = 2 pi / pitch``),
and the ripple at ``x`` is that pair rotated by ``d = k (x - x_a)``, with
``sin d`` and ``cos d`` from their Taylor series (terms to ``d^7`` and ``d^8``:
a truncation below ``1e-17`` for ``|d| <= RIPPLE_ROTATE_MAX``).  Beyond that
phase, and at the first sub-step of a run, the anchor moves to ``x`` and is
computed exactly.  Every value is a rotation from an exactly computed anchor,
never from the previous sub-step, so no error accumulates along a run: the
ripple equals ``A_r sin(k x)`` to a few units in the last place of ``A_r``.

Beyond the rigid body (paper eq. 1), two things every real axis has and that
cap its feedback bandwidth are first-class options of the same vector:

* **A structural mode**: the moving mass M splits into a motor side
  ``m1 = (1 - r) M`` (force, friction, ripple, viscous and offset act there) and
  a load ``m2 = r M`` coupled by a spring ``k`` and damper ``c``, chosen so that
  the free-free mode has the resonance ``f_r`` and damping ``zeta``::

      mu = m1 m2 / M,  k = (2 pi f_r)^2 mu,  c = 2 zeta (2 pi f_r) mu
      m1 x1'' = F_motor - k (x1 - x2) - c (v1 - v2)
      m2 x2'' = k (x1 - x2) + c (v1 - v2)

  The encoder reads ``x1`` (motor side: the response u -> q has an
  anti-resonance at ``f_r sqrt(1 - r)`` below the resonance) or ``x2`` (load
  side: a resonance only).  The coupled equations use the same semi-implicit
  Euler step, sub-divided so that ``2 pi f_r h <= 0.25`` (stable and within
  0.3 % of the mode's frequency).
* **A second structural mode** (optional, only beside the first): a second load
  ``m3 = r2 M`` hangs on the motor side through its own spring and damper, set the
  same way from ``f_2``, ``zeta_2`` with ``mu_2 = (1 - r2) M m3 / M``; the motor side keeps
  ``m1 = (1 - r - r2) M``.  Each of ``f_r``, ``f_2`` is the mode the appendage would have
  alone; coupled through the motor the two shift a little, and
  :func:`commission.controllers.linear.structural_modes` gives the true ones.  The encoder
  reads the motor side, the first load or (``mode2_load_side``) the second load: a scale on a
  bracket or a tool tip.  Sub-steps then follow a Gershgorin bound on the highest coupled
  frequency, so the step stays stable whatever the two modes' coupling.
* **An input delay** ``P_DELAY`` (s, fractional samples allowed): the command
  reaches the force ``P_DELAY`` after the controller issued it.  The plant
  itself is delay-free; the sampled loop (``controllers.simulate``) applies the
  delay exactly by switching the held command inside the sample.

Frequencies are in Hz and delays in seconds so that a plant vector does not
depend on the controller's rate.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# Layout of the plant parameter vector (float64[NP]).
P_M = 0  # mass, u-unit s^2/m
P_B = 1  # viscous, u-unit s/m
P_FC = 2  # Coulomb level, u-unit
P_FS = 3  # static (stiction) level, u-unit
P_VS = 4  # Stribeck velocity, m/s
P_XI = 5  # Stribeck exponent, -
P_OFFSET = 6  # constant force offset, u-unit (u_equiv = ... + offset)
P_RIPPLE_AMP = 7  # force-ripple amplitude, u-unit
P_RIPPLE_PITCH = 8  # force-ripple pitch, m (<= 0: no ripple)
P_MODE_HZ = 9  # structural-mode resonance, Hz (<= 0: rigid body)
P_MODE_DAMPING = 10  # damping ratio of the mode, -
P_MODE_RATIO = 11  # load fraction r = m2 / M of the moving mass, 0 < r < 1
P_MODE_LOAD_SIDE = 12  # 1: the encoder reads the load x2; 0: the motor side x1
P_DELAY = 13  # input delay, s (>= 0)
P_MODE2_HZ = 14  # second structural mode, Hz (<= 0: none; needs the first mode)
P_MODE2_DAMPING = 15  # its damping ratio, -
P_MODE2_RATIO = 16  # its load fraction r2 = m3 / M, with r + r2 < 1
P_MODE2_LOAD_SIDE = 17  # 1: the encoder reads the second load x3
NP = 18

#: Names of the plant vector's entries, in order (the keys of ``tuning.json``'s plants).
PLANT_NAMES = ("M", "B", "fc", "fs", "vs", "xi", "offset", "ripple_amp", "ripple_pitch",
               "mode_hz", "mode_damping", "mode_ratio", "mode_load_side", "delay",
               "mode2_hz", "mode2_damping", "mode2_ratio", "mode2_load_side")
#: Their units ("u" stands for the command unit).
PLANT_UNITS = ("u s^2/m", "u s/m", "u", "u", "m/s", "1", "u", "u", "m", "Hz", "1", "1", "1", "s",
               "Hz", "1", "1", "1")

#: Layout of the plant's integration state (float64[NX]).
X_MOTOR = 0  # motor-side position x1, m
V_MOTOR = 1  # motor-side velocity, m/s
X_LOAD = 2  # load position x2, m (= x1 on a rigid plant)
V_LOAD = 3  # load velocity, m/s
X_LOAD2 = 4  # second load's position x3, m (= x1 without a second mode)
V_LOAD2 = 5  # second load's velocity, m/s
X_ANCHOR = 6  # where the ripple's rotation is anchored, m (nan: not yet; module docstring)
S_ANCHOR = 7  # A_r sin(k x_a), u-unit
C_ANCHOR = 8  # A_r cos(k x_a), u-unit
NX = 9
#: Largest phase (rad) the ripple is rotated from its anchor before the anchor moves.
RIPPLE_ROTATE_MAX = 0.05
#: Largest 2 pi f_r h of one integration step of the mode.
MODE_STEP = 0.25


def plant_vector(M: float, B: float, fc: float = 0.0, fs: float | None = None,
                 vs: float = 0.01, xi: float = 2.0, offset: float = 0.0,
                 ripple_amp: float = 0.0, ripple_pitch: float = 0.0, *, mode_hz: float = 0.0,
                 mode_damping: float = 0.02, mode_ratio: float = 0.5, mode_load_side: bool = False,
                 delay: float = 0.0, mode2_hz: float = 0.0, mode2_damping: float = 0.02,
                 mode2_ratio: float = 0.1, mode2_load_side: bool = False) -> np.ndarray:
    """Pack plant parameters into the float64 vector the kernels take.

    Parameters
    ----------
    M : float
        Mass, u-unit s^2/m.
    B : float
        Viscous coefficient, u-unit s/m.
    fc, fs : float
        Coulomb and static friction levels, u-unit (``fs`` defaults to ``fc``).
    vs : float
        Stribeck velocity, m/s.
    xi : float
        Stribeck exponent.
    offset : float
        Constant force offset, u-unit.
    ripple_amp : float
        Force-ripple amplitude, u-unit.
    ripple_pitch : float
        Force-ripple pitch, m; 0 disables ripple.
    mode_hz : float
        Resonance of the structural mode, Hz; 0: rigid body.
    mode_damping : float
        Damping ratio of the mode, in [0, 1).
    mode_ratio : float
        Load fraction m2 / M, in (0, 1).
    mode_load_side : bool
        The encoder reads the load (True) or the motor side (False).
    delay : float
        Input delay, s.
    mode2_hz, mode2_damping, mode2_ratio : float
        Second structural mode (Hz, 0: none), its damping ratio and load fraction ``m3 / M``;
        it needs the first mode and ``mode_ratio + mode2_ratio < 1``.
    mode2_load_side : bool
        The encoder reads the second load (it takes precedence over ``mode_load_side``).
    """
    if not (M > 0 and B >= 0 and fc >= 0 and vs > 0 and xi > 0):
        raise ValueError(f"plant_vector: need M > 0, B >= 0, fc >= 0, vs > 0, xi > 0; got M={M}, B={B}, fc={fc}, vs={vs}, xi={xi}")
    if not (mode_hz >= 0 and 0 <= mode_damping < 1 and 0 < mode_ratio < 1 and delay >= 0
            and math.isfinite(mode_hz) and math.isfinite(delay)):
        raise ValueError(f"plant_vector: need mode_hz >= 0, 0 <= mode_damping < 1, 0 < mode_ratio < 1, delay >= 0; "
                         f"got mode_hz={mode_hz}, mode_damping={mode_damping}, mode_ratio={mode_ratio}, delay={delay}")
    p = np.zeros(NP)
    p[P_M], p[P_B], p[P_FC] = M, B, fc
    p[P_FS] = fc if fs is None else fs
    p[P_VS], p[P_XI], p[P_OFFSET] = vs, xi, offset
    p[P_RIPPLE_AMP], p[P_RIPPLE_PITCH] = ripple_amp, ripple_pitch
    p[P_MODE_HZ], p[P_MODE_DAMPING], p[P_MODE_RATIO] = mode_hz, mode_damping, mode_ratio
    p[P_MODE_LOAD_SIDE] = 1.0 if mode_load_side else 0.0
    p[P_DELAY] = delay
    if mode2_hz:
        if not (math.isfinite(mode2_hz) and mode2_hz > 0 and mode_hz > 0 and 0 <= mode2_damping < 1
                and 0 < mode2_ratio and mode_ratio + mode2_ratio < 1):
            raise ValueError(f"plant_vector: a second mode needs mode2_hz > 0 beside a first mode (mode_hz > 0), "
                             f"0 <= mode2_damping < 1, mode2_ratio > 0 and mode_ratio + mode2_ratio < 1; got "
                             f"mode_hz={mode_hz}, mode2_hz={mode2_hz}, mode2_damping={mode2_damping}, "
                             f"mode_ratio={mode_ratio}, mode2_ratio={mode2_ratio}")
        p[P_MODE2_HZ], p[P_MODE2_DAMPING], p[P_MODE2_RATIO] = mode2_hz, mode2_damping, mode2_ratio
        p[P_MODE2_LOAD_SIDE] = 1.0 if mode2_load_side else 0.0
    return p


@njit(cache=True)
def stribeck_cut(p):
    """Speed (m/s) above which the Stribeck term no longer changes the friction level in float64.

    Above it, ``(fs - fc) exp(-|v/vs|^xi) < 2**-60 fc``, less than half a unit in the last
    place of ``fc``, so ``fc + (fs - fc) exp(...)`` rounds to ``fc`` exactly: :func:`stribeck`
    may return ``fc`` without evaluating the power and the exponential (the plant's most
    expensive operations) and still give the same value to the last bit.  ``inf`` where no
    such speed exists (``fc <= 0``); 0 for Coulomb-only friction (``fs == fc``).
    """
    ds = p[P_FS] - p[P_FC]
    if ds == 0.0:
        return 0.0
    if p[P_FC] <= 0.0 or p[P_VS] <= 0.0 or p[P_XI] <= 0.0:
        return math.inf
    big = math.log(abs(ds) / p[P_FC]) + 60.0 * math.log(2.0)
    if big <= 0.0:
        return 0.0
    return p[P_VS] * big ** (1.0 / p[P_XI]) * (1.0 + 1e-12)


@njit(cache=True)
def stribeck(p, v, v_cut=math.inf):
    """Nonlinear friction Ff(v) of the plant ``p`` (without the viscous part), u-unit.

    ``v_cut`` (:func:`stribeck_cut`, computed once per integration call) skips the curve where
    it cannot change the result.
    """
    if v == 0.0:
        return 0.0
    if abs(v) > v_cut:
        level = p[P_FC]
    else:
        r = abs(v / p[P_VS])
        if p[P_XI] == 2.0:
            r = r * r  # pow is correctly rounded here too: the same value, without the call
        elif p[P_XI] != 1.0:
            r = r ** p[P_XI]
        level = p[P_FC] + (p[P_FS] - p[P_FC]) * math.exp(-r)
    return level if v > 0.0 else -level


@njit(cache=True)
def ripple(p, x):
    """Force ripple at position ``x`` (m), u-unit."""
    if p[P_RIPPLE_PITCH] <= 0.0:
        return 0.0
    return p[P_RIPPLE_AMP] * math.sin(2.0 * math.pi * x / p[P_RIPPLE_PITCH])


@njit(cache=True, nogil=True)
def ripple_wavenumber(p):
    """``k = 2 pi / pitch`` of the plant's ripple, rad/m (0: no ripple)."""
    return 2.0 * math.pi / p[P_RIPPLE_PITCH] if p[P_RIPPLE_PITCH] > 0.0 else 0.0


@njit(cache=True, nogil=True)
def ripple_anchored(p, st, x, kr):
    """:func:`ripple` at ``x`` (m), u-unit, rotated from the anchor kept in the state ``st``.

    ``kr``: :func:`ripple_wavenumber` (rad/m).  The anchor moves to ``x`` (and is computed exactly) when
    the phase from it exceeds :data:`RIPPLE_ROTATE_MAX` or there is none (NaN): module docstring.
    """
    xa = st[X_ANCHOR]
    d = kr * (x - xa)
    if not (abs(d) <= RIPPLE_ROTATE_MAX):  # nan anchor too
        th = kr * x
        st[X_ANCHOR] = x
        st[S_ANCHOR] = p[P_RIPPLE_AMP] * math.sin(th)
        st[C_ANCHOR] = p[P_RIPPLE_AMP] * math.cos(th)
        return st[S_ANCHOR]
    d2 = d * d
    sd = d * (1.0 - d2 * (1.0 / 6.0 - d2 * (1.0 / 120.0 - d2 * (1.0 / 5040.0))))
    cd = 1.0 - d2 * (0.5 - d2 * (1.0 / 24.0 - d2 * (1.0 / 720.0 - d2 * (1.0 / 40320.0))))
    return st[S_ANCHOR] * cd + st[C_ANCHOR] * sd


@njit(cache=True)
def plant_advance(p, x, v, u, h, n, v_cut=-1.0):
    """Advance the plant over ``n`` sub-steps of ``h`` seconds under a held input.

    The ripple's anchor (module docstring) lives for this call only; :func:`plant_step` keeps
    it in the state across calls.  The two agree to rounding.

    Parameters
    ----------
    p : float64[NP]
        Plant vector (:func:`plant_vector`).
    x, v : float
        Position (m) and velocity (m/s) at the start.
    u : float
        Held input including any disturbance, u-unit.
    h : float
        Sub-step, s.
    n : int
        Number of sub-steps.
    v_cut : float
        :func:`stribeck_cut` of ``p`` when the caller has it (a closed loop computes it once per
        run, not once per sample); negative: computed here.

    Returns
    -------
    x, v : float
        Position (m) and velocity (m/s) at the end.
    """
    st = np.empty(NX)
    st[X_ANCHOR] = math.nan
    return _advance_rigid(p, st, x, v, u, h, n, v_cut)


@njit(cache=True, nogil=True)
def _advance_rigid(p, st, x, v, u, h, n, v_cut):
    """The rigid body over ``n`` sub-steps (:func:`plant_advance`), the ripple's anchor in ``st``."""
    M = p[P_M]
    if v_cut < 0.0:
        v_cut = stribeck_cut(p)
    kr = ripple_wavenumber(p)  # once per call, not per sub-step
    for _ in range(n):
        F = u - p[P_OFFSET] - (ripple_anchored(p, st, x, kr) if kr > 0.0 else 0.0)
        if v == 0.0:
            if abs(F) <= p[P_FS]:
                continue  # stuck: static friction balances F
            a = (F - math.copysign(p[P_FS], F)) / M
            v = a * h
        else:
            a = (F - p[P_B] * v - stribeck(p, v, v_cut)) / M
            v_new = v + a * h
            if v_new * v < 0.0 and p[P_FS] > 0.0:
                v_new = 0.0  # crossed zero: stop, next sub-step decides stick or slip (only static friction can hold it)
            v = v_new
        x += v * h
    return x, v


@njit(cache=True, nogil=True)
def plant_start(p, st, x0):
    """Put the plant at rest at position ``x0`` (m): fill the state ``st`` (float64[NX])."""
    st[X_MOTOR] = x0
    st[V_MOTOR] = 0.0
    st[X_LOAD] = x0
    st[V_LOAD] = 0.0
    st[X_LOAD2] = x0
    st[V_LOAD2] = 0.0
    st[X_ANCHOR] = math.nan


@njit(cache=True, nogil=True)
def plant_output(p, st):
    """Position the encoder reads, m: the load on a load-side encoder, else the motor side."""
    if p[P_MODE2_HZ] > 0.0 and p[P_MODE2_LOAD_SIDE] > 0.5:
        return st[X_LOAD2]
    if p[P_MODE_HZ] > 0.0 and p[P_MODE_LOAD_SIDE] > 0.5:
        return st[X_LOAD]
    return st[X_MOTOR]


@njit(cache=True, nogil=True, inline="always")
def _mode_setup(p, h):
    """The coupled masses' constants for sub-steps of ``h`` s (module docstring): ``(m1, m2, m3, k, c,
    k2, c2, two, split, hh)``, masses (u-unit s^2/m), springs (u-unit/m), dampers (u-unit s/m), whether
    there is a second mode, and the ``split`` integration steps of ``hh`` s each sub-step takes.

    :func:`plant_step` computes the same values in its own body: a call of this function there,
    even inlined, slowed a modal run measurably (docs/scaling.md, "Eleventh pass");
    ``tests/test_plant.py`` holds :func:`plant_step_pair`, which calls this, to it bit for bit.
    """
    M = p[P_M]
    r = p[P_MODE_RATIO]
    two = p[P_MODE2_HZ] > 0.0
    r2 = p[P_MODE2_RATIO] if two else 0.0
    m1 = (1.0 - r - r2) * M
    m2 = r * M
    mu = (1.0 - r) * M * m2 / M
    w = 2.0 * math.pi * p[P_MODE_HZ]
    k = w * w * mu
    c = 2.0 * p[P_MODE_DAMPING] * w * mu
    k2 = 0.0
    c2 = 0.0
    m3 = 1.0
    w_top = w
    if two:
        m3 = r2 * M
        mu2 = (1.0 - r2) * M * m3 / M
        w2 = 2.0 * math.pi * p[P_MODE2_HZ]
        k2 = w2 * w2 * mu2
        c2 = 2.0 * p[P_MODE2_DAMPING] * w2 * mu2
        # Gershgorin bound on the coupled stiffness matrix M^-1 K: no coupled frequency exceeds it
        w_top = math.sqrt(max(2.0 * (k + k2) / m1, 2.0 * k / m2, 2.0 * k2 / m3))
    split = int(math.ceil(w_top * h / MODE_STEP))
    if split < 1:
        split = 1
    return m1, m2, m3, k, c, k2, c2, two, split, h / split


@njit(cache=True, nogil=True)
def plant_step(p, st, u, h, n, v_cut=-1.0):
    """Advance the plant state ``st`` in place over ``n`` sub-steps of ``h`` s under the held input ``u``.

    A rigid plant (``p[P_MODE_HZ] <= 0``) is :func:`plant_advance`, with the load
    coordinates kept equal to the motor's; a plant with one or two modes integrates the
    coupled masses (module docstring) with the same stiction scheme on the
    motor side.  Without a second mode, the second load's coordinates follow the motor's.
    ``v_cut``: as in :func:`plant_advance`.
    """
    if p[P_MODE_HZ] <= 0.0:
        x, v = _advance_rigid(p, st, st[X_MOTOR], st[V_MOTOR], u, h, n, v_cut)
        st[X_MOTOR] = x
        st[V_MOTOR] = v
        st[X_LOAD] = x
        st[V_LOAD] = v
        st[X_LOAD2] = x
        st[V_LOAD2] = v
        return
    M = p[P_M]
    r = p[P_MODE_RATIO]
    two = p[P_MODE2_HZ] > 0.0
    r2 = p[P_MODE2_RATIO] if two else 0.0
    m1 = (1.0 - r - r2) * M
    m2 = r * M
    mu = (1.0 - r) * M * m2 / M
    w = 2.0 * math.pi * p[P_MODE_HZ]
    k = w * w * mu
    c = 2.0 * p[P_MODE_DAMPING] * w * mu
    k2 = 0.0
    c2 = 0.0
    m3 = 1.0
    w_top = w
    if two:
        m3 = r2 * M
        mu2 = (1.0 - r2) * M * m3 / M
        w2 = 2.0 * math.pi * p[P_MODE2_HZ]
        k2 = w2 * w2 * mu2
        c2 = 2.0 * p[P_MODE2_DAMPING] * w2 * mu2
        # Gershgorin bound on the coupled stiffness matrix M^-1 K: no coupled frequency exceeds it
        w_top = math.sqrt(max(2.0 * (k + k2) / m1, 2.0 * k / m2, 2.0 * k2 / m3))
    split = int(math.ceil(w_top * h / MODE_STEP))
    if split < 1:
        split = 1
    hh = h / split
    if v_cut < 0.0:
        v_cut = stribeck_cut(p)
    x1 = st[X_MOTOR]
    v1 = st[V_MOTOR]
    x2 = st[X_LOAD]
    v2 = st[V_LOAD]
    x3 = st[X_LOAD2]
    v3 = st[V_LOAD2]
    kr = ripple_wavenumber(p)  # once per call, not per sub-step
    for _ in range(n * split):
        fk = k * (x1 - x2) + c * (v1 - v2)  # spring and damper force on the load
        fk2 = k2 * (x1 - x3) + c2 * (v1 - v3) if two else 0.0
        F = u - p[P_OFFSET] - (ripple_anchored(p, st, x1, kr) if kr > 0.0 else 0.0) - fk - fk2
        if v1 == 0.0:
            if abs(F) <= p[P_FS]:
                v1n = 0.0
            else:
                v1n = (F - math.copysign(p[P_FS], F)) / m1 * hh
        else:
            v1n = v1 + (F - p[P_B] * v1 - stribeck(p, v1, v_cut)) / m1 * hh
            if v1n * v1 < 0.0 and p[P_FS] > 0.0:
                v1n = 0.0
        v2 = v2 + fk / m2 * hh
        if two:
            v3 = v3 + fk2 / m3 * hh
        v1 = v1n
        x1 += v1 * hh
        x2 += v2 * hh
        if two:
            x3 += v3 * hh
    if not two:
        x3 = x1
        v3 = v1
    st[X_MOTOR] = x1
    st[V_MOTOR] = v1
    st[X_LOAD] = x2
    st[V_LOAD] = v2
    st[X_LOAD2] = x3
    st[V_LOAD2] = v3


@njit(cache=True, nogil=True)
def plant_steps(p, h):
    """Integration steps per sub-step of ``h`` s that :func:`plant_step` takes: 0 for a rigid plant
    (one step of the rigid kind), else the modal split (:func:`_mode_setup`).  Two plants with
    equal ``plant_steps`` are interleaved by :func:`plant_step_pair`."""
    if p[P_MODE_HZ] <= 0.0:
        return 0
    return _mode_setup(p, h)[8]


@njit(cache=True, nogil=True)
def _one_mode_pair(pa, sta, ua, pb, stb, ub, n, m1a, m2a, ka, ca, hha, kra, v_cut_a, m1b, m2b, kb, cb, hhb, krb,
                   v_cut_b):
    """:func:`plant_step_pair`'s loop for two plants of one mode each (``n`` steps of ``hha``, ``hhb``
    s), without the second mode's terms: :func:`plant_step`'s values (there ``fk2`` is 0, and
    ``F - 0.0`` is ``F`` in IEEE arithmetic, and the second load follows the motor side) with a loop
    the compiler need not branch in."""
    x1a = sta[X_MOTOR]
    v1a = sta[V_MOTOR]
    x2a = sta[X_LOAD]
    v2a = sta[V_LOAD]
    x1b = stb[X_MOTOR]
    v1b = stb[V_MOTOR]
    x2b = stb[X_LOAD]
    v2b = stb[V_LOAD]
    for _ in range(n):
        fka = ka * (x1a - x2a) + ca * (v1a - v2a)
        fkb = kb * (x1b - x2b) + cb * (v1b - v2b)
        Fa = ua - pa[P_OFFSET] - (ripple_anchored(pa, sta, x1a, kra) if kra > 0.0 else 0.0) - fka
        Fb = ub - pb[P_OFFSET] - (ripple_anchored(pb, stb, x1b, krb) if krb > 0.0 else 0.0) - fkb
        if v1a == 0.0:
            if abs(Fa) <= pa[P_FS]:
                v1na = 0.0
            else:
                v1na = (Fa - math.copysign(pa[P_FS], Fa)) / m1a * hha
        else:
            v1na = v1a + (Fa - pa[P_B] * v1a - stribeck(pa, v1a, v_cut_a)) / m1a * hha
            if v1na * v1a < 0.0 and pa[P_FS] > 0.0:
                v1na = 0.0
        if v1b == 0.0:
            if abs(Fb) <= pb[P_FS]:
                v1nb = 0.0
            else:
                v1nb = (Fb - math.copysign(pb[P_FS], Fb)) / m1b * hhb
        else:
            v1nb = v1b + (Fb - pb[P_B] * v1b - stribeck(pb, v1b, v_cut_b)) / m1b * hhb
            if v1nb * v1b < 0.0 and pb[P_FS] > 0.0:
                v1nb = 0.0
        v2a = v2a + fka / m2a * hha
        v2b = v2b + fkb / m2b * hhb
        v1a = v1na
        v1b = v1nb
        x1a += v1a * hha
        x1b += v1b * hhb
        x2a += v2a * hha
        x2b += v2b * hhb
    sta[X_MOTOR] = x1a
    sta[V_MOTOR] = v1a
    sta[X_LOAD] = x2a
    sta[V_LOAD] = v2a
    sta[X_LOAD2] = x1a
    sta[V_LOAD2] = v1a
    stb[X_MOTOR] = x1b
    stb[V_MOTOR] = v1b
    stb[X_LOAD] = x2b
    stb[V_LOAD] = v2b
    stb[X_LOAD2] = x1b
    stb[V_LOAD2] = v1b


@njit(cache=True, nogil=True)
def plant_step_pair(pa, sta, ua, ha, pb, stb, ub, hb, n, v_cut_a, v_cut_b):
    """:func:`plant_step` of two plants at once, ``n`` sub-steps each (of ``ha`` and ``hb`` s, under
    the held inputs ``ua`` and ``ub``): the same values to the last bit as the two calls.

    One sub-step of a plant is a chain of dependent operations (the ripple at the new position,
    the friction at the new velocity, a division by the mass), each waiting for the one before:
    a core runs it at that chain's latency, most of its units idle.  Two independent plants
    advanced in one loop give the core two chains to overlap, at little more than the cost of
    one.  They are interleaved when both are rigid, or both modal with the same split
    (:func:`plant_steps`); otherwise advanced one after the other.

    Each loop body here is :func:`_advance_rigid`'s or :func:`plant_step`'s written out for two
    plants, not a call of a shared per-step function: that call, even inlined, slowed a rigid run
    measurably (docs/scaling.md, "Eleventh pass").  ``tests/test_plant.py`` holds the pair to
    the two single calls bit for bit.  ``v_cut_a``, ``v_cut_b``: as in :func:`plant_advance`
    (negative: computed here).
    """
    if v_cut_a < 0.0:
        v_cut_a = stribeck_cut(pa)
    if v_cut_b < 0.0:
        v_cut_b = stribeck_cut(pb)
    kra = ripple_wavenumber(pa)
    krb = ripple_wavenumber(pb)
    if pa[P_MODE_HZ] <= 0.0 and pb[P_MODE_HZ] <= 0.0:
        Ma = pa[P_M]
        Mb = pb[P_M]
        xa = sta[X_MOTOR]
        va = sta[V_MOTOR]
        xb = stb[X_MOTOR]
        vb = stb[V_MOTOR]
        for _ in range(n):
            Fa = ua - pa[P_OFFSET] - (ripple_anchored(pa, sta, xa, kra) if kra > 0.0 else 0.0)
            Fb = ub - pb[P_OFFSET] - (ripple_anchored(pb, stb, xb, krb) if krb > 0.0 else 0.0)
            if va == 0.0:
                if not abs(Fa) <= pa[P_FS]:  # else stuck
                    a = (Fa - math.copysign(pa[P_FS], Fa)) / Ma
                    va = a * ha
                    xa += va * ha
            else:
                a = (Fa - pa[P_B] * va - stribeck(pa, va, v_cut_a)) / Ma
                v_new = va + a * ha
                if v_new * va < 0.0 and pa[P_FS] > 0.0:
                    v_new = 0.0
                va = v_new
                xa += va * ha
            if vb == 0.0:
                if not abs(Fb) <= pb[P_FS]:
                    b = (Fb - math.copysign(pb[P_FS], Fb)) / Mb
                    vb = b * hb
                    xb += vb * hb
            else:
                b = (Fb - pb[P_B] * vb - stribeck(pb, vb, v_cut_b)) / Mb
                v_new = vb + b * hb
                if v_new * vb < 0.0 and pb[P_FS] > 0.0:
                    v_new = 0.0
                vb = v_new
                xb += vb * hb
        sta[X_MOTOR] = xa
        sta[V_MOTOR] = va
        sta[X_LOAD] = xa
        sta[V_LOAD] = va
        sta[X_LOAD2] = xa
        sta[V_LOAD2] = va
        stb[X_MOTOR] = xb
        stb[V_MOTOR] = vb
        stb[X_LOAD] = xb
        stb[V_LOAD] = vb
        stb[X_LOAD2] = xb
        stb[V_LOAD2] = vb
        return
    if pa[P_MODE_HZ] > 0.0 and pb[P_MODE_HZ] > 0.0:
        m1a, m2a, m3a, ka, ca, k2a, c2a, twoa, splita, hha = _mode_setup(pa, ha)
        m1b, m2b, m3b, kb, cb, k2b, c2b, twob, splitb, hhb = _mode_setup(pb, hb)
        if splita == splitb and not twoa and not twob:
            _one_mode_pair(pa, sta, ua, pb, stb, ub, n * splita, m1a, m2a, ka, ca, hha, kra, v_cut_a,
                           m1b, m2b, kb, cb, hhb, krb, v_cut_b)
            return
        if splita == splitb:
            x1a = sta[X_MOTOR]
            v1a = sta[V_MOTOR]
            x2a = sta[X_LOAD]
            v2a = sta[V_LOAD]
            x3a = sta[X_LOAD2]
            v3a = sta[V_LOAD2]
            x1b = stb[X_MOTOR]
            v1b = stb[V_MOTOR]
            x2b = stb[X_LOAD]
            v2b = stb[V_LOAD]
            x3b = stb[X_LOAD2]
            v3b = stb[V_LOAD2]
            for _ in range(n * splita):
                fka = ka * (x1a - x2a) + ca * (v1a - v2a)
                fkb = kb * (x1b - x2b) + cb * (v1b - v2b)
                fk2a = k2a * (x1a - x3a) + c2a * (v1a - v3a) if twoa else 0.0
                fk2b = k2b * (x1b - x3b) + c2b * (v1b - v3b) if twob else 0.0
                Fa = ua - pa[P_OFFSET] - (ripple_anchored(pa, sta, x1a, kra) if kra > 0.0 else 0.0) - fka - fk2a
                Fb = ub - pb[P_OFFSET] - (ripple_anchored(pb, stb, x1b, krb) if krb > 0.0 else 0.0) - fkb - fk2b
                if v1a == 0.0:
                    if abs(Fa) <= pa[P_FS]:
                        v1na = 0.0
                    else:
                        v1na = (Fa - math.copysign(pa[P_FS], Fa)) / m1a * hha
                else:
                    v1na = v1a + (Fa - pa[P_B] * v1a - stribeck(pa, v1a, v_cut_a)) / m1a * hha
                    if v1na * v1a < 0.0 and pa[P_FS] > 0.0:
                        v1na = 0.0
                if v1b == 0.0:
                    if abs(Fb) <= pb[P_FS]:
                        v1nb = 0.0
                    else:
                        v1nb = (Fb - math.copysign(pb[P_FS], Fb)) / m1b * hhb
                else:
                    v1nb = v1b + (Fb - pb[P_B] * v1b - stribeck(pb, v1b, v_cut_b)) / m1b * hhb
                    if v1nb * v1b < 0.0 and pb[P_FS] > 0.0:
                        v1nb = 0.0
                v2a = v2a + fka / m2a * hha
                v2b = v2b + fkb / m2b * hhb
                if twoa:
                    v3a = v3a + fk2a / m3a * hha
                if twob:
                    v3b = v3b + fk2b / m3b * hhb
                v1a = v1na
                v1b = v1nb
                x1a += v1a * hha
                x1b += v1b * hhb
                x2a += v2a * hha
                x2b += v2b * hhb
                if twoa:
                    x3a += v3a * hha
                if twob:
                    x3b += v3b * hhb
            if not twoa:
                x3a = x1a
                v3a = v1a
            if not twob:
                x3b = x1b
                v3b = v1b
            sta[X_MOTOR] = x1a
            sta[V_MOTOR] = v1a
            sta[X_LOAD] = x2a
            sta[V_LOAD] = v2a
            sta[X_LOAD2] = x3a
            sta[V_LOAD2] = v3a
            stb[X_MOTOR] = x1b
            stb[V_MOTOR] = v1b
            stb[X_LOAD] = x2b
            stb[V_LOAD] = v2b
            stb[X_LOAD2] = x3b
            stb[V_LOAD2] = v3b
            return
    plant_step(pa, sta, ua, ha, n, v_cut_a)
    plant_step(pb, stb, ub, hb, n, v_cut_b)
