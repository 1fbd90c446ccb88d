"""Friction map of constant-speed legs (identify.steady.friction_map) on the TRO2021 screw drives.

Reference: the odd parts tabulated in ../shared/data/screwdrive-tro2021/README.md ("Observed
steady-state map", computed there independently from the same files; data of Mablekos-Alexiou,
da Cruz and Bergeles, IEEE T-RO 37(4), 2021).  Each file is one leg: nothing crosses the joins.
"""

from __future__ import annotations

import math

import pytest
from shared_paths import TRO2021_DIR

from commission.identify.steady import friction_map
from commission.logs import load_log

pytestmark = pytest.mark.skipif(not TRO2021_DIR.is_dir(), reason="TRO2021 data not present")

# Odd part (T(+v) - T(-v)) / 2 in % of rated torque, README table, speeds >= 10 rpm.
README_ODD = {
    1: {10: 31.30, 20: 30.62, 30: 29.75, 40: 29.25, 50: 29.30, 60: 29.55, 70: 29.68, 80: 29.85,
        90: 30.30, 100: 30.55, 120: 31.70, 140: 32.68, 160: 33.65, 180: 34.72, 200: 36.00},
    2: {10: 47.52, 20: 47.50, 30: 47.10, 40: 48.12, 50: 48.15, 60: 48.25, 70: 49.35, 80: 49.67,
        90: 49.90, 100: 50.77, 120: 50.27, 140: 50.10, 160: 51.55, 180: 51.15, 200: 54.27},
    3: {10: 14.00, 13: 14.05, 17: 14.18, 20: 14.20, 25: 14.25, 30: 14.00, 40: 14.20, 50: 14.60,
        60: 14.70, 70: 14.60, 80: 14.55, 90: 14.80, 100: 15.00, 120: 15.20, 140: 15.60, 160: 16.52,
        180: 17.15, 200: 17.00},
}


def odd_part(drive: int) -> dict[int, tuple[float, float]]:
    """rpm -> (|mean speed| in rpm, odd part in %) from the drive's steady-state files."""
    folder = TRO2021_DIR / f"driveNo{drive}" / "steady_state" / "0.096kg"
    files = sorted(folder.glob("*.csv"))
    logs = [load_log(f) for f in files]
    fmap = friction_map([(log.t, log.q, log.u) for log in logs])
    by = {f.stem: (v, F) for f, v, F in zip(files, fmap.velocity, fmap.force)}
    out = {}
    for name, (v, F) in by.items():
        if not name.startswith("n") and "n" + name in by:
            v_neg, F_neg = by["n" + name]
            # Odd in (v, F): (F(v) - F(-v)) / 2 with v the leg's own (signed) mean speed.
            sign = 1.0 if v > v_neg else -1.0
            out[int(name)] = (abs(v) * 30 / math.pi, sign * (F - F_neg) / 2)
    return out


@pytest.mark.parametrize("drive", [1, 2, 3])
def test_odd_part_within_5_percent_of_readme_at_10_rpm_and_above(drive):
    odd = odd_part(drive)
    for rpm, ref in README_ODD[drive].items():
        speed, value = odd[rpm]
        assert speed == pytest.approx(rpm, rel=0.02, abs=1.5)
        assert value == pytest.approx(ref, rel=0.05), (drive, rpm)


@pytest.mark.parametrize("drive, has_dip", [(1, True), (2, False), (3, True)])
def test_stribeck_dip_for_drives_1_and_3_none_for_drive_2(drive, has_dip):
    odd = odd_part(drive)
    slow = odd[min(odd)][1]
    lowest = min(value for rpm, (_, value) in odd.items() if rpm <= 100)
    dip = (slow - lowest) / lowest  # README: ~7 % (drive 1), ~10 % (drive 3), < 1 % (drive 2)
    assert (dip > 0.03) == has_dip, dip
