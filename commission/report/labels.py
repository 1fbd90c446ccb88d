"""Every word table of the report: index headings, case titles, criterion and parameter wording,
figure captions.

The performance indexes' names, labels, units, display scales and formats are the one table of
:data:`commission.controllers.metrics.INDEX_TABLE` (Table 1 of Xu & Yao 2001: e_M, e_F, ‖e‖rms in
the small length unit, ‖u‖rms, ‖Δu‖rms in the command's unit, c_u; then the peak input); the
report only words the peak input its own way (:func:`index_heading`).  Markdown tables use "‖"
(U+2016) for the norm bars, since "|" separates cells.
"""

from __future__ import annotations

from dataclasses import replace

from commission.controllers.metrics import INDEX_NAMES, INDEX_ROWS

#: The rows of Table 1 of the paper, in its order.
TABLE1 = INDEX_NAMES
#: The indexes summed up over the Monte-Carlo plants (median and worst).
MONTE_CARLO = ("e_M", "e_F", "e_rms", "c_u", "u_peak")
#: Format of every cell of the Monte-Carlo table (c_u included: medians and worst values).
MONTE_CARLO_FORMAT = "{:.3g}"
#: The report's word for an index where it is not the table's label ("|" would split a Markdown cell).
_WORDING = {"u_peak": "peak command"}


def index_heading(key: str, small: str, u: str) -> str:
    """``label (unit)`` of index ``key`` as the report's tables print it.

    ``small`` is the scaled position unit (um, or urad on a rotary axis), ``u`` the command's unit.
    """
    row = INDEX_ROWS[key]
    return (replace(row, label=_WORDING[key]) if key in _WORDING else row).heading(small, u)


CASE_TITLE = {"case1": "Case 1 (sinusoid through filter (58))", "case2": "Case 2 (back-and-forth point-to-point moves)",
              "user": "The machine's own moves (spec [trajectory] file or [[trajectory.move]])"}
CRITERION_TEXT = {
    "divergence": "no divergence",
    "e_F": "e_F (final accuracy, last 2 s)",
    "e_M": "e_M (largest error)",
    "e_rms": "‖e‖rms",
    "c_u": "c_u (chattering)",
    "u_peak": "peak command below u_max",
    "arc_vs_pid_e_rms": "ARC ‖e‖rms / PID ‖e‖rms",
    "arc_vs_pid_median": "ARC vs PID ‖e‖rms factor, median per group",
    "arc_vs_pid_p90": "ARC vs PID ‖e‖rms factor, 90th percentile per group",
    "arc_vs_pid_nominal": "ARC / PID ‖e‖rms on the identified plant, per case (nominal and +1 sample)",
    "margins": "ARC stability margins, identified plant (floor / margin)",
    "margins_box": "ARC over the theta box: floors with theta_hat at each plant's theta (floor / margin), "
                   "stability with theta_hat anywhere (spectral radius)",
}

#: Parameter -> description (units: :func:`commission.units.parameter_units`).
PARAM_WHAT = {"M": "mass", "B": "viscous friction", "fc": "Coulomb level", "fs": "static level",
              "vs": "Stribeck velocity", "xi": "Stribeck exponent", "offset": "command offset"}
#: Figures of the identification (``identify --plot``; ``run`` writes them beside the report).
IDENT_CAPTIONS = {
    "force_fit.png": "Inverse-dynamics fit: measured against fitted force, and the residual, over the log.",
    "friction_curve.png": "Identified friction curve over the constant-velocity legs, with the atan compensation.",
    "friction_curve.png/no legs": "Identified friction curve, with the atan compensation (the log holds no "
                                  "constant-velocity leg to plot over it).",
    "residuals.png": "Histogram of the fit's residuals.",
    "bode.png": "Measured frequency response u -> q with its coherence, against the rigid and the fitted model.",
}
#: Figures of the validation (drawn by ``cli/plots_validate.py``).
FIGURE_CAPTIONS = {
    "tracking_case1.png": "Tracking errors, ARC vs PID, Case 1 scenarios (as the paper's Figs. 2-4); "
                          "every axis holds both controllers' peaks (a symmetric-log axis where one is "
                          "more than 20 times the other).",
    "tracking_user.png": "Desired trajectory and tracking errors, ARC vs PID, on the machine's own moves "
                         "(the user/... scenarios).",
    "tracking_case2.png": "Desired trajectory and tracking errors, ARC vs PID, Case 2 scenarios "
                          "(as the paper's Figs. 5-6).",
    "theta_hat.png": "The ARC's parameter estimates theta_hat on every fixed scenario of each case (dashed: "
                     "the plant's values; grey: the theta box). They converge only under persistent "
                     "excitation: see 'Reading the results'.",
    "control_input.png": "Control input u of ARC and PID on the nominal scenarios.",
    "monte_carlo.png": "e_rms of ARC against PID on every scenario (below the diagonal: ARC better).",
    "loops.png": "Loop transfers L = -K P of ARC and PID on the identified plant (mode and delay "
                 "included): Bode magnitude and phase, and the Nyquist curves near -1 with the "
                 "modulus-margin circle.",
}
