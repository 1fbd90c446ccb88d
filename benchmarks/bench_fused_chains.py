"""How much a batch could gain by stepping two plants in one loop (an exact option not built yet).

One closed-loop run is a chain of dependent floating-point operations: each plant sub-step
needs the previous one's position and velocity, so a core runs it at the latency of that chain
(a division, a few multiplies and adds per sub-step), not at its throughput.  Two independent
runs stepped in the same loop iteration give the core two chains to overlap, with every run's
operations unchanged (the same values to the last bit).

This script times the identified sample axis's coupled sub-step (the body of
:func:`commission.controllers.plant.plant_step` for one mode, rewritten here on scalars) for two
runs of 25 000 samples x 11 sub-steps: one after the other (as :func:`simulate_batch` runs rows
today, per sample or per run: the same chains), and fused in one loop.  It checks that both give
the same final states and prints the two CPU times and their ratio.

Run: ``python benchmarks/bench_fused_chains.py``.  Prints figures; asserts nothing.
"""

from __future__ import annotations

import math
import statistics
import time

from numba import njit

K, C, M1, M2, HH, FS, B, FC, OFF = 3e5, 2.0, 0.013, 0.013, 0.0004 / 11, 0.1, 0.26, 0.1, 0.008


@njit(cache=False)
def _sub(x1, v1, x2, v2, u):
    """One coupled sub-step (motor side with Coulomb friction and stiction, load on a spring)."""
    fk = K * (x1 - x2) + C * (v1 - v2)
    F = u - OFF - fk
    if v1 == 0.0:
        if abs(F) <= FS:
            v1n = 0.0
        else:
            v1n = (F - math.copysign(FS, F)) / M1 * HH
    else:
        v1n = v1 + (F - B * v1 - math.copysign(FC, v1)) / M1 * HH
        if v1n * v1 < 0.0 and FS > 0.0:
            v1n = 0.0
    v2 = v2 + fk / M2 * HH
    x1 += v1n * HH
    x2 += v2 * HH
    return x1, v1n, x2, v2


@njit(cache=False)
def _drive(i):
    """The held command of sample ``i`` (a square wave of 0.4 s period), u-unit."""
    return 0.3 * ((i // 500) % 2 - 0.5)


@njit(cache=False)
def _chain(s, u, nsub):
    """``nsub`` sub-steps of one run from the state ``s``."""
    for _ in range(nsub):
        s = _sub(s[0], s[1], s[2], s[3], u)
    return s


@njit(cache=False)
def one_after_the_other(n, nsub):
    a = b = (0.0, 0.0, 0.0, 0.0)
    for i in range(n):
        a = _chain(a, _drive(i), nsub)
        b = _chain(b, -0.7 * _drive(i), nsub)
    return a, b


@njit(cache=False)
def fused(n, nsub):
    a = b = (0.0, 0.0, 0.0, 0.0)
    for i in range(n):
        ua, ub = _drive(i), -0.7 * _drive(i)
        for _ in range(nsub):  # the two runs' sub-steps side by side: two chains for the core to overlap
            a = _sub(a[0], a[1], a[2], a[3], ua)
            b = _sub(b[0], b[1], b[2], b[3], ub)
    return a, b


def main() -> None:
    n, nsub = 25_000, 11
    assert one_after_the_other(10, nsub) == fused(10, nsub)
    same = one_after_the_other(n, nsub) == fused(n, nsub)
    times = {}
    for fn in (one_after_the_other, fused, one_after_the_other, fused):
        ts = []
        for _ in range(15):
            c0 = time.thread_time()
            fn(n, nsub)
            ts.append(time.thread_time() - c0)
        times.setdefault(fn.__name__, []).append(min(ts))
    seq = statistics.median(times["one_after_the_other"]) * 1e3
    fu = statistics.median(times["fused"]) * 1e3
    print(f"two runs of {n} samples x {nsub} coupled sub-steps: one after the other {seq:.2f} ms CPU, "
          f"fused {fu:.2f} ms CPU (x{seq / fu:.2f} throughput); identical states: {same}")


if __name__ == "__main__":
    main()
