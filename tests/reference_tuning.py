"""A short tune of the paper's reference axis, as the validation tests use it.

``tune.budget = 8`` keeps it to seconds; the identification's sha256 is recorded as
identify would have written it (its canonical JSON), because validate checks the
embedded identification against it when ident.json is not at hand."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from commission.jsonio import sha256_json
from commission.paper import reference_identification
from commission.spec import spec_from_mapping
from commission.tune.api import tune
from commission.tuning import Tuning


def reference_tuning(budget: int = 8) -> Tuning:
    """The reference axis (delta_d 0.5) tuned with ``budget`` candidates, search seed 0."""
    ident = reference_identification(delta_d=0.5)
    return tune(ident, spec_from_mapping({"tune": {"budget": budget}}), rng=np.random.default_rng(0), seed=0,
                ident_sha256=sha256_json(ident.to_dict()), log_sha256="2" * 64)


def saved_reference_tuning(directory: Path, budget: int = 8) -> tuple[Tuning, Path]:
    """:func:`reference_tuning`, and the path of its ``tuning.json`` saved in ``directory``."""
    t = reference_tuning(budget=budget)
    path = directory / "tuning.json"
    t.save(str(path))
    return t, path
