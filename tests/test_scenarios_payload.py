"""A defaulted payload the ARC cannot hold safely is narrowed to the largest it holds (issue 30, Build 1).

The bisection is checked against a known threshold (the closed form of its grid); the heavy scenarios at
a payload on the CONTRACT sec. 5 reference identification (only the mass moves); and the validity record
flows from validate's result into controller.json (a stated range is never narrowed: the gate refuses).
"""

import math

import numpy as np
import pytest

from commission.controllers.plant import P_M
from commission.paper import reference_identification
from commission.scenarios import (PAYLOAD_BISECTIONS, largest_safe_payload, payload_heavy_at, scenario_matrix)
from commission.spec import spec_from_mapping


@pytest.mark.parametrize("threshold", [0.0, 0.137, 0.5, 1.9])
def test_the_bisection_finds_the_largest_safe_payload_on_its_grid(threshold):
    calls = []

    def safe(p):
        calls.append(p)
        return p <= threshold

    got = largest_safe_payload(0.0, 2.0, safe)
    step = 2.0 / 2 ** PAYLOAD_BISECTIONS
    assert got == pytest.approx(math.floor(threshold / step) * step)  # the safe grid point just below
    assert got <= threshold and len(calls) == PAYLOAD_BISECTIONS + 1


def test_nothing_to_certify_when_even_the_empty_axis_fails():
    assert largest_safe_payload(0.0, 2.0, lambda p: False) is None
    with pytest.raises(ValueError, match="payload range"):
        largest_safe_payload(1.0, 1.0, lambda p: True)


def test_payload_heavy_at_moves_only_the_mass_of_the_heavy_scenarios():
    ident = reference_identification()
    spec = spec_from_mapping({})
    matrix = scenario_matrix(ident, spec, rng=np.random.default_rng(0), n_monte_carlo=4)
    heavy = {s.name: s for s in matrix if s.name.endswith("/payload_heavy")}
    got = payload_heavy_at(matrix, 0.123)
    assert {s.name for s in got} == set(heavy) and len(got) == 2
    for s in got:
        ref = heavy[s.name]
        assert s.plant[P_M] == 0.123
        others = np.delete(np.arange(len(s.plant)), P_M)
        assert np.array_equal(s.plant[others], ref.plant[others])
        assert s.trajectory == ref.trajectory and s.tags == ref.tags and s.noise_std == ref.noise_std
    with pytest.raises(ValueError, match="mass"):
        payload_heavy_at(matrix, 0.0)


@pytest.fixture(scope="module")
def tuned():
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).parent))
    from reference_tuning import reference_tuning
    return reference_tuning(8)


def _with_payload(tuned, defaulted: bool):
    """The tuned reference axis whose box's heavy end (1/theta_min[0]) carries a payload over 0.0395 V s^2/m."""
    import dataclasses
    ident = tuned.identification
    m_lo, m_hi = 1.0 / ident.theta.max[0], 1.0 / ident.theta.min[0]
    bounds = {"mass_range": [m_lo, m_hi], "viscous_range": [0.0, 1.0], "payload_range": [0.0, m_hi - 0.0395],
              "payload_defaulted": defaulted}
    return dataclasses.replace(tuned, identification=dataclasses.replace(ident, extra={**ident.extra, "bounds": bounds}))


def test_validate_certifies_the_largest_default_payload_the_arc_holds_and_says_so(tuned):
    """A peak-command limit (a safety criterion) of 1.5 V: the heavy end (0.12 V s^2/m) needs 2.3 V on Case 1,
    the unloaded axis 0.64 V; the force grows with the mass, so the certified payload is where it reaches 1.5 V."""
    from commission.gate import GateSpec
    from commission.report import validity_lines
    from commission.validate import certified_validity, validate
    t = _with_payload(tuned, defaulted=True)
    r = validate(t, GateSpec(u_max=1.5), seed=0, n_monte_carlo=2, workers=1)
    v = r.validity
    assert v is not None and v["narrowed_by"] == "validate" and v["payload_defaulted"] is True
    lo, hi = v["payload_range"]
    full = 1.0 / t.identification.theta.min[0] - 0.0395
    step = full / 2 ** PAYLOAD_BISECTIONS
    assert lo == 0.0 and 0.0 < hi < full and math.isclose(hi / step, round(hi / step))
    assert v["default_payload_range"] == [0.0, full] and "u_peak at case1/payload_heavy" in v["reason"]
    for name in ("case1/payload_heavy", "case2/payload_heavy"):
        run = r.run(name)
        assert math.isclose(1.0 / run.theta_true[0], 0.0395 + hi)  # simulated at the certified mass
        assert run.arc.u_peak < 1.5
    assert not [c for c in r.verdict.failures if c.scenario.endswith("/payload_heavy")]
    over = validate(_with_payload(tuned, defaulted=False), GateSpec(u_max=1.5), seed=0, n_monte_carlo=0, workers=1)
    assert over.validity is None  # a stated payload is never narrowed: the gate refuses, naming the corner
    assert {c.scenario for c in over.verdict.failures if c.criterion == "u_peak"} >= {"case1/payload_heavy"}
    assert certified_validity(r, t) == v and certified_validity(over, t) is None
    first = validity_lines(r)[0]
    assert first.startswith(f"**Certified for payloads 0 to {hi:.4g}") and "not the default" in first
