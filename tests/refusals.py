"""One check for the readers' refusals: a file with this content is refused with this error.

Shared by the tests of every reader that takes a file a user writes (logs, fleet
manifests), so that each states only its table of bad contents and messages.
"""

from __future__ import annotations

from pathlib import Path

import pytest


def assert_refused(path: Path, content: str | bytes, load, error: type[Exception], match: str):
    """Write ``content`` (text, or bytes as they are) to ``path``; ``load(path)`` must raise ``error`` matching ``match``."""
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    with pytest.raises(error, match=match):
        load(path)
