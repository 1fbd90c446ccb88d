"""Command registry: one import per command module."""
from commission.cli import identify_cmd  # noqa: F401
