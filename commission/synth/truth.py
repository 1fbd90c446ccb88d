"""The known truth of a simulated axis (:class:`AxisTruth`: its parameters, units and plant vector),
and the channel names and units of an excitation log.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any, Mapping

import numpy as np

from commission.controllers.plant import plant_vector


#: Channel names of an excitation log, in file order (CONTRACT section 1).
LOG_CHANNELS = ("t", "q", "u", "q_ref")
Q_UNITS = ("m", "mm", "um")
U_UNITS = ("V", "N", "A")


def _check_finite(owner: str, **values: float) -> None:
    for name, val in values.items():
        if not math.isfinite(val):
            raise ValueError(f"{owner}: {name} must be finite, got {val!r}")

@dataclass(frozen=True)
class AxisTruth:
    """Known parameters of a simulated axis (the "truth" of a synthetic log).

    Model (CONTRACT section 2 convention)::

        M qdd = u - offset - B qd - Ff(qd) - ripple_amp sin(2 pi q / ripple_pitch)
        Ff(v) = [fc + (fs - fc) exp(-|v/vs|^xi)] sign(v)

    Parameters
    ----------
    M : float
        Mass, u-unit s^2/m (V s^2/m for ``u_unit='V'``).
    B : float
        Viscous coefficient, u-unit s/m.
    fc : float
        Coulomb friction level, u-unit.
    fs : float
        Static friction (stiction) level, u-unit.
    vs : float
        Stribeck velocity, m/s.
    xi : float
        Stribeck exponent, dimensionless.
    offset : float
        Constant force offset, u-unit (``u_equiv = ... + offset``).
    ripple_amp : float
        Force-ripple amplitude, u-unit.
    ripple_pitch : float
        Force-ripple pitch, m.
    lsb : float
        Encoder resolution (quantization step), m.
    sample_rate : float
        Controller and logging rate, Hz.
    u_unit : str
        Unit of the command: ``'V'``, ``'N'`` or ``'A'``.
    noise_std : float
        Standard deviation of Gaussian position noise added before
        quantization, m (0: quantization only).
    u_max : float
        Command rail: the controller output is clipped to ``[-u_max, u_max]``, u-unit.
    mode_hz : float
        Resonance of a structural mode, Hz (0: rigid body; see
        :mod:`commission.controllers.plant` for the two-mass model).
    mode_damping : float
        Damping ratio of the mode, in [0, 1).
    mode_ratio : float
        Load fraction ``m2 / M`` of the moving mass, in (0, 1).
    mode_load_side : bool
        The encoder reads the load (True) or the motor side (False).
    delay : float
        Input delay between the command the controller issues and the force, s
        (fractional samples allowed).
    mode2_hz : float
        Resonance of a second structural mode, Hz (0: none; only beside the first: a second
        load on the motor side, :mod:`commission.controllers.plant`).
    mode2_damping : float
        Damping ratio of the second mode, in [0, 1).
    mode2_ratio : float
        Load fraction of the second mode, in (0, 1).
    mode2_load_side : bool
        The encoder reads the second mode's load (True: this wins over ``mode_load_side``).
    input_gain : float
        Force per command unit, N/u-unit (1 for ``u_unit='N'``; a drive's amplifier and force
        constant for ``'V'``): the moving mass is ``M * input_gain`` kg.  Information only: the
        plant is written in command units.
    """

    M: float
    B: float
    fc: float
    fs: float
    vs: float
    xi: float
    offset: float = 0.0
    ripple_amp: float = 0.0
    ripple_pitch: float = 0.03
    lsb: float = 1e-6
    sample_rate: float = 2500.0
    u_unit: str = "V"
    noise_std: float = 0.0
    u_max: float = 10.0
    mode_hz: float = 0.0
    mode_damping: float = 0.02
    mode_ratio: float = 0.5
    mode_load_side: bool = False
    delay: float = 0.0
    mode2_hz: float = 0.0
    mode2_damping: float = 0.02
    mode2_ratio: float = 0.2
    mode2_load_side: bool = False
    input_gain: float = 1.0

    def __post_init__(self) -> None:
        # JSON carries the encoder side as 0/1 (to_dict): store a bool either way.
        object.__setattr__(self, "mode_load_side", bool(self.mode_load_side))
        object.__setattr__(self, "mode2_load_side", bool(self.mode2_load_side))
        nums = {k: v for k, v in asdict(self).items() if k != "u_unit"}
        _check_finite("AxisTruth", **nums)
        bad = [
            f"{name}={nums[name]!r} (need {rule})"
            for name, ok, rule in (
                ("M", self.M > 0, "> 0"),
                ("B", self.B >= 0, ">= 0"),
                ("fc", self.fc >= 0, ">= 0"),
                ("fs", self.fs >= 0, ">= 0"),
                ("vs", self.vs > 0, "> 0"),
                ("xi", self.xi > 0, "> 0"),
                ("ripple_amp", self.ripple_amp >= 0, ">= 0"),
                ("ripple_pitch", self.ripple_pitch > 0, "> 0"),
                ("lsb", self.lsb > 0, "> 0"),
                ("sample_rate", self.sample_rate > 0, "> 0"),
                ("noise_std", self.noise_std >= 0, ">= 0"),
                ("u_max", self.u_max > 0, "> 0"),
                ("mode_hz", self.mode_hz >= 0, ">= 0"),
                ("mode_damping", 0 <= self.mode_damping < 1, "in [0, 1)"),
                ("mode_ratio", 0 < self.mode_ratio < 1, "in (0, 1)"),
                ("delay", self.delay >= 0, ">= 0"),
                ("mode2_hz", self.mode2_hz >= 0, ">= 0"),
                ("mode2_damping", 0 <= self.mode2_damping < 1, "in [0, 1)"),
                ("mode2_ratio", 0 < self.mode2_ratio < 1, "in (0, 1)"),
                ("input_gain", self.input_gain > 0, "> 0"),
            )
            if not ok
        ]
        if self.mode2_hz > 0 and not (self.mode_hz > 0 and self.mode_ratio + self.mode2_ratio < 1):
            bad.append(f"mode2_hz={self.mode2_hz!r} (needs mode_hz > 0 and mode_ratio + mode2_ratio < 1)")
        if bad:
            raise ValueError("AxisTruth: " + "; ".join(bad))
        if self.u_unit not in U_UNITS:
            raise ValueError(f"AxisTruth: u_unit={self.u_unit!r} (need one of {', '.join(U_UNITS)})")

    @property
    def period(self) -> float:
        """Sample period, s."""
        return 1.0 / self.sample_rate

    @property
    def n_modes(self) -> int:
        """Number of structural modes (0, 1 or 2)."""
        return int(self.mode_hz > 0) + int(self.mode2_hz > 0)

    @property
    def mass_kg(self) -> float:
        """Moving mass, kg (``M * input_gain``)."""
        return self.M * self.input_gain

    def plant(self) -> np.ndarray:
        """Plant vector for :mod:`commission.controllers.plant` (float64[NP]), second mode included."""
        return plant_vector(self.M, self.B, self.fc, self.fs, self.vs, self.xi,
                            self.offset, self.ripple_amp, self.ripple_pitch, mode_hz=self.mode_hz,
                            mode_damping=self.mode_damping, mode_ratio=self.mode_ratio,
                            mode_load_side=self.mode_load_side, delay=self.delay, mode2_hz=self.mode2_hz,
                            mode2_damping=self.mode2_damping, mode2_ratio=self.mode2_ratio,
                            mode2_load_side=self.mode2_load_side)

    def units(self) -> dict[str, str]:
        """Unit of every numeric field (``u`` stands for :attr:`u_unit`)."""
        u = self.u_unit
        return {
            "M": f"{u} s^2/m", "B": f"{u} s/m", "fc": u, "fs": u, "vs": "m/s", "xi": "1",
            "offset": u, "ripple_amp": u, "ripple_pitch": "m", "lsb": "m",
            "sample_rate": "Hz", "noise_std": "m", "u_max": u,
            "mode_hz": "Hz", "mode_damping": "1", "mode_ratio": "1", "mode_load_side": "1", "delay": "s",
            "mode2_hz": "Hz", "mode2_damping": "1", "mode2_ratio": "1", "mode2_load_side": "1",
            "input_gain": f"N/{u}",
        }

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form: ``{"u_unit": ..., "parameters": {name: {"value", "unit"}}}``.

        The second mode's fields are written only with a second mode, and ``input_gain`` only
        when it is not 1, so the truth of a one-mode axis reads as it did before they existed
        (``sample_data/truth.json``); :meth:`from_dict` defaults what is absent.
        """
        units = self.units()
        skip = set()
        if self.mode2_hz == 0:
            skip |= {"mode2_hz", "mode2_damping", "mode2_ratio", "mode2_load_side"}
        if self.input_gain == 1.0:
            skip.add("input_gain")
        return {
            "u_unit": self.u_unit,
            "parameters": {k: {"value": float(getattr(self, k)), "unit": units[k]} for k in units if k not in skip},
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "AxisTruth":
        """Inverse of :meth:`to_dict` (units are implied by ``u_unit``)."""
        params = {k: float(v["value"]) for k, v in d["parameters"].items()}
        return cls(u_unit=str(d["u_unit"]), **params)
