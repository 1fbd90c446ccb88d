import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from commission.controllers.plant import plant_advance, plant_vector, stribeck, stribeck_cut


def test_free_mass_matches_closed_form():
    # No friction: x(t) = 0.5 u/M t^2 exactly up to the O(h) integrator error.
    p = plant_vector(M=2.0, B=0.0, fc=0.0)
    x, v = plant_advance(p, 0.0, 0.0, 1.0, 1e-5, 100_000)
    assert math.isclose(v, 0.5, rel_tol=1e-9)
    assert math.isclose(x, 0.25, rel_tol=1e-4)


def test_viscous_decay_matches_exponential():
    p = plant_vector(M=1.0, B=4.0, fc=0.0)
    x, v = plant_advance(p, 0.0, 1.0, 0.0, 1e-6, 500_000)
    assert math.isclose(v, math.exp(-2.0), rel_tol=1e-4)
    assert math.isclose(x, (1 - math.exp(-2.0)) / 4.0, rel_tol=1e-4)


def test_stiction_holds_below_static_level_and_breaks_above():
    p = plant_vector(M=1.0, B=0.1, fc=0.1, fs=0.2, vs=0.01)
    x, v = plant_advance(p, 0.0, 0.0, 0.19, 1e-5, 10_000)
    assert x == 0.0 and v == 0.0
    x, v = plant_advance(p, 0.0, 0.0, -0.21, 1e-5, 10_000)
    assert v < 0.0 and x < 0.0


def test_coulomb_stop_lands_at_rest_without_reversal():
    # A sliding mass with no input stops in time v0 / (fc/M) (closed form)
    # and stays stopped: no chattering reversal.
    p = plant_vector(M=1.0, B=0.0, fc=0.5, fs=0.5)
    h = 1e-5
    x, v = plant_advance(p, 0.0, 1.0, 0.0, h, 300_000)
    assert v == 0.0
    assert math.isclose(x, 1.0 / (2 * 0.5), rel_tol=1e-3)


def test_reversal_under_constant_force():
    # Moving left against a constant push to the right: stops, then slides right.
    p = plant_vector(M=1.0, B=0.0, fc=0.1, fs=0.2)
    x, v = plant_advance(p, 0.0, -0.1, 1.0, 1e-5, 100_000)
    assert v > 0.0
    # Decelerates at (1+0.1) until v=0 then accelerates at (1-0.1) for the rest of 1 s.
    t_stop = 0.1 / 1.1
    assert math.isclose(v, 0.9 * (1.0 - t_stop), rel_tol=1e-3)


@settings(max_examples=300, deadline=None)
@given(fc=st.floats(1e-4, 10.0), ratio=st.floats(0.2, 5.0), vs=st.floats(1e-4, 0.1),
       xi=st.one_of(st.just(1.0), st.just(2.0), st.floats(0.3, 4.0)), v=st.floats(-5.0, 5.0))
def test_stribeck_shortcuts_give_the_formula_to_the_last_bit(fc, ratio, vs, xi, v):
    """The skipped curve above stribeck_cut and the squared exponent equal the plain formula exactly."""
    p = plant_vector(M=1.0, B=0.0, fc=fc, fs=fc * ratio, vs=vs, xi=xi)
    plain = 0.0 if v == 0.0 else math.copysign(fc + (fc * ratio - fc) * math.exp(-abs(v / vs) ** xi), v)
    assert stribeck(p, v, stribeck_cut(p)) == plain
    assert stribeck(p, v) == plain


def test_stribeck_cut_is_where_the_curve_drops_below_the_last_bit():
    p = plant_vector(M=1.0, B=0.0, fc=0.1, fs=0.12, vs=0.01, xi=2.0)
    cut = stribeck_cut(p)
    # (fs - fc) exp(-(v/vs)^2) = 2^-60 fc  <=>  v = vs sqrt(ln(0.2) + 60 ln 2)
    assert cut == pytest.approx(0.01 * math.sqrt(math.log(0.2) + 60 * math.log(2.0)), rel=1e-9)
    assert stribeck_cut(plant_vector(M=1.0, B=0.0, fc=0.1)) == 0.0  # Coulomb only
    assert stribeck_cut(plant_vector(M=1.0, B=0.0, fc=0.0, fs=0.1)) == math.inf  # no Coulomb level to round to
