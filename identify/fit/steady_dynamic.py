"""The steady+dynamic method: friction from the legs, mass from the dynamics, alternated (steps 1-3)."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from commission.identify.errors import MassNotIdentifiableError
from commission.identify.ls import FrictionModel, ripple_pitches, solve
from commission.identify.signals import Preprocessed
from commission.identify.steady import SteadySegments
from commission.identify.units import unit
from commission.identify.fit.checks import _check_mass
from commission.identify.fit.friction_map import _map_fit, _stribeck_knee
from commission.identify.fit.result import _friction_force, _ripple_params


#: Alternations of the friction-map / mass steps.
N_ALTERNATIONS = 3

#: Where rows near reversals are cut from the mass fit, in multiples of the map's Stribeck speed vs
#: (the knee :func:`_stribeck_knee` is 3 vs), tried in turn while M is not identified.  3 vs keeps
#: the fit away from the Stribeck dip, whose shape the map extrapolates below its slowest leg; on an
#: axis whose dip reaches a good part of the moves' speeds (a high vs against a slow envelope) that
#: leaves too few accelerating rows, and M is refused although the legs determine the curve well.
#: At 1 vs the map's own curve, fitted on legs at those speeds, carries the
#: friction of the rows kept; the fit says so in a warning.
REVERSAL_CUTS = (3.0, 1.0)
#: Where rows near reversals are cut when the friction curve gives no Stribeck speed: this fraction of
#: the top speed (of the legs for the mass fit; of the log for the whole-log method's delta_d).
REVERSAL_FRACTION = 0.05
#: Least number of rows away from reversals that delta_d is taken over (fewer: every row).
MIN_MODEL_ROWS = 100


def moving_rows(pp: Preprocessed, v_ex: float) -> np.ndarray:
    """The decimated rows away from reversals: no sample within the anti-alias filter's reach slower than ``v_ex``.

    A row whose filter window saw a reversal or a stiction phase carries the filtered ``sign(qd)``
    column's error (the filtered velocity crosses zero at other times than the true one, and the
    axis sticks): the rigid-body model does not describe it.  The mass fit uses these rows only,
    and the Assumption-1 bound ``delta_d`` is taken over them (:attr:`AxisFit.model_rows`).

    Parameters
    ----------
    pp : Preprocessed
    v_ex : float
        Speed below which a sample counts as a reversal, m/s (<= 0: every row).

    Returns
    -------
    numpy.ndarray of bool
        One entry per decimated row.
    """
    if not v_ex > 0:
        return np.ones(pp.t_dec.shape[0], dtype=bool)
    slow = (np.abs(pp.qd) < v_ex).astype(np.uint8)
    low = ndimage.maximum_filter1d(slow, 4 * pp.decimation + 1, mode="nearest").astype(bool)
    return ~pp.decimate_mask(low)


def _steady_fit(pp: Preprocessed, segs: SteadySegments, friction: FrictionModel,
                ripple_pitch: float | tuple[float, ...] | None,
                reversal_speed: float | None, warnings: list[str],
                mass: float | None = None) -> tuple[dict[str, tuple[float, float]], np.ndarray, float]:
    """Friction from the legs, mass (and ripple) from the dynamics; ``mass`` given: M is known, not fitted."""
    # M starts at 0 in each alternation: the legs' mean acceleration is ~0; the first map fit needs no mass
    pitches = ripple_pitches(ripple_pitch)
    n_r = 2 * len(pitches)  # ripple coefficients: (sin, cos) per pitch
    if pitches:
        sc = [f(2.0 * np.pi * pp.q / pitch) for pitch in pitches for f in (np.sin, np.cos)]
        seg_sc = np.column_stack([segs.mean_over(c) for c in sc])
        X_rip = pp.decimate(np.column_stack([pp.qdd, *sc]))
    else:
        seg_sc = np.zeros((len(segs), 2))
        X_rip = pp.decimate(pp.qdd[:, None])
    n_m = 1 if mass is None else 0  # columns of X_rip before the ripple's
    if mass is not None:
        X_rip = X_rip[:, 1:]
    y_u = pp.decimate(pp.u)

    def usable_rows(v_ex: float) -> np.ndarray:
        rows = moving_rows(pp, v_ex)
        n_rows = int(rows.sum())
        if n_rows < 10 * X_rip.shape[1]:
            raise MassNotIdentifiableError(
                f"M: only {n_rows} decimated rows move faster than {v_ex:.3g} {unit('v')} away from reversals "
                "(need dynamic motion at speed for the mass)")
        return rows

    def alternate(cut: float, warnings: list[str]):
        # Pass 0 fits a Coulomb line (robust, never refused) to get provisional M and ripple:
        # a requested Stribeck fit needs the ripple removed from the slow legs first, which
        # sit on a short stretch of travel where the ripple does not average out.
        # Passes 1..N fit the requested model.
        M = 0.0 if mass is None else mass
        ripple_ab = np.zeros(max(n_r, 2))
        res = None  # no regression when the mass is given and there is no ripple
        for it in range(N_ALTERNATIONS + 1):
            F = segs.command - M * segs.acceleration - seg_sc @ ripple_ab
            model: FrictionModel = "coulomb" if it == 0 else friction
            # Keep the warnings of the last pass only: the earlier ones saw a provisional M.
            fr = _map_fit(segs.velocity, F, model, warnings if it == N_ALTERNATIONS else [])
            p = {k: v[0] for k, v in fr.items()}
            if it <= 1:
                v_ex = reversal_speed
                if v_ex is None:
                    knee = 3.0 * p["vs"] if "vs" in p else _stribeck_knee(segs.velocity, F)
                    if knee is not None:
                        v_ex = knee * cut / 3.0
                        scaled.add(it)
                    else:
                        v_ex = REVERSAL_FRACTION * float(np.max(np.abs(segs.velocity)))
                rows = usable_rows(v_ex)
                reversal = float(v_ex)
            y = y_u - pp.decimate(_friction_force(p, pp.qd)) - (0.0 if mass is None else mass * pp.decimate(pp.qdd))
            if X_rip.shape[1] == 0:  # known mass, no ripple: nothing to regress
                continue
            res = solve(X_rip[rows], y[rows])
            if mass is None:
                M = float(res.theta[0])
                _check_mass(M, float(res.std[0]), res.condition_number)
            if pitches:
                ripple_ab = np.asarray(res.theta[n_m:n_m + n_r])
        return M, res, fr, F, ripple_ab, reversal

    # A lower cut only where the default one refuses M (and nobody set the cut or the mass).
    cuts = REVERSAL_CUTS if reversal_speed is None and mass is None else REVERSAL_CUTS[:1]
    first: MassNotIdentifiableError | None = None
    scaled: set[int] = set()  # the passes whose row cut followed ``cut`` (a Stribeck speed was known)
    for cut in cuts:
        w: list[str] = []
        try:
            M, res, fr, F, ripple_ab, reversal = alternate(cut, w)
        except MassNotIdentifiableError as exc:
            first = first or exc
            if cut == cuts[-1] or not scaled:  # a lower cut would select the same rows
                raise first from None
            continue
        if first is not None:
            w.append(f"M: fitted on the rows faster than {cut:g} vs = {reversal:.3g} {unit('v')} away from reversals; "
                     f"cut at {cuts[0]:g} vs, as by default, the rows left did not identify it ({first}); the "
                     f"friction map's Stribeck curve, fitted on the legs, carries the friction of the slower rows kept")
        warnings.extend(w)
        break
    params: dict[str, tuple[float, float]] = {"M": (M, float(res.std[0])) if mass is None else (mass, 0.0)}
    params.update(fr)
    for k in range(len(pitches)):
        i = n_m + 2 * k
        params.update(_ripple_params(ripple_ab[2 * k], ripple_ab[2 * k + 1], np.asarray(res.cov)[i:i + 2, i:i + 2], k))
    # The map points as the final friction fit saw them.
    return params, np.column_stack([segs.velocity, F]), reversal
