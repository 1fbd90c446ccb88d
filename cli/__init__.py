"""Command line of commission (typer).  The only layer that imports typer and matplotlib."""
