"""What ``identify`` is told: the options of one identification and their checks.

:class:`IdentifyOptions` is the one definition of everything ``commission identify`` and
``run``'s identify stage pass on (:meth:`IdentifyOptions.kwargs` gives
:func:`commission.identification.identify_log`'s keywords); :class:`BoundsOptions` what the
user declares about the operating range.  The parsers and checks of the flags that need more
than a type (``--input-gain``, ``--fix``, ``--terms``) sit beside them, so that the CLI and
the stage refuse the same values with the same words.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Literal, Mapping, Sequence

import numpy as np

from commission.errors import UsageError
from commission.identify import richer


#: Command units of CONTRACT §1.
U_UNITS = ("V", "N", "A", "Nm", "%")


#: Parameters ``--fix`` accepts.
FIXABLE = ("M",)
#: Accepted range of each ``--fix`` value, u-unit·s²/m, both ends inclusive.  ``theta1 = 1/M``
#: is what tune and the controller work with, so M's range is the reciprocal of the range
#: the tune spec accepts for theta1 (``controller.theta1_0``, :data:`commission.spec.RANGES`):
#: whatever the unit of u, an axis outside it is a typo or a unit slip, and the arithmetic of
#: the fit (``M qdd`` squared and summed over the log) and of the theta box stays finite inside it.
FIX_RANGES = {"M": (1e-12, 1e12)}


@dataclass(frozen=True)
class BoundsOptions:
    """What the user declares about the operating range (Assumption 1).

    Attributes
    ----------
    k_sigma : float
        Standard deviations of the estimates covered by the box.
    model_margin : float
        Relative margin on M and B for model error (0.2 = +-20 %).
    payload_min, payload_max : float or None
        Added mass range in operation, u-unit s^2/m; ``payload_max`` None means
        the default of :func:`commission.identify.bounds.theta_bounds` (3 M).
    disturbance_bound : float or None
        Largest constant load force besides the offset, u-unit (None: 10 max(fc, fs)).
    """

    k_sigma: float = 3.0
    model_margin: float = 0.2
    payload_min: float = 0.0
    payload_max: float | None = None
    disturbance_bound: float | None = None


@dataclass(frozen=True)
class IdentifyOptions:
    """Everything ``commission identify`` (and ``run``'s identify stage) is told about a log.

    One definition for both commands; :meth:`kwargs` gives :func:`identify_log`'s keywords.

    Attributes
    ----------
    mapping : mapping of str to str
        Contract channel -> name in the file (``--map``).
    input_gain : float
        Multiplies u before identification (``--input-gain``), u-unit per file unit.
    sample_rate : float or None
        Hz, for a file without ``t``.
    friction : {"auto", "coulomb", "stribeck"}
        Friction model.  ``"auto"``: the Stribeck curve when the log supports it; when its
        Stribeck-specific checks refuse it (no significant hump, too few slow samples, ``vs``
        on the edge of the speeds seen) the Coulomb model, with a warning in ident.json.
        ``"stribeck"`` refuses instead.
    ripple_pitch : tuple of float
        Force-ripple pitches, m (rad on a rotary axis; ``--ripple-pitch``, repeatable): one
        sinusoid per pitch; empty: none.  The first is the ripple the simulator uses
        (``model.ripple_pitch``/``ripple_amp``).
    find_ripple : bool
        Find the force-ripple pitch on the log's constant-velocity legs
        (:mod:`commission.identify.ripple`) and fit its ripple when one stands out
        (``model.ripple_search`` says what was searched and found; a warning says a pitch
        found), when no ``ripple_pitch`` is given.  The default (``--ripple-pitch auto``):
        a ripple left out of the fit biases the friction (it hides the Stribeck rise on
        slow legs) and the mass (docs/robustness.md, "Friction the log did not resolve");
        ``--ripple-pitch none`` turns the search off.
    validate_on : str or None
        Other log(s) for the cross-test relative error (same mapping and gain; several
        are segments, as the identification logs).
    bounds : BoundsOptions
        Declared operating range.
    u_unit : {"V", "N", "A", "Nm", "%"} or None
        ``--u-unit``: unit of ``u`` after ``input_gain``; default the file's unit, allowed only
        when ``input_gain`` is 1 (:func:`check_input_gain`).
    q_unit : {"m", "mm", "um", "rad"} or None
        ``--q-unit``: unit of ``q`` in files without a ``q_unit`` attribute (CSV, v5 MAT);
        default m (``"rad"``: a rotary axis).  Applies to ``validate_on`` too.
    fmt : {"hdf5", "csv", "mat", "epos"} or None
        ``--format``: forces the log format; default: recognised from the content (EPOS
        recorder files) or the extension.  Applies to ``validate_on`` too.
    resample : float or None
        Hz (``--resample``): interpolate the log (and ``validate_on``) onto a uniform grid
        first (:func:`commission.identification.resample_log`), for irregular time stamps.
    fix : mapping of str to float
        Known parameters (``{"M": u-unit s^2/m}``, ``--fix``), not fitted.
    lead, gear : float or None
        ``--lead`` (m per load rad) and ``--gear`` (motor rad per load rad): the rotary
        log(s), ``validate_on`` too, converted before anything is fitted
        (:func:`commission.identification.convert_axis`); ``ripple_pitch`` and ``fix`` are
        then in the converted unit.
    counts_per_rev : float or None
        ``--counts-per-rev``: q (and q_ref) of every log in encoder counts, N per revolution,
        read as rad on loading (:func:`commission.logs.load_log`), before ``gear`` and ``lead``.
    terms : str
        ``--terms`` (:func:`parse_terms`), with ``friction="auto"`` only: the switchable
        terms of the delay-aware inverse dynamics (:mod:`commission.identify.richer`)
        among which blocked cross-validation on the identification log(s) chooses;
        ``"auto"`` all of them, ``"none"`` none (the model of ``friction="auto"``
        before them).  Used on logs fitted by the whole-log (dynamic) method, with M
        fitted; the validation logs are read only after the choice.
    plan : mapping or None
        ``--plan``: the parsed plan.json of ``commission excite`` the one log was recorded from
        (:func:`commission.excite.load_plan_json`): the frequency response is estimated on its
        injection windows (:func:`commission.excite.injection_ranges`) instead of the segments
        the command's level shows.  None: a plan.json beside the one log is used when the log
        is a recording of it (:func:`commission.identification.plan_beside`).
    plan_path : str or None
        Where ``plan`` was read (recorded in ``frequency_response.plan``).
    """

    mapping: Mapping[str, str] = dataclasses.field(default_factory=dict)
    input_gain: float = 1.0
    sample_rate: float | None = None
    friction: Literal["coulomb", "stribeck", "auto"] = "auto"
    ripple_pitch: tuple[float, ...] = ()
    find_ripple: bool = True
    validate_on: str | None = None
    bounds: BoundsOptions = BoundsOptions()
    u_unit: str | None = None
    q_unit: str | None = None
    fmt: str | None = None
    resample: float | None = None
    fix: Mapping[str, float] = dataclasses.field(default_factory=dict)
    lead: float | None = None
    gear: float | None = None
    counts_per_rev: float | None = None
    terms: str = "auto"
    plan: Mapping[str, Any] | None = None
    plan_path: str | None = None

    def kwargs(self) -> dict[str, object]:
        """Keywords of :func:`identify_log` (``plan`` and ``plan_path`` only when a plan is given)."""
        extra: dict[str, object] = {} if self.plan is None else {"plan": self.plan, "plan_path": self.plan_path}
        return {**extra, "mapping": dict(self.mapping), "input_gain": self.input_gain, "sample_rate": self.sample_rate,
                "friction": self.friction, "ripple_pitch": self.ripple_pitch or None, "find_ripple": self.find_ripple,
                "validate_on": self.validate_on, "bounds": self.bounds, "u_unit": self.u_unit, "q_unit": self.q_unit,
                "fmt": self.fmt, "resample": self.resample, "fix": dict(self.fix), "lead": self.lead,
                "gear": self.gear, "counts_per_rev": self.counts_per_rev, "terms": self.terms}


def check_input_gain(input_gain: float, u_unit: str | None) -> None:
    """Refuse a gain that is not a positive finite number, or one that changes u's unit unnamed.

    ``--input-gain G`` turns the file's command into ``G x u``, whose unit is not the
    file's (volts times N/V are newtons): every artifact and report labels u with the
    unit after the gain, so a gain other than 1 needs ``--u-unit`` to name it.

    Parameters
    ----------
    input_gain : float
        ``--input-gain``, u-unit per file unit.
    u_unit : str or None
        ``--u-unit``: the unit of ``input_gain x u``.

    Raises
    ------
    UsageError
        Naming ``--input-gain`` or ``--u-unit``.
    """
    if not input_gain > 0 or not np.isfinite(input_gain):
        raise UsageError(f"--input-gain must be a positive finite number, got {input_gain}")
    if u_unit is not None and u_unit not in U_UNITS:
        raise UsageError(f"--u-unit must be one of {', '.join(U_UNITS)}, got {u_unit!r}")
    if u_unit is None and input_gain != 1.0:
        raise UsageError(f"--input-gain {input_gain:g} needs --u-unit (the unit of {input_gain:g} x u, e.g. N)")


def payload_from_kg(kg: float, force_constant: float) -> float:
    """Convert a payload in kg to the command-unit mass, u-unit s^2/m.

    Parameters
    ----------
    kg : float
        Added mass, kg.
    force_constant : float
        Force per command unit, N/u-unit.
    """
    if not force_constant > 0:
        raise UsageError(f"--force-constant must be > 0 N per u-unit, got {force_constant}")
    return kg / force_constant


def parse_fix(items: Sequence[str]) -> dict[str, float]:
    """``["M=0.027"]`` -> ``{"M": 0.027}`` (``--fix``; values of :data:`FIXABLE` within :data:`FIX_RANGES`).

    A parameter given twice is refused rather than the last one kept: the two
    values disagree (or one is a typo), and which one the user meant is theirs
    to say.  A value outside its range is refused by name (the range and why
    are at :data:`FIX_RANGES`).

    Raises
    ------
    UsageError
        Naming the ``--fix`` item.
    """
    out: dict[str, float] = {}
    given: dict[str, str] = {}
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or name not in FIXABLE:
            raise UsageError(f"--fix {item!r}: expected NAME=VALUE with NAME one of {', '.join(FIXABLE)}")
        if name in given:
            raise UsageError(f"--fix {name}: given twice ({given[name]!r} and {item!r}); give it once")
        try:
            v = float(value)
        except ValueError:
            raise UsageError(f"--fix {item!r}: {value!r} is not a number") from None
        lo, hi = FIX_RANGES[name]
        if not (math.isfinite(v) and v > 0):
            raise UsageError(f"--fix {item!r}: {name} must be a positive finite number (u-unit·s²/m)")
        if not lo <= v <= hi:
            raise UsageError(f"--fix {item!r}: {name} = {v:g} is outside the plausible range [{lo:g}, {hi:g}] "
                             f"u-unit·s²/m (theta1 = 1/{name} must lie in tune's range for theta1)")
        given[name], out[name] = item, v
    return out


def parse_terms(terms: str | Sequence[str] | None) -> tuple[str, ...] | None:
    """``--terms``: ``auto`` (None: every switchable term, chosen by cross-validation), ``none``
    (the richer model off), or a comma-separated subset of :data:`richer.TERMS` to choose among."""
    if terms is None:
        return None
    items = [t.strip() for t in (terms.split(",") if isinstance(terms, str) else terms) if t.strip()]
    if items == ["auto"]:
        return None
    if items == ["none"]:
        return ()
    bad = [t for t in items if t not in richer.TERMS]
    if bad or not items:
        raise UsageError(f"--terms: expected auto, none or a comma-separated subset of {', '.join(richer.TERMS)}; "
                         f"got {terms!r}")
    return tuple(t for t in richer.TERMS if t in items)
