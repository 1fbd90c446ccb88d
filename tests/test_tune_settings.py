"""commission/tune/settings.py: tune's knobs in one frozen, documented object that the stages read.

Checked: every field carries its own ``#:`` documentation; no other module of ``commission.tune``
defines a knob of its own (only the facts and encodings listed below stay module constants); and a
knob changed on the object (not on a module) changes what the stage does, against a closed form.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import math
import pathlib

import pytest

import commission.tune as tune_pkg
from commission.tune.settings import DEFAULT_SETTINGS, TuneSettings

#: Upper-case names a tune module may define that are not knobs: the paper's reference axis, the
#: layout of the free vector, and the encoding of the candidates' order.
NOT_KNOBS = {"PAPER_THETA1", "PAPER_RATE", "PAPER_THETA1_0", "N_FREE", "I_THETA1_0", "FEASIBLE",
             "GATE_MISSED", "STABILITY_MISSED", "LEVEL_OFFSET", "SCREEN_OFFSET", "DEFAULT_SETTINGS"}


def test_every_field_is_documented_above_its_line():
    src = inspect.getsource(TuneSettings).splitlines()
    fields = [f.name for f in dataclasses.fields(TuneSettings)]
    assert len(fields) == len(set(fields)) > 40
    for name in fields:
        i = next(k for k, line in enumerate(src) if line.strip().startswith(f"{name}:"))
        assert src[i - 1].strip().startswith("#:"), f"{name} has no #: documentation"


def test_no_tune_module_defines_a_knob_of_its_own():
    for path in sorted(pathlib.Path(tune_pkg.__file__).parent.glob("*.py")):
        for node in ast.parse(path.read_text()).body:
            targets = node.targets if isinstance(node, ast.Assign) else (
                [node.target] if isinstance(node, ast.AnnAssign) else [])
            names = [n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)]
            for n in names:
                if n.isupper() and n != "__all__":
                    assert n in NOT_KNOBS, f"{path.name} defines {n}: a knob belongs in TuneSettings"


def test_settings_are_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        DEFAULT_SETTINGS.population = 4  # type: ignore[misc]


def test_the_last_matched_start_scale_is_the_low_cap():
    assert math.isclose(DEFAULT_SETTINGS.match_scales[-1], DEFAULT_SETTINGS.cap_low)
