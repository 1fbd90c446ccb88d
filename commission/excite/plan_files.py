"""The plan's files: plan.json, plan.csv and plan.h5, and the injection windows identify reads back."""

from __future__ import annotations

import json
import os
from typing import Any, Mapping

import numpy as np

from commission.errors import SchemaError
from commission.excite.plan import Plan
from commission.formats.plan_json import check_plan

PLAN_COLUMNS = ("t", "q_ref", "v_ref", "u_inject")


def plan_columns(plan: Plan) -> dict[str, np.ndarray]:
    """plan.csv's columns, in order."""
    return {"t": plan.t, "q_ref": plan.q_ref, "v_ref": plan.v_ref, "u_inject": plan.u_inject}


def write_plan_csv(path: str | os.PathLike[str], plan: Plan) -> None:
    """``t,q_ref,v_ref,u_inject``, one row per sample, 12 significant digits."""
    cols = plan_columns(plan)
    arr = np.column_stack([cols[c] for c in PLAN_COLUMNS])
    np.savetxt(path, arr, delimiter=",", header=",".join(PLAN_COLUMNS), comments="", fmt="%.12g")


def write_plan_h5(path: str | os.PathLike[str], plan: Plan) -> None:
    """The columns of plan.csv as 1-D float64 datasets at the root; units as root attributes."""
    import h5py

    with h5py.File(path, "w") as f:
        for name, col in plan_columns(plan).items():
            f.create_dataset(name, data=np.asarray(col, np.float64))
        f.attrs["q_unit"] = plan.spec.q_unit
        f.attrs["u_unit"] = plan.spec.u_unit
        f.attrs["sample_rate"] = plan.spec.sample_rate


def injection_ranges(plan: Mapping[str, Any], t: np.ndarray, trim_s: float = 0.05) -> list[tuple[int, int]]:
    """Sample ranges ``[i0, i1)`` of a log recorded from ``plan`` (plan.json) that carry its broadband injection.

    The log's time is taken to start with the plan's (``t - t[0]`` against the plan's ``t``);
    each injection window (``segments[].windows_s``) is trimmed by ``trim_s`` s at both ends.

    Raises
    ------
    UsageError
        The log ends before the plan's injection does, or the plan has no injection segment.
    """
    from commission.errors import UsageError

    tt = np.asarray(t, float) - float(t[0])
    wins = [w for g in plan["segments"] if g["name"] == "injection" for w in g.get("windows_s", [])]
    if not wins:
        raise UsageError("--plan: the plan has no injection segment with windows_s")
    end = max(b for _a, b in wins)
    if tt[-1] < end - trim_s:
        raise UsageError(f"--plan: the log ends at {tt[-1]:.4g} s, before the plan's injection does "
                         f"({end:.4g} s): not a recording of this plan")
    out = []
    for a, b in wins:
        i0, i1 = int(np.searchsorted(tt, a + trim_s)), int(np.searchsorted(tt, b - trim_s))
        if i1 > i0:
            out.append((i0, i1))
    return out


def load_plan_json(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read plan.json strictly (for ``identify --plan``) through its table
    (:func:`commission.formats.plan_json.check_plan`): kind, schema version, segments with times.

    Returns
    -------
    dict
        The parsed plan.json.

    Raises
    ------
    SchemaError
        Naming the JSON path of a bad field.
    """
    name = os.fspath(path)
    try:
        with open(name, encoding="utf-8") as fh:
            d = json.load(fh)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SchemaError(f"{name}: not a readable plan.json ({exc})") from None
    return check_plan(d, name)

