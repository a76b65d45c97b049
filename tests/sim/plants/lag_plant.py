#!/usr/bin/env python3
"""A plant for feedloop's External plant v1 contract (DESIGN.md), written for the tests.

Each axis's carriage follows its commanded motor position through a second-order lag (a belt
spring and a damper: natural frequency --freq-hz, damping ratio --zeta), so the carriage lags and
overshoots the staircase the way a belt-driven axis does. Options make it misbehave on purpose:

  --exit-after N      exit with status 3 after N periods
  --exit-into-motion N  exit with status 3 N periods after the first commanded motion
  --garbage-after N   answer N periods, then a line that is not numbers
  --silent-after N    answer N periods, then stop answering (and keep running)
  --greeting TEXT     answer the handshake with TEXT instead of 'ready'

It checks the contract from its side and exits with status 2 and a message on stderr when
feedloop breaks it: the handshake line, t_s = k * period_s, one number per axis.
"""
import argparse
import math
import re
import sys
import time


def fail(msg):
    sys.stderr.write("lag_plant: contract violated: %s\n" % msg)
    sys.exit(2)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--freq-hz", type=float, default=60.0)
    ap.add_argument("--zeta", type=float, default=0.3)
    ap.add_argument("--exit-after", type=int, default=-1)
    ap.add_argument("--exit-into-motion", type=int, default=-1)
    ap.add_argument("--garbage-after", type=int, default=-1)
    ap.add_argument("--silent-after", type=int, default=-1)
    ap.add_argument("--greeting", default="ready")
    a = ap.parse_args()

    stdin, stdout = sys.stdin.buffer, sys.stdout
    hello = stdin.readline().decode("ascii", "replace").rstrip("\n")
    m = re.fullmatch(r"feedloop-plant 1 axes=([A-Za-z](?:,[A-Za-z])*) period_s=([0-9.eE+-]+)", hello)
    if not m:
        fail("handshake %r" % hello)
    axes = m.group(1).split(",")
    period_s = float(m.group(2))
    n = len(axes)
    stdout.write(a.greeting + "\n")
    stdout.flush()

    w = 2.0 * math.pi * a.freq_hz
    pos = None   # carriage positions
    vel = [0.0] * n
    u_prev = None
    k = 0
    moving_since = None
    substeps = max(1, int(math.ceil(period_s * w / 0.2)))  # keep the integration stable
    h = period_s / substeps
    for raw in stdin:
        k += 1
        fields = raw.split()
        if len(fields) != n + 1:
            fail("line %d has %d fields, expected %d" % (k, len(fields), n + 1))
        t_s = float(fields[0])
        if abs(t_s - k * period_s) > 1e-9 * max(1.0, t_s):
            fail("period %d at t_s=%r, expected %r" % (k, t_s, k * period_s))
        u = [float(x) for x in fields[1:]]
        if pos is None:
            pos, u_prev = list(u), list(u)   # at rest at the start position
        if moving_since is None and u != u_prev:
            moving_since = k
        if k == a.exit_after or (moving_since is not None and k - moving_since == a.exit_into_motion):
            sys.exit(3)
        if k == a.garbage_after:
            stdout.write("1.0 banana\n")
            stdout.flush()
            continue
        if k == a.silent_after:
            time.sleep(3600)
        # The staircase held over the period: the value at its start (the previous end).
        for i in range(n):
            for _ in range(substeps):
                acc = w * w * (u_prev[i] - pos[i]) - 2.0 * a.zeta * w * vel[i]
                vel[i] += acc * h
                pos[i] += vel[i] * h
        u_prev = u
        stdout.write(" ".join("%.12g" % p for p in pos) + "\n")
        stdout.flush()


if __name__ == "__main__":
    main()
