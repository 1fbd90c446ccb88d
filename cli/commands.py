"""Command registry: one import per command module."""
from commission.cli import paper_cmd  # noqa: F401
from commission.cli import identify_cmd  # noqa: F401
from commission.cli import validate_cmd  # noqa: F401
from commission.cli import run_cmd  # noqa: F401
from commission.cli import tune_cmd  # noqa: F401
from commission.cli import export_cmd  # noqa: F401
