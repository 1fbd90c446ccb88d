"""Pure numerics of axis identification (inverse-dynamics least squares).

Installed as ``commission.identify``.  Never imports typer, h5py or matplotlib.
"""

from commission.identify.bounds import ThetaBounds, friction_compensation, theta_bounds
from commission.identify.errors import NotIdentifiableError, SignalError
from commission.identify.fit import AxisFit, evaluate, evaluate_segments, fit_axis, fit_segments
from commission.identify.frf import FrequencyResponse, StructureFit, frequency_response
from commission.identify.friction import FrictionCompensation, fit_atan, friction_compensation_curve, \
    stribeck_friction
from commission.identify.ls import LSResult, Regressor, regressor, solve
from commission.identify.signals import Preprocessed, encoder_grid, preprocess, preprocess_segments, quantization_step
from commission.identify.steady import SteadySegments, find_steady_segments

__all__ = [
    "AxisFit", "FrequencyResponse", "FrictionCompensation", "StructureFit", "frequency_response", "LSResult", "NotIdentifiableError", "Preprocessed", "Regressor",
    "SignalError", "SteadySegments", "ThetaBounds", "evaluate", "evaluate_segments", "find_steady_segments", "fit_atan",
    "fit_axis", "fit_segments", "friction_compensation", "friction_compensation_curve", "preprocess",
    "preprocess_segments", "quantization_step", "encoder_grid", "regressor",
    "solve", "stribeck_friction", "theta_bounds",
]
