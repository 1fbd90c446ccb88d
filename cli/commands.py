"""Command registry: one import per command module."""
