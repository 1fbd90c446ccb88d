"""The batched margins give the per-loop margins to the last bit (docs/scaling.md, "Fourth pass").

The search's box check computes (a)'s thirty-odd loop margins and every closed loop's spectral
radius as stacked arrays (:func:`loop_margins_batch`, :func:`closed_loop_radii`); these tests hold
them to :func:`loop_margins` and :func:`closed_loop_radius` of each loop alone, and the whole batched
box check to the per-loop one (``BoxArcCheck._check`` without early stop), bit for bit, on stable,
unstable and resonant loops.
"""

import dataclasses
import json
import math

import numpy as np

from commission.controllers.arc import arc_pack, paper_gains_implementable
from commission.controllers.linear import sampled_plant
from commission.controllers.margins import (closed_loop_radii, closed_loop_radius, frequency_grid, linearize_arc,
                                            linearize_pid, loop_margins, loop_margins_batch)
from commission.controllers.pid import pid_pack, pid_place_poles
from commission.controllers.plant import P_DELAY
from commission.paper import paper_pid_gains, reference_identification, reference_plant
from commission.robustness import BoxArcCheck, MarginFloors
from commission.spec import spec_from_mapping
from commission.tune.box import start_gains

SPEC = spec_from_mapping({})
TS = SPEC.period


def _bits(m) -> tuple:
    """Every field of a Margins as its exact bits (nan equal to nan)."""
    return tuple(np.float64(v).tobytes() if isinstance(v, float) else v
                 for v in dataclasses.astuple(m))


def _plants():
    out = [reference_plant(0.027), reference_plant(0.08), reference_plant(0.027, mode_hz=400.0, mode_damping=0.02,
                                                                           mode_ratio=0.4)]
    late = reference_plant(0.027)
    late[P_DELAY] += 1.5 * TS  # one and a half samples more, s
    out.append(late)
    return [sampled_plant(p, TS) for p in out]


def _controllers():
    ap = arc_pack(paper_gains_implementable())
    th = paper_gains_implementable().theta0
    ctrls = [linearize_arc(ap, th), linearize_arc(ap, (th[0] * 3.0, th[1] * 0.5, th[2]))]
    for pole in (150.0, 300.0, 900.0):  # 900 rad/s: unstable on the reference plant
        Kp, Ki, Kd = pid_place_poles(0.02, -pole)
        ctrls.append(linearize_pid(pid_pack(dataclasses.replace(paper_pid_gains(TS), Kp=Kp, Ki=Ki, Kd=Kd))))
    return ctrls


def test_batched_loop_margins_and_radii_equal_each_loop_alone_to_the_last_bit():
    f = frequency_grid(TS)
    plants, ctrls = _plants(), _controllers()
    pairs = [(c, p) for c in ctrls for p in plants]
    radii = closed_loop_radii([c for c, _ in pairs], [p.state_space() for _, p in pairs])
    assert radii.shape == (len(pairs),)
    for r, (c, p) in zip(radii, pairs):
        assert np.float64(r).tobytes() == np.float64(closed_loop_radius(c, p)).tobytes()
    batch = loop_margins_batch([c.frequency_response(f) for c, _ in pairs], [p.frequency_response(f) for _, p in pairs],
                               f, TS, radii)
    alone = [loop_margins(c, p, f) for c, p in pairs]
    assert [_bits(m) for m in batch] == [_bits(m) for m in alone]
    # the set covers what the margins distinguish: stable and unstable loops, with and without a gain margin
    assert any(m.stable for m in alone) and not all(m.stable for m in alone)
    assert any(math.isfinite(m.gain_margin_db) for m in alone)
    assert loop_margins_batch([], [], f, TS, np.empty(0)) == []


def test_the_batched_box_check_equals_the_per_loop_check_to_the_last_bit():
    floors = MarginFloors.from_spec(SPEC)
    spec_mode = spec_from_mapping({"plant": {"mode_hz": 500.0, "mode_damping": 0.05, "mode_ratio": 0.3}})
    ident = reference_identification(delta_d=0.5)
    holds = []
    for spec in (SPEC, spec_mode):
        for delayed in (False, True):
            chk = BoxArcCheck(ident, spec, delay_any_estimate=delayed)
            for g in start_gains(ident, spec)[:2]:
                for scale in (1.0, 4.0):  # 4 x the caps: unstable somewhere in the box
                    g2 = dataclasses.replace(g, k1s_max=g.k1s_max * scale, k2s_max=g.k2s_max * scale)
                    batched, alone = chk(g2), chk._check(g2, None)
                    assert batched is not None and alone is not None
                    assert json.dumps(batched.to_dict(floors), sort_keys=True) == json.dumps(alone.to_dict(floors),
                                                                                           sort_keys=True)
                    assert [_bits(r.margins) for r in batched.at_plant] == [_bits(r.margins) for r in alone.at_plant]
                    assert batched.any_estimate == alone.any_estimate
                    holds.append(batched.holds(floors))
    assert any(holds) and not all(holds)
