"""What a whole run left for the machine, by its verdict (a helper of the end-to-end tests)."""


def deployable(r, out):
    """The deployable file a run left: controller.json (the whole gate passed) or, since issue 30, the ARC
    flagged in controller_not_better.json when it is safe and within every limit but does not beat the
    margin-floored PID yardstick (the only other verdict accepted here)."""
    assert r.exit_code in (0, 1), r.output
    if r.exit_code == 1:
        assert "Safe, but not better than the PID yardstick." in r.output, r.output
        return out / "controller_not_better.json"
    return out / "controller.json"
