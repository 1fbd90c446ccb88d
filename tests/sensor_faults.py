"""Faults of the position reading, as functions ``sensor(k, y) -> y`` between the encoder and the step.

The closed-loop simulator cannot express a reading that stops following the axis, so the
runtime guards' tests (``tests/test_runtime_guards.py``) and ``benchmarks/bench_frozen_encoder.py``
pass every reading through one of these in their own sample loop.  One definition, so that
the benchmark's figures are of the very fault the tests pin.
"""

from __future__ import annotations


def frozen(k0: int, n: int):
    """An encoder that repeats the reading of sample k0 - 1 over samples k0 .. k0 + n - 1 (``n`` samples)."""
    held = {}

    def sensor(k, y):
        if k == k0 - 1:
            held["y"] = y
        return held["y"] if k0 <= k < k0 + n else y
    return sensor
