"""Where the read-only ``shared/`` folder (EMPS data, contract) is.

CI clones the repository with ``shared/`` beside it; developers may point
``COMMISSION_SHARED`` elsewhere.  Searched: that variable, then ``shared/``
beside every parent of this file.
"""

from __future__ import annotations

import os
from pathlib import Path


def find_shared() -> Path:
    env = os.environ.get("COMMISSION_SHARED")
    candidates = [Path(env)] if env else []
    candidates += [p / "shared" for p in Path(__file__).resolve().parents]
    for c in candidates:
        if (c / "data" / "emps" / "DATA_EMPS.mat").is_file():
            return c
    raise FileNotFoundError(
        "shared/data/emps/DATA_EMPS.mat not found beside the repository; set COMMISSION_SHARED"
    )


SHARED = find_shared()
EMPS_DIR = SHARED / "data" / "emps"
TRO2021_DIR = SHARED / "data" / "screwdrive-tro2021" / "experiments"
ODRIVE_DIR = SHARED / "data" / "odrive-cogging"
