"""tuning.json's provenance checked before validating (:func:`check_provenance`): the embedded
identification must be the one of the ident.json whose sha256 the tuning records.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Mapping

from commission.errors import SchemaError
from commission.jsonio import canonical_json, read_json, sha256_file, sha256_json
from commission.tuning import Tuning


def _identification_as_identified(tuning: Tuning) -> dict[str, Any]:
    """tuning.json's embedded identification as ident.json held it: tune's theta3 narrowing undone.

    ``tune`` may narrow the theta3 box (:func:`commission.tune.narrow_disturbance_box`) and
    records the box it started from in ``bounds.narrowed_by_tune``; restoring that box and
    dropping the record gives back the identification tune read.  A record that does not
    contain the narrowed box is left as it is (and the comparison that follows then fails).
    """
    embedded = json.loads(json.dumps(tuning.identification.to_dict()))
    _undo_payload_narrowing(embedded)
    narrowed = (embedded.get("bounds") or {}).pop("narrowed_by_tune", None)
    if isinstance(narrowed, dict):
        lo, hi = embedded["theta"]["min"][2], embedded["theta"]["max"][2]
        t3min, t3max = narrowed.get("theta3_min"), narrowed.get("theta3_max")
        if (isinstance(t3min, (int, float)) and isinstance(t3max, (int, float)) and t3min <= lo <= hi <= t3max
                and _narrowed_as_recorded(narrowed, lo, hi, embedded["theta"]["max"][0],
                                          embedded["theta"]["min"][0])):
            embedded["theta"]["min"][2], embedded["theta"]["max"][2] = t3min, t3max
    return embedded


def _undo_payload_narrowing(embedded: dict[str, Any]) -> None:
    """Undo tune's narrowing of a defaulted payload range (``bounds.payload_narrowed_by_tune``,
    :func:`commission.tune.box.narrow_default_payload`) in place.

    Restored only when the record is consistent with a narrowing (the recorded box's lower ends
    at or below the embedded ones, the embedded theta1_min = 1/M_hi of the embedded mass range,
    the narrowed payload within the default one); otherwise the record is left, and the
    comparison that follows fails.
    """
    bounds = embedded.get("bounds")
    rec = bounds.get("payload_narrowed_by_tune") if isinstance(bounds, dict) else None
    if not isinstance(rec, dict):
        return
    try:
        t1, t2 = float(rec["theta1_min"]), float(rec["theta2_min"])
        dpay, dmass = [float(x) for x in rec["default_payload_range"]], [float(x) for x in rec["default_mass_range"]]
        pay, mass = [float(x) for x in bounds["payload_range"]], [float(x) for x in bounds["mass_range"]]
        tmin = embedded["theta"]["min"]
        ok = (t1 <= tmin[0] and t2 <= tmin[1] and dpay[0] == pay[0] and pay[1] <= dpay[1]
              and math.isclose(1.0 / tmin[0], mass[1], rel_tol=1e-9) and dmass[0] == mass[0])
    except (KeyError, TypeError, ValueError, IndexError, ZeroDivisionError):
        return
    if not ok:
        return
    bounds.pop("payload_narrowed_by_tune")
    tmin[0], tmin[1] = t1, t2
    bounds["payload_range"], bounds["mass_range"] = dpay, dmass


def _narrowed_as_recorded(narrowed: Mapping[str, Any], lo: float, hi: float, theta1_max: float,
                          theta1_min: float) -> bool:
    """The narrowed theta3 box is the one tune recorded as a force range (``narrowed_force_range``,
    the force the box admits at every mass, :func:`commission.scenarios.force_range`), so that a box
    shrunk further by hand inside the narrowing is not taken for tune's; a record without the force
    range is taken as it is."""
    from commission.scenarios.box import forces_of_theta3

    rec = narrowed.get("narrowed_force_range")
    if rec is None:
        return True
    if not (isinstance(rec, list) and len(rec) == 2 and all(isinstance(x, (int, float)) for x in rec)):
        return False
    forces = forces_of_theta3(lo, hi, 1.0 / theta1_max, 1.0 / theta1_min)
    return all(math.isclose(r, f, rel_tol=1e-9, abs_tol=1e-300) for r, f in zip(rec, forces))


def check_provenance(tuning: Tuning, tuning_path: str) -> None:
    """Check tuning.json's embedded identification against the ident.json it was tuned from.

    The embedded identification sets the plant box that validate simulates, so an edit there
    (a box shrunk to +-0.1 %) would validate a controller for an axis nobody identified.

    - **ident.json at hand**: it is looked for where ``provenance.ident_path`` says
      (relative to the working folder) and beside tuning.json under the same name.  Its
      sha256 must be ``provenance.ident_sha256``, and the embedded identification must be
      that file's content, up to the theta3 narrowing that tune records
      (``bounds.narrowed_by_tune``: within the file's box, and the box tune recorded).
    - **ident.json not at hand** (tuning.json travels alone): ident.json as this tool writes
      it is the canonical JSON (:func:`commission.jsonio.canonical_json`) of its content, and
      tune embeds that content verbatim, so the canonical JSON of the embedded
      identification, narrowing undone, hashes to ``provenance.ident_sha256``.  A mismatch
      is refused: the embedded identification was edited after tune, or tune read an
      ident.json this tool did not write (then give validate that file, beside tuning.json).
      An unkeyed hash catches edits, not an author who recomputes it: a signed
      controller.json (``--sign-key``) is what proves origin.

    Raises
    ------
    SchemaError
        Naming ``$.provenance.ident_sha256`` (ident.json changed since the tuning) or
        ``$.identification`` (tuning.json's identification edited).
    """
    rec = tuning.provenance.ident_path
    cands = [Path(rec), Path(tuning_path).parent / Path(rec).name]
    found = next((c for c in cands if c.is_file()), None)
    embedded = _identification_as_identified(tuning)
    if found is None:
        actual = sha256_json(embedded)
        if actual != tuning.provenance.ident_sha256:
            raise SchemaError(
                f"{tuning_path}: $.identification: hashes to {actual[:16]}..., not to $.provenance.ident_sha256 "
                f"{tuning.provenance.ident_sha256[:16]}..., and {rec} is not at hand to compare with: tuning.json "
                f"was edited after tune (the validated plant box would not be the identified one), or it was tuned "
                f"from an ident.json this tool did not write (put that ident.json beside tuning.json)")
        return
    actual = sha256_file(found)
    if actual != tuning.provenance.ident_sha256:
        raise SchemaError(f"{tuning_path}: $.provenance.ident_sha256: {tuning.provenance.ident_sha256[:16]}... is not "
                          f"the sha256 of {found} ({actual[:16]}...): that identification is not the one this tuning "
                          f"was made from (tune again, or validate with the matching ident.json)")
    from commission.artifacts import Identification

    ident = Identification.from_dict(read_json(found), source=str(found)).to_dict()
    if json.loads(canonical_json(embedded)) != json.loads(canonical_json(ident)):
        raise SchemaError(f"{tuning_path}: $.identification: differs from {found}, whose sha256 the tuning records: "
                          f"tuning.json was edited after tune (the validated plant box would not be the identified one)")
