#!/usr/bin/env python3
"""`feedloop calibrate` on drawn machines of the second simulator (issue 15), one row per seed.

For each seed: the embedded simulated printer (config/examples/cartesian_sim.yaml) with the LPV
feedforward, its X and Y on the second simulator (`feedloop-plant2 --seed N`: X is drawn machine
N, Y drawn machine N + 1) as an external plant, in virtual time; `feedloop calibrate` runs the
calibration program, identifies both axes, installs the overlay and measures the check pattern's
e_t before (the config's thesis model), after (the calibrated model) and open loop. Prints a
table; the reports stay in --keep DIR when given.

    python3 bench/calibrate/calibrate_seeds.py [--build build] [--seeds 1-7] [--keep DIR] [--json F]
                                               [--effect KIND] [--ablate KEY] [--simulator plant2|sim]
                                               [--thesis]

--simulator sim: the first simulator (sim/, in-process, switches and all) instead, its seed the
row's, with --effect KIND (one of the config's simulated effects, config/README.md) or all of them
on X and Y, each size drawn from the seed in bench/ident_draws' ranges for that simulator.

--thesis: also the thesis's tests of bench/control (THESIS_CASES), before the calibration, open
loop and after, e_t measured as the check pattern's; a table per seed and a summary per case.

--ablate KEY (e.g. backlash_mm): after the calibration, every KEY of the installed overlay is set
to 0, the daemon reloads it, and the check pattern runs once more (`feedloop calibrate
--check-only`): the column `without` is e_t with the calibrated model less that one term, so the
term's own share is measured on the same machine.

Each seed takes about 75 s on a 2-core machine (two minutes of simulated motion in lock-step with
the external plant, four fits). Same build as the tests (the README's build directory).
"""
import argparse
import json
import socket
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


def seeds_from(text):
    out = []
    for part in text.split(","):
        if "-" in part:
            a, b = part.split("-")
            out.extend(range(int(a), int(b) + 1))
        else:
            out.append(int(part))
    return out


FIRST_SIM_EFFECTS = ["coulomb_friction", "backlash", "periodic_position", "direction_dependent_stiffness",
                     "extra_resonance", "time_delay", "scale_error"]


def first_sim_effect(kind, rng):
    """One simulated effect's config (simulator.effects, config/README.md), its size drawn from
    bench/ident_draws' ranges for the first simulator."""
    u = rng.uniform
    sizes = {
        "coulomb_friction": "force_n: %.3f" % u(0.8, 4.0),
        "backlash": "width_um: %.1f" % u(15.0, 60.0),
        "periodic_position": "period_mm: %.2f, amplitude_um: %.1f" % (u(20.0, 40.0), u(8.0, 30.0)),
        "direction_dependent_stiffness": "ratio: %.3f" % u(1.4, 2.2),
        "extra_resonance": "freq_hz: %.1f, damping: %.3f" % (u(25.0, 80.0), u(0.03, 0.1)),
        "time_delay": "delay_ms: %.2f" % u(2.0, 10.0),
        "scale_error": "scale: %.5f" % (1.0 + rng.choice([-1, 1]) * u(0.002, 0.01)),
    }
    return "%s: {%s, axes: [x, y]}" % (kind, sizes[kind])


def first_sim_yaml(seed, effect):
    """The first simulator (sim/, in-process) with `effect` on X and Y, or every effect for "all",
    sizes drawn from the seed (first_sim_effect); `seed` is also the simulator's."""
    import random
    rng = random.Random(seed)
    with open(os.path.join(ROOT, "config/examples/cartesian_sim.yaml")) as f:
        y = f.read()
    y, n1 = re.subn(r"feedforward:\n  type: none", "feedforward:\n  type: lpv", y)
    kinds = FIRST_SIM_EFFECTS if effect == "all" else ([effect] if effect else [])
    eff = "{%s}" % ", ".join(first_sim_effect(k, rng) for k in kinds)
    y, n2 = re.subn(r"simulator:\n  seed: 1\n", "simulator:\n  seed: %d\n" % seed, y)
    y, n3 = re.subn(r"\n  effects: \{\}", "\n  effects: %s" % eff, y)
    if n1 != 1 or n2 != 1 or n3 != 1:
        sys.exit("calibrate_seeds: config/examples/cartesian_sim.yaml changed shape (feedforward or simulator block)")
    return y


def printer_yaml(plant2, seed, effect=""):
    with open(os.path.join(ROOT, "config/examples/cartesian_sim.yaml")) as f:
        y = f.read()
    y, n1 = re.subn(r"feedforward:\n  type: none", "feedforward:\n  type: lpv", y)
    y, n2 = re.subn(r"simulator:\n  seed: 1",
                    'simulator:\n  seed: 1\n  external_plant: {command: "%s --seed %d%s", axes: [x, y], period_us: 100}'
                    % (plant2, seed, " --effect " + effect if effect else ""), y)
    # An external plant's carriages have no simulated switches: G28 is a move (docs/homing.md).
    y = re.sub(r"\n    homing: \{direction: min[^\n]*", "", y)
    if n1 != 1 or n2 != 1:
        sys.exit("calibrate_seeds: config/examples/cartesian_sim.yaml changed shape (feedforward or simulator block)")
    return y


def wait_for(path, proc, timeout_s):
    end = time.time() + timeout_s
    while time.time() < end:
        if os.path.exists(path):
            return True
        if proc.poll() is not None:
            return False
        time.sleep(0.05)
    return False


def api_call(sock_path, method, params=None):
    """One JSON-RPC call on the daemon's api.sock (one object per line)."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(30)
        s.connect(sock_path)
        req = {"jsonrpc": "2.0", "id": 1, "method": method}
        if params is not None:
            req["params"] = params
        s.sendall((json.dumps(req) + "\n").encode())
        buf = b""
        while b"\n" not in buf:
            chunk = s.recv(65536)
            if not chunk:
                break
            buf += chunk
    reply = json.loads(buf.split(b"\n")[0])
    if "error" in reply:
        raise RuntimeError("%s: %s" % (method, reply["error"]))
    return reply.get("result")


def ablated_e_t(build, env, work, overlay, key):
    """e_t of the check pattern with every `key` of the overlay set to 0 (reloaded), or an error."""
    with open(overlay) as f:
        text = f.read()
    text, n = re.subn(r"(\b%s:\s*)[-+0-9.eE]+" % re.escape(key), r"\g<1>0", text)
    if n == 0:
        return None, "the overlay has no %s" % key
    with open(overlay, "w") as f:
        f.write(text)
    sock = os.path.join(work, "api.sock")
    reloads = api_call(sock, "status").get("config_reloads", 0)
    api_call(sock, "config.reload", {"open_loop": False})
    end = time.time() + 30
    while api_call(sock, "status").get("config_reloads", 0) <= reloads:
        if time.time() > end:
            return None, "the daemon did not reload"
        time.sleep(0.1)
    p = subprocess.run([os.path.join(build, "cli/feedloop"), "calibrate", "--check-only"], env=env,
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=600)
    m = re.search(r"e_t of the check pattern: ([0-9.]+) mm", p.stdout)
    return (float(m.group(1)), "") if m else (None, p.stdout.strip().splitlines()[-1:])


# The thesis's tests of bench/control (bench_control.cpp, gantry_cases(); trajectories.cpp): id,
# shape, speed mm/s, acceleration mm/s^2, the thesis's corner rule (Sect. 2.2: |v_out - v_in| at
# most this, mm/s), and whether the case pools four runs at the bed's quadrant centres (Table 1).
THESIS_CASES = [
    ("circle_90", "circle", 90.0, 3000.0, 15.0, False),
    ("small_star_90", "small_star", 90.0, 3000.0, 15.0, False),
    ("small_star_150_a3000", "small_star", 150.0, 3000.0, 15.0, True),
    ("small_star_150_a6000", "small_star", 150.0, 6000.0, 15.0, True),
    ("large_star_150_sc15", "large_star", 150.0, 3000.0, 15.0, False),
    ("large_star_150_sc300", "large_star", 150.0, 3000.0, 300.0, False),
]
BED_CENTRE_MM = (125.0, 125.0)  # the middle of cartesian_sim.yaml's 250 x 250 mm bed
QUADRANT_CENTRES_MM = [(62.5, 62.5), (187.5, 62.5), (62.5, 187.5), (187.5, 187.5)]


def thesis_path(shape, cx, cy):
    """The vertices of bench/control's paths (trajectories.cpp), closed: the last is the first."""
    import math
    if shape == "circle":  # 50 chords of r 20 mm, the first vertex half a chord past 0 deg
        return [(cx + 20.0 * math.cos(math.pi / 50 + 2 * math.pi * (k % 50) / 50),
                 cy + 20.0 * math.sin(math.pi / 50 + 2 * math.pi * (k % 50) / 50)) for k in range(51)]
    outer, inner = (5.0, 2.0) if shape == "small_star" else (35.0, 14.0)
    return [(cx + (outer if k % 2 == 0 else inner) * math.cos(math.pi / 2 + math.pi / 5 * (k % 10)),
             cy + (outer if k % 2 == 0 else inner) * math.sin(math.pi / 2 + math.pi / 5 * (k % 10)))
            for k in range(11)]


def with_planner(yaml_text, accel_mm_s2, speed_change_mm_s):
    """The config with the thesis's corner rule and a case's acceleration (the planner's and the
    X and Y axes' limits); None when the config's planner block changed shape."""
    y, n1 = re.subn(r"\n  cornering: junction_deviation\n",
                    "\n  cornering: speed_change\n  max_speed_change_mm_s: %g\n" % speed_change_mm_s, yaml_text)
    y, n2 = re.subn(r"(\nplanner:\n  max_velocity_mm_s: [0-9.]+[^\n]*\n  max_accel_mm_s2: )[0-9.]+",
                    r"\g<1>%g" % accel_mm_s2, y)
    return y if n1 == 1 and n2 == 1 else None


def reload_daemon(sock, open_loop, no_feedforward):
    reloads = api_call(sock, "status").get("config_reloads", 0)
    api_call(sock, "config.reload", {"open_loop": open_loop, "no_feedforward": no_feedforward})
    end = time.time() + 60
    while True:
        try:
            if api_call(sock, "status").get("config_reloads", 0) > reloads:
                return
        except OSError:
            pass  # a reload may drop the connection
        if time.time() > end:
            raise RuntimeError("the daemon did not reload its config")
        time.sleep(0.1)


def run_gcode(sock, name, gcode):
    """One print job, to its end; the status at its end."""
    api_call(sock, "files.upload", {"filename": name, "content": gcode})
    api_call(sock, "job.start", {"filename": name})
    end = time.time() + 900
    while time.time() < end:
        j = api_call(sock, "job.status")
        if j.get("state") == "complete":
            return api_call(sock, "status")
        if j.get("state") in ("cancelled", "error", "off"):
            raise RuntimeError("job %s ended %s: %s" % (name, j.get("state"), j.get("message", "")))
        time.sleep(0.05)
    raise RuntimeError("job %s did not end within 15 min" % name)


def thesis_tests(sock, cfg, base_yaml, open_loop):
    """e_t (mm) of every thesis case, {id: e_t}: each path from rest after a travel at 50 mm/s and a
    300 ms dwell (a job of its own), e_t the daemon's tracking-error counters over the path's job,
    as the check pattern's (feedloop calibrate). The config's planner takes each case's corner rule
    and acceleration (rewritten and reloaded); open_loop: no feedforward and no PI."""
    out = {}
    for cid, shape, speed, accel, sc, pooled in THESIS_CASES:
        y = with_planner(base_yaml, accel, sc)
        if y is None:
            raise RuntimeError("config/examples/cartesian_sim.yaml changed shape (planner block)")
        with open(cfg, "w") as f:
            f.write(y)
        try:
            reload_daemon(sock, open_loop, open_loop)  # also clears a fault of the case before
            st = api_call(sock, "status")
            if "x" not in st.get("homed_axes", "") or "y" not in st.get("homed_axes", ""):
                run_gcode(sock, "thesis_home.gcode", "G28\n")
            total, samples = 0.0, 0.0
            for cx, cy in (QUADRANT_CENTRES_MM if pooled else [BED_CENTRE_MM]):
                v = thesis_path(shape, cx, cy)
                a = run_gcode(sock, "thesis_start.gcode", "G21\nG90\nG1 X%.4f Y%.4f F3000\nG4 P300\nM400\n" % v[0])
                path = "".join("G1 X%.4f Y%.4f F%.1f\n" % (x, yy, speed * 60.0) for x, yy in v[1:]) + "M400\n"
                b = run_gcode(sock, "thesis_%s.gcode" % cid, path)
                if b.get("last_error"):
                    raise RuntimeError("the machine reported a fault: %s" % b["last_error"])
                ta, tb = a["motion"]["tracking_error_mm"], b["motion"]["tracking_error_mm"]
                total += tb["mean"] * tb["samples"] - ta["mean"] * ta["samples"]
                samples += tb["samples"] - ta["samples"]
            out[cid] = total / samples if samples > 0 else None
        except (RuntimeError, OSError, ValueError, KeyError) as e:
            out[cid] = None
            print("  %s (%s): %s" % (cid, "open loop" if open_loop else "closed loop", e), file=sys.stderr, flush=True)
    with open(cfg, "w") as f:
        f.write(base_yaml)
    reload_daemon(sock, False, False)
    return out


def run_seed(build, seed, keep, effect="", ablate="", simulator="plant2", thesis=False):
    work = tempfile.mkdtemp(prefix="calibrate_seed%d." % seed)
    env = dict(os.environ, RUNTIME_DIRECTORY=work, STATE_DIRECTORY=work)
    cfg = os.path.join(work, "printer.yaml")
    with open(cfg, "w") as f:
        f.write(first_sim_yaml(seed, effect) if simulator == "sim" else
                printer_yaml(os.path.join(build, "plant2/feedloop-plant2"), seed, effect))
    log = open(os.path.join(work, "daemon.log"), "w")
    daemon = subprocess.Popen([os.path.join(build, "daemon/feedloopd"), "--virtual-time", "--config", cfg],
                              env=env, stdout=log, stderr=subprocess.STDOUT)
    row = {"seed": seed}
    try:
        if not wait_for(os.path.join(work, "api.sock"), daemon, 30):
            row["error"] = "feedloopd did not start (%s)" % os.path.join(work, "daemon.log")
            return row
        sock = os.path.join(work, "api.sock")
        with open(cfg) as f:
            base_yaml = f.read()
        if thesis:  # the thesis's tests with the config's model, before the calibration
            row["thesis_before"] = thesis_tests(sock, cfg, base_yaml, False)
        t0 = time.time()
        out_dir = os.path.join(work, "out")
        p = subprocess.run([os.path.join(build, "cli/feedloop"), "calibrate", "--out", out_dir], env=env,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=900)
        row["wall_s"] = time.time() - t0
        row["rc"] = p.returncode
        try:
            with open(os.path.join(out_dir, "report.json")) as f:
                row["report"] = json.load(f)
        except (OSError, ValueError):
            row["error"] = "no report (exit %d): %s" % (p.returncode, p.stdout.strip().splitlines()[-1:] or "")
        installed = row.get("report", {}).get("installed", "")
        if thesis and "report" in row:  # open loop, and with the model calibrate left in use
            row["thesis_open_loop"] = thesis_tests(sock, cfg, base_yaml, True)
            row["thesis_after"] = thesis_tests(sock, cfg, base_yaml, False)
        if ablate and installed:
            row["ablated"], why = ablated_e_t(build, env, work, installed, ablate)
            if row["ablated"] is None:
                row["ablate_error"] = str(why)
    finally:
        daemon.send_signal(signal.SIGTERM)
        try:
            daemon.wait(20)
        except subprocess.TimeoutExpired:
            daemon.kill()
        log.close()
        if keep:
            dst = os.path.join(keep, "seed%d" % seed)
            shutil.rmtree(dst, ignore_errors=True)
            shutil.copytree(work, dst, ignore=shutil.ignore_patterns("*.sock"))
        shutil.rmtree(work, ignore_errors=True)
    return row


def vs_open(after, open_loop):
    return 100.0 * (after / open_loop - 1.0) if after is not None and open_loop else None


def print_thesis(r):
    """One seed's thesis tests: e_t open loop, before and after the calibration, mm."""
    ol, be, af = (r.get("thesis_" + k) or {} for k in ("open_loop", "before", "after"))
    fmt = lambda v: "%.4f" % v if isinstance(v, (int, float)) else "-"
    print("       %-22s %10s %10s %10s %14s" % ("thesis case", "open_loop", "before", "after", "after_vs_open"))
    for cid, *_ in THESIS_CASES:
        v = vs_open(af.get(cid), ol.get(cid))
        print("       %-22s %10s %10s %10s %14s" % (cid, fmt(ol.get(cid)), fmt(be.get(cid)), fmt(af.get(cid)),
                                                    "%+.0f %%" % v if v is not None else "-"), flush=True)


def print_thesis_summary(rows):
    """Per thesis case, after vs open loop over the seeds, and how many reach issue 15's -90 %."""
    print("\nthesis tests, e_t after the calibration vs open loop (issue 15: -90 % or better)")
    print("%-22s %-40s %s" % ("case", "after_vs_open per seed", "at -90 % or better"))
    met = total = 0
    for cid, *_ in THESIS_CASES:
        vals = [vs_open((r.get("thesis") or {}).get("after", {}).get(cid),
                        (r.get("thesis") or {}).get("open_loop", {}).get(cid)) for r in rows if r.get("thesis")]
        ok = sum(1 for v in vals if v is not None and v <= -90.0)
        met += ok
        total += len(vals)
        print("%-22s %-40s %d of %d" % (cid, " / ".join("%+.0f" % v if v is not None else "-" for v in vals), ok,
                                       len(vals)))
    print("all cases: %d of %d at -90 %% or better" % (met, total))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--seeds", default="1-7")
    ap.add_argument("--keep", default="")
    ap.add_argument("--json", default="")
    ap.add_argument("--ablate", default="",
                    help="an overlay key set to 0 after the calibration, then the check pattern again")
    ap.add_argument("--effect", default="",
                    help="one effect kind drawn into both axes' machines (feedloop-plant2 --effect KIND); "
                         "with --simulator sim, one of the config's effects at its default size, or all")
    ap.add_argument("--simulator", default="plant2", choices=["plant2", "sim"],
                    help="plant2: the second simulator as an external plant (default); sim: the first, "
                         "in-process, its seed the row's")
    ap.add_argument("--thesis", action="store_true",
                    help="also the thesis's tests of bench/control (circle, stars, Table 1), open loop, before "
                         "and after the calibration; a table per seed and a summary")
    a = ap.parse_args()
    if a.simulator == "sim" and a.effect and a.effect != "all" and a.effect not in FIRST_SIM_EFFECTS:
        sys.exit("calibrate_seeds: --simulator sim knows the effects %s and all" % ", ".join(FIRST_SIM_EFFECTS))
    rows = []
    for exe in ("daemon/feedloopd", "cli/feedloop", "plant2/feedloop-plant2"):
        if not os.access(os.path.join(a.build, exe), os.X_OK):
            sys.exit("calibrate_seeds: %s not built (cmake --build %s)" % (exe, a.build))
    if a.keep:
        os.makedirs(a.keep, exist_ok=True)
    print("feedloop calibrate on the %s simulator, check pattern e_t in mm (LPV feedforward + PI on the device)" %
          ("first" if a.simulator == "sim" else "second"))
    if a.effect and a.simulator == "sim":
        print("effects on x and y, sizes drawn from the seed: %s" % a.effect)
    elif a.effect:
        print("every drawn machine with the effect %s (feedloop-plant2 --effect %s)" % (a.effect, a.effect))
    if a.ablate:
        print("without: e_t after the calibration with every %s of the overlay set to 0" % a.ablate)
    print("%5s %10s %10s %10s %14s %10s  %-20s %7s  %s" % ("seed", "open_loop", "before", "after", "after_vs_open",
                                                        "without", "model", "wall_s", "effects named (x; y)"))
    for seed in seeds_from(a.seeds):
        print("seed %d ..." % seed, file=sys.stderr, flush=True)
        r = run_seed(a.build, seed, a.keep, a.effect, a.ablate, a.simulator, a.thesis)
        rows.append({"seed": seed, "error": r.get("error", ""), "wall_s": r.get("wall_s"),
                     "e_t_mm": r.get("report", {}).get("e_t_mm"), "kept": bool(r.get("report", {}).get("installed")),
                     "warning": r.get("report", {}).get("warning", ""), "ablated_e_t_mm": r.get("ablated"),
                     "ablate_error": r.get("ablate_error", ""),
                     "pi_gains": r.get("report", {}).get("pi_gains")})
        if "report" not in r:
            print("%5d  %s" % (seed, r.get("error", "failed")), flush=True)
            continue
        e = r["report"].get("e_t_mm", {})
        ol, be, af = e.get("open_loop"), e.get("before"), e.get("after")
        kept = "kept" if r["report"].get("installed") else "rolled back"
        if r["report"].get("pi_gains"):
            kept += ", PI x%g" % r["report"]["pi_gains"]["scale"]  # the gain scale calibrate chose
        if r["report"].get("warning"):
            kept += ", warned"  # the model in use tracks worse than open loop
        vs = "%+.0f %%" % (100.0 * (af / ol - 1.0)) if ol and af is not None else "-"
        fmt = lambda v: "%.4f" % v if isinstance(v, (int, float)) else "-"
        named = "; ".join(
            ", ".join("%s%s" % (e["name"], "" if e.get("in_model") else " (recorded)") for e in ax.get("effects", [])) or "none"
            for ax in r["report"].get("axes", []))
        rows[-1]["effects"] = {ax.get("axis"): ax.get("effects", []) for ax in r["report"].get("axes", [])}
        without = fmt(r.get("ablated")) if a.ablate else "-"
        print("%5d %10s %10s %10s %14s %10s  %-20s %7.0f  %s" % (seed, fmt(ol), fmt(be), fmt(af), vs, without, kept,
                                                              r["wall_s"], named), flush=True)
        if r.get("ablate_error"):
            print("       without: %s" % r["ablate_error"], flush=True)
        if a.thesis:
            rows[-1]["thesis"] = {k: r.get("thesis_" + k) for k in ("open_loop", "before", "after")}
            print_thesis(r)
    if a.thesis:
        print_thesis_summary(rows)
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"bench": "calibrate_seeds", "rows": rows}, f, indent=2)
            f.write("\n")


if __name__ == "__main__":
    main()
