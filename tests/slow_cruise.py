"""Record a random axis's excite log on the slow injection cruise excite planned before the swing rule.

``commission excite`` now raises the injection's cruise until the injection's velocity swing on the
pre-simulation's light model stays within it (:func:`commission.excite.presim.plan_run`).  Some
identification tests pin what the code does with a log whose friction crossed zero under the
injection (a negative viscous estimate of a delay-aware model, a low-frequency departure): they
record that log as it was, with the swing rule switched off (the swing fraction made infinite, so
that no plan is raised -- the only difference between the two plans), which also holds for a
shortened plan, whose ``[plan]`` table replaces the axis's.
"""

from __future__ import annotations

import math
import os

import pytest


def record_on_the_slow_cruise(seed: int, path: str | os.PathLike[str]):
    """:func:`commission.synth.record_random_axis_log` of ``seed`` with the injection at its default cruise."""
    import commission.excite.presim as presim
    from commission.synth import record_random_axis_log

    with pytest.MonkeyPatch.context() as m:
        m.setattr(presim, "INJECTION_SWING_FRACTION", math.inf)
        return record_random_axis_log(seed, path)
