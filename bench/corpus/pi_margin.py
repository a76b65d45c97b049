#!/usr/bin/env python3
"""Gain margin of a carriage PI on the delta's predicted FRFs (docs/decisions.md, "The delta's PI").

Usage (from the repository root, after building):
  python3 bench/corpus/pi_margin.py [--config config/examples/delta_sim.yaml] [--delay-ms 1.5]
      [--gains 0.5:20,0.05:5,0.02:2,0.01:2]

For each position of a grid over the print disc it runs `feedloop model frf` (Eq. 29, the
virtual-work form the config names), takes each carriage's diagonal FRF G_ii(jw) (2-125 Hz), forms
the loop L = (kp + ki / jw) G_ii e^(-jw delay) of the device loop's PI (its correction acts through
the carriage's electrical part) and prints, per gain pair, the largest |L| where the phase of L
crosses -180 deg and the gain margin 1 / max|L| (below 1: unstable). The cross-coupling terms are
small below the resonance (|G_ij| < 0.01 |G_ii| at 2 Hz) and are left out.
"""
import argparse
import cmath
import csv
import math
import os
import subprocess
import tempfile

POSITIONS = ["0,0,30", "-80,0,30", "40,-69,30", "40,69,30", "120,0,30", "-125,0,5", "60,-120,1",
             "100,0,200", "-100,0,200", "0,-130,30", "0,130,30", "-130,30,100", "130,0,5"]


def frf(feedloop, config, pos, out):
    subprocess.run([feedloop, "model", "frf", "--config", config, "--pos", pos, "--out", out, "--virtual-work"],
                   check=True, stdout=subprocess.DEVNULL)
    rows = list(csv.DictReader(open(out)))
    return [(float(r["freq_hz"]), [complex(float(r[f"{a}_{a}_re"]), float(r[f"{a}_{a}_im"])) for a in "ABC"])
            for r in rows]


def worst_crossing(data, kp, ki, delay_s):
    worst, where = 0.0, None
    for pos, d in data.items():
        for i in range(3):
            prev = None
            for f, g in d:
                w = 2 * math.pi * f
                loop = (kp + ki / (1j * w)) * g[i] * cmath.exp(-1j * w * delay_s)
                ph = cmath.phase(loop)
                if prev is not None and ((prev > 2.5 and ph < -2.5) or (prev < -2.5 and ph > 2.5)):
                    if abs(loop) > worst:
                        worst, where = abs(loop), (pos, "ABC"[i], f)
                prev = ph
    return worst, where


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--config", default="config/examples/delta_sim.yaml")
    ap.add_argument("--feedloop", default="build/cli/feedloop")
    ap.add_argument("--delay-ms", type=float, default=1.5)
    ap.add_argument("--gains", default="0.5:20,0.1:5,0.05:5,0.02:2,0.015:2,0.01:2,0.01:5,0.005:2")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        data = {p: frf(a.feedloop, a.config, p, os.path.join(tmp, "frf.csv")) for p in POSITIONS}
    peak = max((abs(g), p, "ABC"[i], f) for p, d in data.items() for f, gs in d for i, g in enumerate(gs))
    print("largest |G_ii|: %.1f (carriage %s at %s, %.1f Hz); %d positions, delay %.1f ms"
          % (peak[0], peak[2], peak[1], peak[3], len(POSITIONS), a.delay_ms))
    for pair in a.gains.split(","):
        kp, ki = (float(x) for x in pair.split(":"))
        worst, where = worst_crossing(data, kp, ki, a.delay_ms * 1e-3)
        margin = 1.0 / worst if worst > 0 else math.inf
        print("kp %-6g ki %-4g  max |L| at -180 deg %6.3f  gain margin %5.2f  %s  (at %s)"
              % (kp, ki, worst, margin, "stable" if margin > 1 else "UNSTABLE", where))


if __name__ == "__main__":
    main()
