"""A controller.json document edited by hand, sealed again as the tool seals it.

What someone who edits the file and holds the key (or needs none) does: the checksum
recomputed, and, ``key`` given, the HMAC-SHA256 signature too, so that what a test edits
reaches the schema checks instead of stopping at the checksum.  Shared by the tests of
the strict loader (``test_artifact_strictness.py``) and of a unit planted to inject C
(``test_artifacts_hostile_unit.py``).
"""

from __future__ import annotations

import hashlib
import hmac

from commission.jsonio import canonical_json, sha256_json


def reseal(doc: dict, key: bytes | None = None) -> dict:
    """``doc`` in place with its checksum (and, ``key`` given, its signature) recomputed."""
    doc.pop("checksum", None)
    if key is not None:
        body = {k: v for k, v in doc.items() if k != "signature"}
        doc["signature"] = {"algorithm": "hmac-sha256",
                            "value": hmac.new(key, canonical_json(body).encode(), hashlib.sha256).hexdigest()}
    doc["checksum"] = {"algorithm": "sha256", "value": sha256_json(doc)}
    return doc
