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


def test_a_coulomb_only_fit_gets_the_stribeck_rise_the_log_could_not_show():
    """Where the fit kept Coulomb friction only, the robustness scenarios add ``<case>/stribeck``: the
    identified plant with the reference axis's rise (CONTRACT section 5: fs = 1.2 fc, vs = 0.01, xi = 2),
    nothing else changed; a fit that resolved the rise, or an axis without friction, gets none."""
    import dataclasses

    from commission.artifacts import Estimate
    from commission.controllers.plant import P_FC, P_FS, P_VS, P_XI
    from commission.scenarios import identified_plant

    spec = default_spec()
    ref = reference_identification()  # the paper's plant, Stribeck fitted (fs 0.12, fc 0.10)
    assert [s.name for s in robustness_scenarios(ref, spec)] == ["case1/delay+1", "case2/delay+1"]
    coulomb = dataclasses.replace(ref, parameters={**{k: v for k, v in ref.parameters.items()
                                                      if k not in ("fs", "vs", "xi")},
                                                   "fs": None, "vs": None, "xi": None})
    base = identified_plant(coulomb, spec)
    assert base[P_FS] == base[P_FC] == 0.10
    by = {s.name: s for s in robustness_scenarios(coulomb, spec)}
    assert sorted(by) == ["case1/delay+1", "case1/stribeck", "case2/delay+1", "case2/stribeck"]
    for case in ("case1", "case2"):
        p = by[f"{case}/stribeck"].plant
        assert p[P_FS] == 1.2 * 0.10 and p[P_VS] == 0.01 and p[P_XI] == 2.0
        rest = [i for i in range(len(p)) if i not in (P_FS, P_VS, P_XI)]
        assert np.array_equal(p[rest], base[rest])
        assert by[f"{case}/stribeck"].tags == (case, "robustness")
    frictionless = dataclasses.replace(coulomb, parameters={**coulomb.parameters, "fc": Estimate(0.0, 0.0)})
    assert not [s for s in robustness_scenarios(frictionless, spec) if s.name.endswith("/stribeck")]
