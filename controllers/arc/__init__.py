"""Discrete output-feedback adaptive robust controller (ARC) of Xu & Yao (2001), sec. 3.

The law runs once per sample from the measured position and the desired motion;
everything it needs is packed into one float64 vector and everything it carries from
one sample to the next into another, so that the simulator, ``validate``, the runtime
and the generated C run the same compiled step on the same layout.

Modules
-------
* :mod:`~commission.controllers.arc.layout`: the slots of the packed parameter and state
  vectors (``P_*``, ``S_*``, ``NP``, ``NS``), the fault codes (``FAULT_*``) and
  :data:`V_LOOP_RATE_LIMIT`;
* :mod:`~commission.controllers.arc.gains`: :class:`ArcGains` and its checks, why the
  paper's robust terms are capped, and the sec. 4.3 parameters
  (:func:`paper_gains_as_printed`, :func:`paper_gains_implementable`);
* :mod:`~commission.controllers.arc.pack`: :func:`arc_pack` (the exact hold matrices of
  the filters, the gains' quadratic weights) and :func:`arc_new_state`;
* :mod:`~commission.controllers.arc.alpha1`: step 1 of the law, alpha_1 and its exact
  partials (:func:`alpha1_and_partials`);
* :mod:`~commission.controllers.arc.step`: the law itself and its runtime guards, the
  compiled :func:`arc_step` and :func:`arc_reset`.

This package's namespace is also what :mod:`commission.export.c_target` translates to C:
it reads the step and the compiled functions it calls (``_alpha1``, ``_fault``) and every
layout constant from here by name, and names this package in the generated C, which is
why those two private functions are imported here as well.
"""

from __future__ import annotations

from commission.controllers.arc.layout import *  # noqa: F401,F403 - every P_*/S_*/FAULT_* slot (C header)
from commission.controllers.arc.gains import (RUNTIME_GUARDS, ArcGains, ArcGainsError, paper_gains_as_printed,
                                              paper_gains_implementable)
from commission.controllers.arc.pack import arc_new_state, arc_pack
from commission.controllers.arc.alpha1 import _alpha1, alpha1_and_partials  # noqa: F401 - _alpha1: the C export
from commission.controllers.arc.step import _fault, arc_reset, arc_step  # noqa: F401 - _fault: the C export
