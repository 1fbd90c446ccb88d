"""Frozen dataclasses for the identification artifact (``ident.json``).

The JSON keys of CONTRACT §2 are a stable external interface: fields may be
added, never renamed or removed.  Saved with sorted keys via
:func:`commission.jsonio.write_json_atomic`; loaded strictly via
:class:`commission.jsonio.Reader`, which names the JSON path of a bad field.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

from commission.jsonio import Reader, read_json
from commission.logs.model import U_UNITS
from commission.spec import RANGES
from commission.units import mass_wording  # noqa: F401  (the wording lives in commission.units)

IDENT_KIND = "identification"
IDENT_SCHEMA_VERSION = 1

#: Parameters of CONTRACT §2 in a stable order.
PARAMETER_NAMES = ("M", "B", "fc", "fs", "vs", "xi", "offset")

#: ``units.u`` of every artifact: exactly the command units this tool itself can write
#: (:data:`commission.logs.model.U_UNITS`: a log's ``u_unit`` attribute, an EPOS file's torque
#: unit, ``--u-unit``).  A fixed vocabulary rather than free text, because the unit travels from
#: ident.json through tuning.json and controller.json into generated code and reports.
UNIT_VOCABULARY_U = U_UNITS
#: ``units.q``: a linear axis in m (a log in mm or um is converted on reading), a rotary one in rad.
UNIT_VOCABULARY_Q = ("m", "rad")


def read_units(r: Reader) -> dict[str, str]:
    """``$.units`` of an artifact root, each unit checked against its fixed vocabulary.

    Shared by ident.json, tuning.json (its embedded identification) and controller.json, so
    that a unit the tool could not have written is refused wherever it is planted, with its
    JSON path, before it can reach a report or generated code.

    Raises
    ------
    SchemaError
        ``ident.json: $.units.u: expected one of [...], got 'parsec'``, or an unknown key.
    """
    ur = r.obj("units")
    for k in ur.keys():
        if k not in ("u", "q"):
            raise ur.fail("unknown field", f"{ur.path}.{k}")
    return {"u": ur.str_("u", choices=UNIT_VOCABULARY_U),  # type: ignore[dict-item]
            "q": ur.str_("q", choices=UNIT_VOCABULARY_Q)}


def read_sha256(r: Reader, key: str, *, optional: bool = False) -> str | None:
    """A sha256 field: 64 lowercase hex digits (what :mod:`hashlib` writes), or None when optional and absent.

    A digest is whitelisted by its form because it is copied into provenance records and
    generated files; free text there would be a channel for anything.
    """
    v = r.str_(key, optional=optional)
    if v is not None and not _is_sha256(v):
        raise r.fail(f"expected a sha256 (64 lowercase hex digits), got {v[:80]!r}", f"{r.path}.{key}")
    return v


def _is_sha256(v: object) -> bool:
    return isinstance(v, str) and len(v) == 64 and all(c in "0123456789abcdef" for c in v)


def _in_range(r: Reader, key: str, rng: tuple[str, str], unit: str) -> None:
    """An optional number at ``key`` that, when present, lies in the spec's range :data:`commission.spec.RANGES`."""
    v = r.num(key, optional=True)
    lo, hi = RANGES[rng]
    if v is not None and not lo <= v <= hi:
        raise r.fail(f"must be within [{lo:g}, {hi:g}] {unit}, got {v!r}", f"{r.path}.{key}")


def _optional_obj(r: Reader, key: str) -> Reader | None:
    return r.obj(key) if r.has(key) else None


def _check_extra(r: Reader) -> None:
    """Check the optional ident.json fields that ``tune`` and ``validate`` use, where present.

    A missing optional field (or null) takes its documented default downstream
    (:func:`commission.scenarios.resolve_quantization`, :func:`commission.tune.log_sample_rate`,
    ...); a field that is **present** with a value of the wrong type or outside its range is
    refused here, naming its JSON path, instead of being replaced by that default further on
    (an encoder step of -1 um is not "no encoder step recorded").  The ranges are the spec's
    (:data:`commission.spec.RANGES`) where the spec has the same quantity.
    """
    src = _optional_obj(r, "source")
    if src is not None:
        src.num("sample_rate", optional=True, positive=True)
        if src.has("n_samples") and src.int_("n_samples") < 0:
            raise src.fail("expected a non-negative integer", f"{src.path}.n_samples")
        if src.has("sha256"):
            digests = src.child("sha256")
            if isinstance(digests.data, list):
                for i, d in enumerate(digests.data):
                    if not _is_sha256(d):
                        raise src.fail(f"expected a sha256 (64 lowercase hex digits), got {str(d)[:80]!r}",
                                       f"{digests.path}[{i}]")
            else:
                read_sha256(src, "sha256")
    read_sha256(r, "log_sha256", optional=True)
    _in_range(r, "quantization", ("controller", "quantization"), "m")  # the older place of encoder.quantization
    enc = _optional_obj(r, "encoder")
    if enc is not None:
        _in_range(enc, "quantization", ("controller", "quantization"), "m")
        _in_range(enc, "noise_std", ("plant", "noise_std"), "m")
        enc.num("apparent_resolution", optional=True, nonneg=True)
    model = _optional_obj(r, "model")
    if model is not None:
        model.num("ripple_pitch", optional=True, positive=True)
        if model.has("ripple_amp"):
            amp = model.child("ripple_amp")
            if isinstance(amp.data, dict):
                amp.num("value")
                amp.num("std", nonneg=True)
            else:
                model.num("ripple_amp")
    ripple = _optional_obj(r, "ripple")
    if ripple is not None:
        ripple.num("pitch", positive=True)
        for k in ("amplitude", "amp"):
            ripple.num(k, optional=True)
    bounds = _optional_obj(r, "bounds")
    if bounds is not None:
        if bounds.has("disturbance_bound_defaulted"):
            bounds.bool_("disturbance_bound_defaulted")
        bounds.num("disturbance_bound", optional=True, nonneg=True)
        nb = _optional_obj(bounds, "narrowed_by_tune")
        if nb is not None:
            lo, hi = nb.num("theta3_min"), nb.num("theta3_max")
            if not lo <= hi:  # type: ignore[operator]
                raise nb.fail(f"theta3_min {lo!r} exceeds theta3_max {hi!r}")
            nb.num("u_max", optional=True, positive=True)
    if r.has("warnings"):
        w = r.child("warnings")
        if not isinstance(w.data, list) or not all(isinstance(x, str) for x in w.data):
            raise w.fail("expected a list of strings")


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


def _structural_model(data: Mapping[str, Any], source: str) -> StructuralModel | None:
    """Strictly read ``$.frequency_response.model`` (None when the section or the model is absent)."""
    r = Reader(data, "$", source)
    if not r.has("frequency_response"):
        return None
    fr = r.obj("frequency_response")
    if not fr.has("model"):
        return None
    m = fr.obj("model")
    delay = m.num("delay_s", nonneg=True)
    if not m.has("mode_hz"):
        return StructuralModel(None, None, None, None, delay)  # type: ignore[arg-type]
    hz = m.num("mode_hz", positive=True)
    zeta = m.num("mode_damping", nonneg=True)
    ratio = m.num("mode_ratio", positive=True)
    if not zeta < 1:  # type: ignore[operator]
        raise m.fail(f"expected a damping ratio below 1, got {zeta!r}", f"{m.path}.mode_damping")
    if not ratio < 1:  # type: ignore[operator]
        raise m.fail(f"expected a load fraction below 1, got {ratio!r}", f"{m.path}.mode_ratio")
    if not m.has("mode2_hz"):
        return StructuralModel(hz, zeta, ratio, m.bool_("mode_load_side"), delay)  # type: ignore[arg-type]
    # Added: a second mode, the simulator's second appendage (ident.json written by this version).
    hz2 = m.num("mode2_hz", positive=True)
    zeta2 = m.num("mode2_damping", nonneg=True)
    ratio2 = m.num("mode2_ratio", positive=True)
    if not zeta2 < 1:  # type: ignore[operator]
        raise m.fail(f"expected a damping ratio below 1, got {zeta2!r}", f"{m.path}.mode2_damping")
    if not ratio + ratio2 < 1:  # type: ignore[operator]
        raise m.fail(f"expected mode_ratio + mode2_ratio below 1, got {ratio!r} + {ratio2!r}", f"{m.path}.mode2_ratio")
    return StructuralModel(hz, zeta, ratio, m.bool_("mode_load_side"), delay,  # type: ignore[arg-type]
                           hz2, zeta2, ratio2, m.bool_("mode2_load_side"))


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
    def from_dict(cls, data: Any, source: str = "ident.json") -> "Identification":
        r = Reader(data, "$", source)
        r.header(IDENT_KIND, IDENT_SCHEMA_VERSION)
        units = read_units(r)
        pr = r.obj("parameters")
        params: dict[str, Estimate | None] = {}
        not_identified = data.get("not_identified")
        not_identified = {} if not_identified is None else not_identified  # present: an object, even if empty
        if not isinstance(not_identified, dict) or not all(isinstance(v, str) for v in not_identified.values()):
            raise r.fail("expected an object of parameter -> reason", "$.not_identified")
        for name in PARAMETER_NAMES:
            required = name in ("M", "B", "fc", "offset")
            if name in not_identified and name in pr.keys() and pr.data[name] is None:
                params[name] = None  # reported as not identified, with its reason
                continue
            if not required and not pr.has(name):
                params[name] = None
                continue
            er = pr.obj(name)
            # vs and xi are positive by construction (identify searches log vs and xi in a positive
            # box); a file that says otherwise is refused rather than replaced by the simulator's default
            params[name] = Estimate(er.num("value", positive=name in ("vs", "xi")),  # type: ignore[arg-type]
                                    er.num("std", nonneg=True))  # type: ignore[arg-type]
        M = params["M"]
        if M is not None and M.value <= 0:
            raise r.fail(f"expected a positive mass, got {M.value!r}", "$.parameters.M.value")
        fit = r.obj("fit")
        theta: ThetaBox | None = None
        delta_d: float | None = None
        if M is None and data.get("theta") is None:
            if data.get("delta_d") is not None:
                raise r.fail("expected null: M is not identified", "$.delta_d")
        else:
            th = r.obj("theta")
            nominal, lo, hi = th.vec("nominal", 3), th.vec("min", 3), th.vec("max", 3)
            try:
                theta = ThetaBox(nominal, lo, hi)  # type: ignore[arg-type]
            except ValueError as exc:  # only the box's own consistency checks land here
                raise r.fail(str(exc), "$.theta") from None
            delta_d = r.num("delta_d", nonneg=True)
        fcr = r.obj("friction_compensation")
        known = {"kind", "schema_version", "units", "parameters", "fit", "theta", "delta_d", "friction_compensation"}
        extra = {k: v for k, v in data.items() if k not in known}
        _structural_model(data, source)  # a malformed optional section fails here, naming its path
        _check_extra(r)  # so do the optional fields tune and validate read: none is replaced by a default
        return cls(
            units=units,
            parameters=params,
            relative_error=fit.num("relative_error", nonneg=True),  # type: ignore[arg-type]
            condition_number=fit.num("condition_number", positive=True),  # type: ignore[arg-type]
            validation_relative_error=fit.num("validation_relative_error", optional=True, nonneg=True),
            theta=theta,
            delta_d=delta_d,
            fric_level=fcr.num("level", nonneg=True),  # type: ignore[arg-type]
            fric_slope=fcr.num("slope", nonneg=True),  # type: ignore[arg-type]
            extra=extra,
        )

    @classmethod
    def load(cls, path: str) -> "Identification":
        return cls.from_dict(read_json(path), source=str(path))
