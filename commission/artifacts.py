"""Frozen dataclasses for the identification artifact (``ident.json``).

The JSON keys of CONTRACT §2 are a stable external interface: fields may be
added, never renamed or removed.  Saved with sorted keys via
:func:`commission.jsonio.write_json_atomic`; loaded strictly through
the model of its one table, :mod:`commission.formats.ident_json`, naming the JSON path of a bad
field.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

from pydantic import ValidationError

from commission.errors import SchemaError
from commission.formats.ident_json import (IDENT_FIELDS, IDENT_KIND, IDENT_SCHEMA_VERSION, PARAMETER_NAMES,
                                           REQUIRED_PARAMETERS, UNIT_VOCABULARY_Q, UNIT_VOCABULARY_U, IdentJson)
from commission.formats.json_table import check_header, json_error, sub_model
from commission.jsonio import read_json
from commission.units import mass_wording  # noqa: F401  (the wording lives in commission.units)

__all__ = ["IDENT_KIND", "IDENT_SCHEMA_VERSION", "PARAMETER_NAMES", "UNIT_VOCABULARY_Q", "UNIT_VOCABULARY_U",
           "Estimate", "Identification", "StructuralModel", "ThetaBox"]


@dataclass(frozen=True)
class Estimate:
    """A parameter value with its standard deviation (same unit as the value)."""

    value: float
    std: float

    def to_dict(self) -> dict[str, float]:
        return {"value": self.value, "std": self.std}


@dataclass(frozen=True)
class ThetaBox:
    """The paper's parameter vector theta = [1/M, B/M, d_n/M] with its Assumption-1 box.

    Units: theta1 in m/(u-unit s^2), theta2 in 1/s, theta3 in m/s^2.
    """

    nominal: tuple[float, float, float]
    min: tuple[float, float, float]
    max: tuple[float, float, float]

    def __post_init__(self) -> None:
        for i in range(3):
            if not self.min[i] <= self.nominal[i] <= self.max[i]:
                raise ValueError(
                    f"theta[{i}]: nominal {self.nominal[i]:g} outside [{self.min[i]:g}, {self.max[i]:g}]"
                )
        if not self.min[0] > 0:
            raise ValueError(f"theta_min[0] = {self.min[0]:g}: 1/M bound must be positive")

    def to_dict(self) -> dict[str, list[float]]:
        return {"nominal": list(self.nominal), "min": list(self.min), "max": list(self.max)}


@dataclass(frozen=True)
class StructuralModel:
    """What ``frequency_response.model`` of ident.json says beyond the rigid body.

    Attributes
    ----------
    mode_hz : float or None
        Resonance of the structural mode, Hz (None: no mode found).
    mode_damping : float or None
        Its damping ratio, -.
    mode_ratio : float or None
        Load fraction m2 / M, -.
    mode_load_side : bool or None
        The encoder reads the load (True) or the motor side (False).
    delay_s : float
        Input delay beyond the zero-order hold, s.
    mode2_hz, mode2_damping, mode2_ratio, mode2_load_side : float, float, float, bool or None
        *Added*: a second mode, the simulator's second appendage on the motor (Hz, -, load
        fraction m3 / M, the encoder reads it); None without one.
    """

    mode_hz: float | None
    mode_damping: float | None
    mode_ratio: float | None
    mode_load_side: bool | None
    delay_s: float
    mode2_hz: float | None = None
    mode2_damping: float | None = None
    mode2_ratio: float | None = None
    mode2_load_side: bool | None = None

    def plant_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of :func:`commission.controllers.plant.plant_vector` for the modes and delay."""
        if self.mode_hz is None:
            return {"delay": self.delay_s}
        kw = {"mode_hz": self.mode_hz, "mode_damping": self.mode_damping, "mode_ratio": self.mode_ratio,
              "mode_load_side": bool(self.mode_load_side), "delay": self.delay_s}
        if self.mode2_hz is not None:
            kw.update(mode2_hz=self.mode2_hz, mode2_damping=self.mode2_damping, mode2_ratio=self.mode2_ratio,
                      mode2_load_side=bool(self.mode2_load_side))
        return kw


#: The model of ``frequency_response.model`` (a row of ident.json's table).
_StructuralJson = sub_model(IdentJson, "frequency_response.model")


def _structural_model(data: Mapping[str, Any], source: str) -> StructuralModel | None:
    """``$.frequency_response.model`` through its model (None when the section or the model is absent)."""
    fr = data.get("frequency_response")
    if not isinstance(fr, Mapping) or fr.get("model") is None:
        return None
    try:
        m = _StructuralJson.model_validate(fr["model"])
    except ValidationError as exc:
        raise SchemaError(json_error(exc, (), source=source, prefix="$.frequency_response.model")) from None
    if m.mode_hz is None:
        return StructuralModel(None, None, None, None, m.delay_s)
    if m.mode2_hz is None:
        return StructuralModel(m.mode_hz, m.mode_damping, m.mode_ratio, m.mode_load_side, m.delay_s)
    return StructuralModel(m.mode_hz, m.mode_damping, m.mode_ratio, m.mode_load_side, m.delay_s,
                           m.mode2_hz, m.mode2_damping, m.mode2_ratio, m.mode2_load_side)


@dataclass(frozen=True)
class Identification:
    """Result of ``commission identify`` (CONTRACT §2).

    Attributes
    ----------
    units : dict
        ``{"u": u-unit, "q": "m"}``.
    parameters : dict
        Name -> :class:`Estimate`.  M in u-unit s^2/m, B in u-unit s/m,
        fc, fs, offset in u-unit, vs in m/s, xi dimensionless.  ``fs``, ``vs``,
        ``xi`` are ``None`` for the Coulomb model.  ``M`` is ``None`` when the log
        carries no information on it; ``extra["not_identified"]["M"]`` then says why.
    relative_error : float
        ||y - y_hat|| / ||y|| on the identification data (fraction).
    condition_number : float
        Of the (column-scaled) regressor.
    validation_relative_error : float or None
        Same figure on the ``--validate-on`` log.
    theta : ThetaBox or None
        Nominal theta and the Assumption-1 box; ``None`` when ``M`` was not
        identified (theta1 = 1/M), e.g. from a friction test of constant-speed legs.
    delta_d : float or None
        Bound on |d~| = |d - d_n|/M, m/s^2; ``None`` with ``theta``.
    fric_level, fric_slope : float
        Friction compensation ``level*(2/pi)*atan(slope*v)``: level in u-unit,
        slope in s/m.
    extra : dict
        Additive, non-contract details (provenance, ripple, quantization,
        warnings, bound settings, the optional ``frequency_response`` section
        ...), stored under their own keys.
    """

    units: Mapping[str, str]
    parameters: Mapping[str, Estimate | None]
    relative_error: float
    condition_number: float
    validation_relative_error: float | None
    theta: ThetaBox | None
    delta_d: float | None
    fric_level: float
    fric_slope: float
    extra: Mapping[str, Any] = field(default_factory=dict)

    def value(self, name: str) -> float:
        est = self.parameters.get(name)
        if est is None:
            raise KeyError(f"parameter {name!r} was not identified")
        return est.value

    def not_identified(self) -> dict[str, str]:
        """Parameter -> why the log could not identify it (``not_identified`` in ident.json)."""
        return dict(self.extra.get("not_identified") or {})

    def tuning_gaps(self, source: str = "ident.json") -> list[str]:
        """What ``tune`` needs and this identification lacks, one message per gap (empty: complete)."""
        gaps = []
        what, unit = mass_wording(self.units)
        for name, why in self.not_identified().items():
            if name == "M":
                gaps.append(f"{source}: $.parameters.M: not identified ({why}); tune needs the {what} ({unit}): "
                            f"identify a log with acceleration content, or give the {what.split()[0]} with "
                            "identify --fix M=VALUE")
            else:
                gaps.append(f"{source}: $.parameters.{name}: not identified ({why})")
        return gaps

    def structural_model(self) -> StructuralModel | None:
        """The mode and input delay the frequency response found (None: the log did not measure them)."""
        return _structural_model(self.extra, "ident.json")

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = dict(self.extra)
        d.update(
            {
                "kind": IDENT_KIND,
                "schema_version": IDENT_SCHEMA_VERSION,
                "units": dict(self.units),
                "parameters": {k: (v.to_dict() if v is not None else None) for k, v in self.parameters.items()},
                "fit": {
                    "relative_error": self.relative_error,
                    "condition_number": self.condition_number,
                    "validation_relative_error": self.validation_relative_error,
                },
                "theta": self.theta.to_dict() if self.theta is not None else None,
                "delta_d": self.delta_d,
                "friction_compensation": {"level": self.fric_level, "slope": self.fric_slope},
            }
        )
        return d

    @classmethod
    def from_dict(cls, data: Any, source: str = "ident.json", prefix: str = "$") -> "Identification":
        """Strict load through the table's model (:data:`commission.formats.ident_json.IdentJson`).

        A refused value raises :class:`SchemaError` naming its JSON path (``prefix`` anchors the
        paths: ``$.identification`` inside tuning.json).  What relates two fields (a required
        parameter null only when ``not_identified`` says why, a theta box whose nominal lies
        inside it, ``delta_d`` with ``theta``) is checked here, after the fields.
        """
        def fail(path: str, msg: str) -> SchemaError:
            return SchemaError(f"{source}: {prefix}{path[1:]}: {msg}")

        check_header(data, IDENT_KIND, IDENT_SCHEMA_VERSION, source, prefix)
        try:
            m = IdentJson.model_validate(data)
        except ValidationError as exc:
            raise SchemaError(json_error(exc, IDENT_FIELDS, source=source, prefix=prefix)) from None
        not_identified = m.not_identified or {}
        params: dict[str, Estimate | None] = {}
        for name in PARAMETER_NAMES:
            est = getattr(m.parameters, name)
            if est is None and name in REQUIRED_PARAMETERS and name not in not_identified:
                raise fail(f"$.parameters.{name}", "expected an object, got NoneType")
            params[name] = None if est is None else Estimate(est.value, est.std)
        M = params["M"]
        if M is not None and M.value <= 0:
            raise fail("$.parameters.M.value", f"expected a positive mass, got {M.value!r}")
        theta: ThetaBox | None = None
        delta_d: float | None = None
        if M is None and m.theta is None:
            if m.delta_d is not None:
                raise fail("$.delta_d", "expected null: M is not identified")
        else:
            if m.theta is None:
                raise fail("$.theta", "expected an object, got NoneType")
            try:
                theta = ThetaBox(tuple(m.theta.nominal), tuple(m.theta.min), tuple(m.theta.max))  # type: ignore[arg-type]
            except ValueError as exc:  # only the box's own consistency checks land here
                raise fail("$.theta", str(exc)) from None
            if m.delta_d is None:
                raise fail("$.delta_d", "missing required field")
            delta_d = m.delta_d
        known = {"kind", "schema_version", "units", "parameters", "fit", "theta", "delta_d", "friction_compensation"}
        return cls(
            units={"u": m.units.u, "q": m.units.q},
            parameters=params,
            relative_error=m.fit.relative_error,
            condition_number=m.fit.condition_number,
            validation_relative_error=m.fit.validation_relative_error,
            theta=theta,
            delta_d=delta_d,
            fric_level=m.friction_compensation.level,
            fric_slope=m.friction_compensation.slope,
            extra={k: v for k, v in data.items() if k not in known},
        )

    @classmethod
    def load(cls, path: str) -> "Identification":
        return cls.from_dict(read_json(path), source=str(path))
