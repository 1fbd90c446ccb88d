"""``python -m commission.formats [ROOT]``: rewrite the generated schema files and docs tables."""

import sys
from pathlib import Path

from commission.formats.generated import write_generated

for p in write_generated(Path(sys.argv[1] if len(sys.argv) > 1 else ".")):
    print(f"wrote {p}")
