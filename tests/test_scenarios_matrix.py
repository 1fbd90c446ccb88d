"""commission.scenarios.matrix: the tune-only families (box corners, largest forces, interior payloads)
and the robustness scenarios, named, ordered, tagged and encoded as validate and tune rely on."""

from __future__ import annotations

import numpy as np

from commission.paper import reference_identification
from commission.scenarios import (corner_scenarios, offset_scenarios, payload_scenarios, resolve_encoder_noise,
                                  resolve_quantization, robustness_scenarios, trajectories)
from commission.spec import default_spec, spec_from_mapping


def test_every_family_is_each_plant_on_every_trajectory_in_order():
    ident, spec = reference_identification(), spec_from_mapping({"plant": {"noise_std": 2e-7}})
    trajs = dict(trajectories(spec))
    expected = {
        "corner": ([f"corner/{c}/{b:03b}" for c in ("case1", "case2") for b in range(8)], ("corner", "tune")),
        "offset": ([f"offset/{c}/{e}" for c in ("case1", "case2") for e in ("lo", "hi")], ("offset", "tune")),
        "payload": ([f"payload/{c}/{k}" for c in ("case1", "case2") for k in ("0.25", "0.5", "0.75")],
                    ("payload", "tune")),
        "robustness": (["case1/delay+1", "case2/delay+1"], ("robustness",)),
    }
    got = {"corner": corner_scenarios(ident, spec), "offset": offset_scenarios(ident, spec),
           "payload": payload_scenarios(ident, spec), "robustness": robustness_scenarios(ident, spec)}
    for family, (names, tags) in expected.items():
        scenarios = got[family]
        assert [s.name for s in scenarios] == names, family
        for s in scenarios:
            case = s.name.split("/")[-2]
            assert s.tags == (case, *tags)
            assert s.trajectory == trajs[case] and s.y0 == 0.0 and s.disturbance.amplitude == 0.0
            assert s.quantization == resolve_quantization(ident, spec) == 1e-6
            assert s.noise_std == resolve_encoder_noise(ident, spec) == 2e-7
            assert not s.plant.flags.writeable


def test_a_family_is_the_same_plants_on_both_trajectories():
    # the plant does not depend on the trajectory: case1's k-th scenario and case2's k-th carry the same vector
    ident, spec = reference_identification(), default_spec()
    for family in (corner_scenarios, offset_scenarios, payload_scenarios, robustness_scenarios):
        scenarios = family(ident, spec)
        half = len(scenarios) // 2
        for a, b in zip(scenarios[:half], scenarios[half:]):
            assert a.name.replace("case1", "case2") == b.name
            assert np.array_equal(a.plant, b.plant)
