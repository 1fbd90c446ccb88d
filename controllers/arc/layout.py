"""The packed layouts of the ARC: parameter vector p, state vector s, fault codes.

The compiled step (:mod:`commission.controllers.arc.step`) takes every gain in one
float64 vector ``p`` and keeps everything that changes from sample to sample in one
float64 vector ``s``, so that the simulator, the runtime and the exported C share one
flat layout and nothing is allocated inside the loop.  Every slot is named here once;
the C export reads these constants from the package (``commission.export.c_target``)
rather than retyping them.  No imports: ``from ... import *`` takes exactly the layout.
"""

# Layout of the packed parameter vector p (float64[NP]).
P_TS = 0  # sample period, s
P_K1 = 1  # observer gain k1, 1/s
P_K2 = 2  # observer gain k2, 1/s^2
P_W1 = 3  # weight w1
P_W2 = 4  # weight w2
P_G1 = 5  # g1, 1/s
P_G2 = 6  # g2, 1/s
P_C11 = 7  # 1/(4 eps11) (0 when eps11 = inf)
P_C12 = 8  # 1/(4 eps12)
P_C21 = 9  # 1/(4 eps21)
P_C22 = 10  # 1/(4 eps22)
P_CPHI1 = 11  # C_phi1 diagonal (3)
P_CPHI2 = 14  # C_phi2 diagonal (3)
P_CTH2 = 17  # C_theta2 diagonal (3)
P_GAMMA = 20  # Gamma diagonal (3)
P_TMIN = 23  # theta_min (3)
P_TMAX = 26  # theta_max (3)
P_THETA0 = 29  # initial estimates (3)
P_FLEVEL = 32  # friction-compensation level, u-unit
P_FSLOPE = 33  # friction-compensation slope, s/m
P_K1MAX = 34  # cap on K1 (total gain of alpha_1s), 1/s (inf: none)
P_K2MAX = 35  # cap on K2 (total gain of u*_s), 1/s (inf: none)
P_UMAX = 36  # output limit, u-unit (inf: none)
P_THM2 = 37  # ||theta_max - theta_min||^2
P_Q1 = 38  # K1 = g1 + sum_i Q1_i phi1_i^2 + C12: Q1_i = (Cphi1_i Gamma_i)^2 + C11 ||theta_M||^2 (3)
P_Q2 = 41  # same for phi2 in K2: (Cphi2_i Gamma_i)^2 + C21 ||theta_M||^2 (3)
P_CT2SQ = 44  # C_theta2_i^2 (3)
P_AD = 47  # expm(A0 Ts), row-major 2x2 (4)
P_BD = 51  # int_0^Ts expm(A0 s) ds e2 (2): held-input response
P_BD1 = 53  # int_0^Ts expm(A0 (Ts - s)) e2 s/Ts ds (2): response to an input ramp 0 -> 1
# Runtime guards (:mod:`commission.controllers.arc.step`, "Runtime guards"); inf / 0 switch each off.
P_DY_MAX = 55  # largest plausible |y_k - y_good| per sample since the last accepted y, m (inf: no check)
P_DY_FAULT = 56  # a jump |y_k - y_good| beyond this latches a fault at once, m (inf: none)
P_NREJ_MAX = 57  # this many rejected samples in a row latch a fault (inf: never)
P_E_MAX = 58  # tracking-error watchdog on the accepted |y - q_d|, m (inf: none)
P_FREEZE_SAT = 59  # 1: no adaptation in a sample whose command is saturated at u_max (0: adapt)
P_A_MAX = 60  # largest plausible acceleration of the axis, m/s^2 (inf: no innovation check)
P_Y_ERR = 61  # largest error of one measurement (rounding + noise), m (0: exact readings)
P_NFRZ_MAX = 62  # still samples in a row that must have moved (weighted) that latch a fault (inf: never)
P_U_FREE = 63  # largest command that may leave the axis at rest (friction, offsets, loads), u-unit
NP = 64

#: Bound on R Ts, R = K2 - theta_hat1 d(alpha1)/dy the rate of the sampled v-loop
#: (:mod:`commission.controllers.arc.gains`, the caps); applied whenever ``k2s_max`` is finite.
V_LOOP_RATE_LIMIT = 1.75

# Layout of the state vector s (float64[NS]).
S_ETA = 0  # eta (2), filter (18) driven by y
S_LAMBDA = 2  # lambda = v (2), filter (18) driven by u*
S_PSI = 4  # psi (2), filter (12) driven by 1
S_THETA = 6  # theta_hat (3)
S_YPREV = 9  # y of the previous sample, m
S_USPREV = 10  # u* applied over the previous sample, u-unit
S_PRIMED = 11  # 0 right after arc_reset, 1 once a sample has been taken
S_FAULT = 12  # 1 once a non-finite value was met (latched until arc_reset)
S_Z1 = 13  # z1 = y - qd, m
S_Z2 = 14  # z2 = v2 - alpha1
S_ALPHA1 = 15  # alpha1
S_XHAT = 16  # x_hat (2) of (13)
S_K1 = 18  # K1 used (after the cap), 1/s
S_K2 = 19  # K2 used (after the cap), 1/s
S_USTAR = 20  # u* (before the friction term and saturation), u-unit
S_U = 21  # u returned, u-unit
S_YGOOD = 22  # last accepted measurement, m
S_EGOOD = 23  # y - q_d at the last accepted measurement, m
S_NREJ = 24  # measurements rejected in a row
S_REJECTED = 25  # 1 when this sample's y was rejected (a glitch) and replaced by q_d + S_EGOOD
S_FROZEN = 26  # 1 when the adaptation was frozen in this sample (y rejected, or command saturated)
S_VLAST = 27  # velocity of the last accepted pair of measurements, m/s
S_VPREV = 28  # velocity of the accepted pair before the last one, m/s: what the prediction uses
S_YSTILL = 29  # raw measurement at the start of the current still run, m
S_NSTILL = 30  # evidence of the still run that the axis must have moved: 1 per rejected y, <= 1 per push
S_DU = 31  # |u_k - u_k-1| of the last three commands (3), most recent first, u-unit
S_INNOV = 34  # innovation y - y_pred of this sample's raw measurement, m (logged)
S_BOUND = 35  # the innovation bound it was held to, m (logged)
NS = 36

# Fault reason codes held in s[S_FAULT] (0: no fault); latched until arc_reset.
FAULT_NONE = 0
FAULT_NONFINITE = 1  # an input (y, q_d, dq_d, ddq_d) or an intermediate value (u, u*, tau) not finite
FAULT_JUMP = 2  # one measurement jumped farther than dy_fault from the last accepted one
FAULT_GLITCH_RUN = 3  # n_reject_max measurements in a row were implausible
FAULT_TRACKING = 4  # the accepted tracking error |y - q_d| exceeded e_max
FAULT_FROZEN = 5  # n_frozen_max still measurements in a row while the command was at u_max or y was implausible
#: Reason code -> name (the runtime's ``fault_reason``).
FAULT_REASONS = {
    FAULT_NONE: "none",
    FAULT_NONFINITE: "non-finite input or intermediate value",
    FAULT_JUMP: "measurement jump beyond dy_fault",
    FAULT_GLITCH_RUN: "n_reject_max implausible measurements in a row",
    FAULT_TRACKING: "tracking error beyond e_max",
    FAULT_FROZEN: "measurement frozen while the command is at u_max or the axis must move",
}
#: The entries of s that carry the controller's dynamics from one sample to the next
#: (the others are flags or values logged for the caller); what a linearisation perturbs.
S_DYNAMIC = (S_ETA, S_ETA + 1, S_LAMBDA, S_LAMBDA + 1, S_PSI, S_PSI + 1, S_THETA, S_THETA + 1, S_THETA + 2,
             S_YPREV, S_USPREV)

