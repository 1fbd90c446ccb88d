"""The deployable controller artifact (``controller.json``, CONTRACT §3).

Written by ``commission validate`` only when every gate passes; read by
:func:`commission.runtime.load_controller`.  It holds every number the
discrete ARC needs, grouped the way the paper states them, plus what it was
validated against and where it came from::

    kind               "controller"
    schema_version     1
    controller         "arc-output-feedback" (Xu & Yao 2001, §3)
    control_law        the law in words: the paper's equations by number, the filters, the
                       departures from the paper (:data:`CONTROL_LAW`; optional on load)
    sample_rate        Hz
    sample_period      s (the exact period simulated; 1/sample_rate up to rounding)
    units              {"u": command unit, "q": "m"}
    observer           k1 (1/s), k2 (1/s^2): A0 of (10)
    gains              w1, w2, g1, g2 (1/s), eps11, eps12, eps21, eps22,
                       C_phi1, C_phi2, C_theta2 (3 each)
    bounds             theta_min, theta_max (the Assumption-1 box), u_max (u-unit),
                       k1s_max, k2s_max (1/s): caps of the nonlinear gains
    adaptation         Gamma (3): the diagonal adaptation rate of (19)
    initial_estimates  theta0 (3)
    friction_compensation  level (u-unit), slope (s/m): F_hat(v) = level (2/pi) atan(slope v)
    runtime            OPTIONAL (absent: every guard off): the runtime guards of the
                       compiled step (:mod:`commission.controllers.arc`, "Runtime guards"):
                       dy_max (m), dy_fault (m), n_reject_max (count), e_max (m),
                       freeze_on_saturation (bool); optional accel_max (m/s^2), y_err (m),
                       n_frozen_max (count), u_free (u-unit) (absent: off); written by
                       validate, which simulated with exactly these
    validated          what validate checked: the resolved gate, the worst value of
                       each criterion with its scenario, the ARC's indexes on the
                       identified plant (nominal, per trajectory), scenario count, seed
    provenance         log_sha256, ident_sha256, tuning_sha256, tool_version, created_utc
    validity           OPTIONAL (absent: the whole box of bounds.theta_min/theta_max, as
                       identified): present when tune narrowed a defaulted payload range to
                       what the gains certify; payload_range and mass_range [min, max] in
                       unit (u-unit s^2/m), default_payload_range, payload_defaulted, reason
    checksum           {"algorithm": "sha256", "value": hex}: sha256 of the canonical JSON
                       (sorted keys, 2-space indent) of every other field

    signature          optional {"algorithm": "hmac-sha256", "value": hex}: a keyed
                       signature of every field but checksum and signature

``null`` stands for infinity where a term may be off (eps11 ... eps22).  The
output limit ``u_max`` and the gain caps ``k1s_max``, ``k2s_max`` are always
finite: this tool never emits a controller without them, and
:meth:`ControllerConfig.from_dict` refuses a file where they are null.
Numbers round-trip exactly through JSON (shortest repr), so the loaded
controller packs to the very vector validate simulated.

What the checksum protects, and what it does not
------------------------------------------------
The checksum is an unkeyed sha256 of the file's own content.  It detects
accidental damage -- a truncated copy, a flipped bit, a hand edit that forgot
to recompute it -- and then the file is refused.  It does **not** show who
wrote the file: anyone can edit a number and recompute the sha256.  A site that
must refuse controllers it did not produce signs them: ``commission validate``
and ``run`` with ``--sign-key KEYFILE`` (or the environment variable
:data:`SIGN_KEY_ENV` naming the key file) add an HMAC-SHA256 signature under a
secret key, and ``load_controller(path, key=...)`` refuses a file that is
unsigned, signed under another key, or edited after signing.  The key must stay
secret (anyone holding it can sign); the signature says nothing about whether
the gains are good, only that a holder of the key emitted them.
"""

from __future__ import annotations

import dataclasses
import hashlib
import hmac
import math
import os
from dataclasses import dataclass
from typing import Any, Mapping

from pydantic import ValidationError

from commission.controllers.arc import ArcGains
from commission.errors import SchemaError, UsageError
from commission.formats.controller_json import (CONTROLLER_FIELDS, CONTROLLER_KIND, CONTROLLER_SCHEMA_VERSION,
                                                CONTROLLER_TYPE, FRICTION, INF_OK, LIMITS, RUNTIME_ADDED,
                                                RUNTIME_FIELDS, SECTIONS, VECTORS, ControllerJson)
from commission.formats.json_table import check_header, json_error
from commission.jsonio import canonical_json, read_json, sha256_json
from commission.spec import RANGES

#: The law a controller.json parameterises, stated for the engineer who deploys it: the paper
#: and its equations by number, the filter structure, and where the implementation departs
#: from the paper (:mod:`commission.controllers.arc` gives the reasons).  Written into every
#: file; a file whose statement differs describes a law this runtime does not run and is refused.
CONTROL_LAW: dict[str, str] = {
    "paper": ("Xu L., Yao B. (2001), Output feedback adaptive robust precision motion control of linear "
              "motors, Automatica 37, sec. 3"),
    "observer_filters": ("eta' = A0 eta + e2 y, lambda' = A0 lambda + e2 u*, psi' = A0 psi + e2 with "
                         "A0 = [[-k1, 1], [-k2, 0]]: eqs. (10), (12), (18); advanced exactly over each sample "
                         "period (u* zero-order hold, y first-order hold between samples)"),
    "step1": ("z1 = y - q_d, alpha_1 = alpha_1a + alpha_1s with alpha_1s = -(K1/theta1_min) z1: "
              "eqs. (25)-(28), (37), (38); K1 capped at bounds.k1s_max"),
    "step2": ("z2 = v2 - alpha_1, u* = u*_a - K2 z2 with the exact partials of alpha_1: eqs. (39), (43), (47); "
              "K2 capped at bounds.k2s_max"),
    "adaptation": ("theta_hat <- clip(theta_hat + Ts Gamma tau, theta_min, theta_max), "
                   "tau = w1 phi1 z1 + w2 phi2 z2: eqs. (19), (20), (50)"),
    "output": "u = sat(u* + F_hat(dq_d), u_max), F_hat(v) = level (2/pi) atan(slope v): eq. (5)",
    "departures": ("robust gains capped (k1s_max, k2s_max) so that the sampled loop is stable at sample_rate; "
                   "runtime guards of the runtime section (absent: off)"),
    "implementation": "commission.controllers.arc.arc_step, the step validate simulated",
}
CHECKSUM_ALGORITHM = "sha256"
SIGNATURE_ALGORITHM = "hmac-sha256"
#: Environment variable naming the signing key file (``--sign-key`` takes precedence).
SIGN_KEY_ENV = "COMMISSION_SIGN_KEY"
#: Shortest accepted key, bytes (HMAC-SHA256 keys should carry at least 128 bits).
MIN_KEY_BYTES = 16

_FRICTION = FRICTION
_INF_OK = INF_OK
_VECTORS = VECTORS
#: Allowed relative mismatch between sample_period and 1/sample_rate.
_PERIOD_RTOL = 1e-9
#: Physical plausibility of a loaded controller, (lowest, highest) inclusive: the spec's own
#: ranges (:data:`commission.spec.RANGES`, one definition), so that a file cannot carry a rate
#: or an output limit that ``tune`` would have refused to start from (a 1e308 u_max is no clamp).
PLAUSIBLE: dict[str, tuple[tuple[str, str], str]] = {
    "sample_rate": (("controller", "sample_rate"), "Hz"),
    "u_max": (("controller", "u_max"), "u-unit"),
}


def _failer(source: str):
    """``fail(msg, path)``: the SchemaError naming the file and the JSON path."""
    return lambda msg, path: SchemaError(f"{source}: {path}: {msg}")


def _plausible(fail, path: str, key: str, value: float, unit: str | None = None) -> None:
    """Refuse ``value`` at ``path`` outside its :data:`PLAUSIBLE` range, naming the field
    (``unit``: the file's own unit of the value, when it has one)."""
    rng, default_unit = PLAUSIBLE[key]
    unit = unit or default_unit
    lo, hi = RANGES[rng]
    if not lo <= value <= hi:
        raise fail(f"{value!r} {unit} is outside the plausible range [{lo:g}, {hi:g}] {unit}", path)


@dataclass(frozen=True)
class ControllerProvenance:
    """Where a controller came from.

    Attributes
    ----------
    log_sha256 : str or None
        sha256 of the excitation log (null when ident.json did not record it).
    ident_sha256 : str
        sha256 of ident.json.
    tuning_sha256 : str
        sha256 of the tuning.json validated.
    tool_version : str
    created_utc : str
        ISO-8601 UTC time of the validation.
    """

    log_sha256: str | None
    ident_sha256: str
    tuning_sha256: str
    tool_version: str
    created_utc: str

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class ControllerConfig:
    """Content of ``controller.json`` (module docstring).

    Attributes
    ----------
    gains : ArcGains
        The discrete ARC exactly as validated (``gains.Ts`` is the sample period, s).
    sample_rate : float
        Hz.
    units : dict
        ``{"u": command unit, "q": "m"}``.
    validated : dict
        JSON-ready record of the gate and the worst values (see :mod:`commission.validate`).
    provenance : ControllerProvenance
    validity : dict or None
        The certified payload range (module docstring; None: the identified box as is).
    """

    gains: ArcGains
    sample_rate: float
    units: Mapping[str, str]
    validated: Mapping[str, Any]
    provenance: ControllerProvenance
    validity: Mapping[str, Any] | None = None

    def body(self) -> dict[str, Any]:
        """Every field but the checksum, JSON-ready."""
        g = self.gains
        doc: dict[str, Any] = {
            "kind": CONTROLLER_KIND,
            "schema_version": CONTROLLER_SCHEMA_VERSION,
            "controller": CONTROLLER_TYPE,
            "control_law": dict(CONTROL_LAW),
            "sample_rate": self.sample_rate,
            "sample_period": g.Ts,
            "units": dict(self.units),
        }
        for section, names in SECTIONS.items():
            doc[section] = {n: _out(getattr(g, n)) for n in names}
        doc["friction_compensation"] = {k: getattr(g, a) for k, a in _FRICTION.items()}
        if any(getattr(g, n) != f.default for n, f in _RUNTIME_DEFAULTS.items()):
            # only when set, so that a file written before the guards existed keeps its checksum
            doc["runtime"] = {n: (bool(getattr(g, n)) if n == "freeze_on_saturation" else _out(getattr(g, n)))
                              for n in RUNTIME_FIELDS if n not in RUNTIME_ADDED}
            if any(getattr(g, n) != _RUNTIME_DEFAULTS[n].default for n in RUNTIME_ADDED):
                # the guards added later (issue 29) likewise: a file without them keeps its checksum
                doc["runtime"].update({n: _out(getattr(g, n)) for n in RUNTIME_ADDED})
        doc["validated"] = dict(self.validated)
        doc["provenance"] = self.provenance.to_dict()
        if self.validity is not None:  # only when narrowed, so that other files keep their checksum
            doc["validity"] = dict(self.validity)
        return doc

    def to_dict(self, sign_key: bytes | None = None) -> dict[str, Any]:
        """The document written to disk: :meth:`body`, its signature under ``sign_key`` if given,
        and its checksum (module docstring)."""
        doc = self.body()
        if sign_key is not None:
            doc["signature"] = {"algorithm": SIGNATURE_ALGORITHM, "value": _hmac(sign_key, doc)}
        doc["checksum"] = {"algorithm": CHECKSUM_ALGORITHM, "value": sha256_json(doc)}
        return doc

    @classmethod
    def from_dict(cls, data: Any, source: str = "controller.json", *, key: bytes | None = None,
                  allow_unbounded: bool = False) -> "ControllerConfig":
        """Strict load: the schema, then the checksum, then (``key`` given) the signature.

        Parameters
        ----------
        data : object
            The parsed JSON.
        source : str
            File name for the messages.
        key : bytes, optional
            The site's signing key: the file must carry a valid HMAC-SHA256 signature under it.
        allow_unbounded : bool
            Accept null ``u_max``, ``k1s_max``, ``k2s_max`` (infinite limits).  Only for
            ``validate``'s round trip of a tuning, whose floors then refuse to emit it.

        Raises
        ------
        SchemaError
            ``controller.json: $.gains.g1: ...`` naming the first field that is
            missing, mistyped or out of range (a null or non-finite limit
            included; a sample rate or u_max outside :data:`PLAUSIBLE`; a unit outside
            :data:`commission.artifacts.UNIT_VOCABULARY_U`), ``controller.json: $.checksum: ...`` when the content does
            not match its checksum (edited or corrupted), or ``$.signature: ...``
            when a key is given and the file is unsigned or signed under another key.
        """
        check_header(data, CONTROLLER_KIND, CONTROLLER_SCHEMA_VERSION, source)
        try:
            ControllerJson.model_validate(data)
        except ValidationError as exc:  # the checksum and signature: last, as before
            msg = json_error(exc, CONTROLLER_FIELDS, source=source, later=("checksum", "signature"))
            if msg is not None:
                raise SchemaError(msg) from None
        fail = _failer(source)
        if data["controller"] != CONTROLLER_TYPE:
            raise fail(f"expected {CONTROLLER_TYPE!r}, got {data['controller']!r}", "$.controller")
        if "control_law" in data and data["control_law"] != CONTROL_LAW:
            raise fail("describes a control law this runtime does not implement (the statement "
                       "differs from commission.controller_config.CONTROL_LAW)", "$.control_law")
        rate, Ts = float(data["sample_rate"]), float(data["sample_period"])
        if abs(Ts * rate - 1.0) > _PERIOD_RTOL:
            raise fail(f"{Ts!r} s does not match sample_rate {rate!r} Hz", "$.sample_period")
        _plausible(fail, "$.sample_rate", "sample_rate", rate)
        units = {"u": data["units"]["u"], "q": data["units"]["q"]}
        kw: dict[str, Any] = {"Ts": Ts}
        for section, names in SECTIONS.items():
            for n in names:
                v = data[section][n]
                if n in _VECTORS:
                    kw[n] = tuple(float(x) for x in v)
                elif v is None and (n in _INF_OK or (n in LIMITS and allow_unbounded)):
                    kw[n] = math.inf
                elif v is None:  # a limit (the table lets it be null so that a round trip may allow it)
                    raise fail(f"null: a controller without a finite {n} is refused (no limit)", f"$.{section}.{n}")
                else:
                    kw[n] = float(v)
                    if n == "u_max":
                        _plausible(fail, f"$.{section}.{n}", n, kw[n], units["u"])
        for k, attr in _FRICTION.items():
            kw[attr] = float(data["friction_compensation"][k])
        if data.get("runtime") is not None:
            rt = data["runtime"]
            for n in RUNTIME_FIELDS:
                if n in RUNTIME_ADDED and rt.get(n) is None:
                    continue  # optional: absent keeps ArcGains' default (that guard off)
                if n == "freeze_on_saturation":
                    kw[n] = rt[n]
                else:
                    kw[n] = math.inf if rt[n] is None else float(rt[n])
        try:
            gains = ArcGains(**kw)
        except ValueError as exc:
            raise fail(str(exc), _gain_path(str(exc))) from None
        pr = data["provenance"]
        prov = ControllerProvenance(log_sha256=pr["log_sha256"], ident_sha256=pr["ident_sha256"],
                                    tuning_sha256=pr["tuning_sha256"], tool_version=pr["tool_version"],
                                    created_utc=pr["created_utc"])
        validity = dict(data["validity"]) if data.get("validity") is not None else None
        verify_checksum(data, source)
        verify_signature(data, source, key)
        return cls(gains=gains, sample_rate=rate, units=units, validated=data["validated"], provenance=prov,
                   validity=validity)

    @classmethod
    def load(cls, path: str, key: bytes | None = None) -> "ControllerConfig":
        """Read and strictly validate ``controller.json`` (and its signature under ``key``, if given)."""
        return cls.from_dict(read_json(path), source=str(path), key=key)


_RUNTIME_DEFAULTS = {f.name: f for f in dataclasses.fields(ArcGains) if f.name in RUNTIME_FIELDS}


def _out(v: Any) -> Any:
    if isinstance(v, tuple):
        return [float(x) for x in v]
    return None if not math.isfinite(v) else float(v)


def _gain_path(msg: str) -> str:
    """JSON path of the ArcGains field an ArcGainsError message names (``ArcGains.g1: ...``)."""
    if msg.startswith("ArcGains."):
        name = msg[len("ArcGains."):].split(":")[0].split("/")[0].split("[")[0]
        for section, names in SECTIONS.items():
            if name in names:
                return f"$.{section}.{name}"
        if name in ("fric_level", "fric_slope"):
            return f"$.friction_compensation.{'level' if name == 'fric_level' else 'slope'}"
        if name == "Ts":
            return "$.sample_period"
        if name in RUNTIME_FIELDS:
            return f"$.runtime.{name}"
    return "$"


def verify_checksum(data: Any, source: str = "controller.json") -> None:
    """Check ``$.checksum`` against the canonical JSON of every other field.

    Raises
    ------
    SchemaError
        Missing or malformed checksum, unknown algorithm, or a mismatch.
    """
    fail = _failer(source)
    value = _digest_field(_member(data, "checksum", "$", fail), CHECKSUM_ALGORITHM, "$.checksum", fail)
    body = {k: v for k, v in data.items() if k != "checksum"}
    try:
        actual = sha256_json(body)
    except ValueError as exc:  # NaN or inf smuggled into the file
        raise fail(f"content is not canonical JSON ({exc})", "$") from None
    if actual != value:
        raise fail(f"mismatch: the file says {value!s:.16}..., its content hashes to {actual[:16]}...; "
                      f"the file was edited or corrupted after validation", "$.checksum")


def _member(obj: Any, key: str, path: str, fail) -> dict[str, Any]:
    """The object ``obj[key]`` (``path`` is ``obj``'s JSON path)."""
    if not isinstance(obj, dict):
        raise fail(f"expected an object, got {type(obj).__name__}", path)
    if obj.get(key) is None:
        raise fail("missing required field", f"{path}.{key}")
    if not isinstance(obj[key], dict):
        raise fail(f"expected an object, got {type(obj[key]).__name__}", f"{path}.{key}")
    return obj[key]


def _digest_field(obj: Mapping[str, Any], algorithm: str, path: str, fail) -> str:
    """The ``value`` of a ``{"algorithm", "value"}`` object: ``algorithm`` and 64 lowercase hex digits."""
    for k in ("algorithm", "value"):
        if obj.get(k) is None:
            raise fail("missing required field", f"{path}.{k}")
        if not isinstance(obj[k], str):
            raise fail(f"expected a string, got {obj[k]!r}", f"{path}.{k}")
    algo, value = obj["algorithm"], obj["value"]
    if algo != algorithm:
        raise fail(f"unsupported algorithm {algo!r} (expected {algorithm!r})", f"{path}.algorithm")
    if len(value) != 64 or any(ch not in "0123456789abcdef" for ch in value):
        raise fail(f"expected 64 lowercase hex digits, got {value!r}", f"{path}.value")
    return value


def _hmac(key: bytes, doc: Mapping[str, Any]) -> str:
    """HMAC-SHA256 (hex) of the canonical JSON of ``doc`` without its checksum and signature."""
    body = {k: v for k, v in doc.items() if k not in ("checksum", "signature")}
    return hmac.new(key, canonical_json(body).encode(), hashlib.sha256).hexdigest()


def verify_signature(data: Any, source: str = "controller.json", key: bytes | None = None) -> None:
    """Check ``$.signature``: well-formed when present; valid under ``key`` when a key is given.

    Raises
    ------
    SchemaError
        A malformed signature; with a key: no signature (unsigned), or one that
        does not match (signed under another key, or edited after signing).
    """
    fail = _failer(source)
    if not isinstance(data, dict):
        raise fail(f"expected an object, got {type(data).__name__}", "$")
    if "signature" not in data:
        if key is not None:
            raise fail("missing: the file is not signed, and a signing key was given", "$.signature")
        return
    sr = _member(data, "signature", "$", fail)
    for k in sr:
        if k not in ("algorithm", "value"):
            raise fail("unknown field", f"$.signature.{k}")
    value = _digest_field(sr, SIGNATURE_ALGORITHM, "$.signature", fail)
    if key is None:
        return
    try:
        expected = _hmac(key, data)
    except ValueError as exc:  # NaN or inf smuggled into the file
        raise fail(f"content is not canonical JSON ({exc})", "$") from None
    if not hmac.compare_digest(expected, value):
        raise fail("does not match the signing key: signed under another key, or edited after signing",
                      "$.signature")


def load_sign_key(path: str | os.PathLike[str] | None = None, *, flag: str = "--sign-key") -> bytes | None:
    """The signing key: the file ``path``, else the file named by :data:`SIGN_KEY_ENV`, else None.

    The key is the file's bytes without trailing whitespace (a key written by
    ``openssl rand -hex 32 > site.key`` ends in a newline); at least
    :data:`MIN_KEY_BYTES` bytes.

    Raises
    ------
    InputFileError
        The file is missing, not a regular file, or over 64 KiB.
    UsageError
        The key is shorter than :data:`MIN_KEY_BYTES`.
    """
    from commission.infra.files import read_input_bytes

    if path is None:
        env = os.environ.get(SIGN_KEY_ENV)
        if not env:
            return None
        path, flag = env, SIGN_KEY_ENV
    key = read_input_bytes(path, 64 * 1024).rstrip()
    if len(key) < MIN_KEY_BYTES:
        raise UsageError(f"{flag} {os.fspath(path)}: the key has {len(key)} bytes; give at least {MIN_KEY_BYTES}")
    return key
