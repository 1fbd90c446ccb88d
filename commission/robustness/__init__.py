"""Stability margins of the tuned loops over the identified plant set.

The margins themselves (definitions, how the ARC's adaptive and robust terms
are linearised) are :mod:`commission.controllers.margins`; this package chooses
where to evaluate them and records them for ``tuning.json``,
``validation.json`` and ``report.md``:

* **plants**: the identified plant (its mode and input delay included,
  :func:`commission.scenarios.plant_dynamics`) and the four (theta1, theta2)
  corners of the Assumption-1 box (mass ``1/theta1``, viscous ``theta2/theta1``);
* **PID**: linear but for its friction compensation, one loop per plant;
* **ARC**: linearised twice per plant, with the estimate at its initial value
  theta_hat(0) (the start-up, before any adaptation) and at the plant's own
  theta (what the adaptation tends to when the motion excites it), since the
  sampled loop's stability depends on the estimate (``controllers/arc/step.py``).

Floors (``[margins]`` of spec.toml; defaults 6 dB, 30 deg, one sample beyond
the identified delay and modulus 0.5, common practice for servo loops) are checked per loop;
:func:`floor_violations` names each one missed, and :func:`commission.gate.margin_checks` turns
those of the identified plant into gate checks.

Which module holds what
-----------------------
* :mod:`commission.robustness.margins` -- the floors (:class:`MarginFloors`), one loop's record
  (:class:`LoopMargins`) and the loops on the identified plant and the box's corners
  (:func:`margin_table`, :class:`IdentifiedPlantArcMargins`, :func:`nominal_loops`);
* :mod:`commission.robustness.box` -- the ARC over the whole box (:class:`BoxArcCheck`,
  :func:`box_plants`, :class:`BoxRobustness`);
* :mod:`commission.robustness.payload` -- the payload range of ident.json's box
  (:func:`payload_box`, :func:`narrowed_ident`, :func:`certified_payload`,
  :func:`identified_performance`).
"""

from commission.robustness.box import (BOX_DELAY_ANY_ESTIMATE, BOX_DELAY_EXTRA, AnyEstimateWorst, BoxArcCheck,
                                       BoxRobustness, box_check, box_plants)
from commission.robustness.margins import (CONTROLLERS, IdentifiedPlantArcMargins, LoopMargins, MarginFloors,
                                           floor_violations, margin_plants, margin_rows, margin_table, nominal_loops,
                                           worst)
from commission.robustness.payload import (PAYLOAD_BISECTIONS, certified_payload, identified_performance,
                                           narrowed_ident, narrowed_theta_min, payload_box)

__all__ = ["AnyEstimateWorst", "BOX_DELAY_ANY_ESTIMATE", "BOX_DELAY_EXTRA", "BoxArcCheck", "BoxRobustness",
           "CONTROLLERS", "IdentifiedPlantArcMargins", "LoopMargins", "MarginFloors", "PAYLOAD_BISECTIONS",
           "box_check", "box_plants", "certified_payload", "floor_violations", "identified_performance",
           "margin_plants", "margin_rows", "margin_table", "narrowed_ident", "narrowed_theta_min", "nominal_loops",
           "payload_box", "worst"]
