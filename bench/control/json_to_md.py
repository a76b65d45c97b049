#!/usr/bin/env python3
"""The README's result tables from `bench_control --json FILE`: python3 json_to_md.py FILE.

Prints Markdown: the two blocks (nominal, effects), the delta block, the "where the loop runs"
table and the criteria, in the README's layout. Nothing is computed here that the bench did not
write; a missing key prints as a dash.
"""
import json
import sys


def f4(x):
    return "-" if x is None else f"{x:.4f}"


def thesis_text(t, row):
    if not t:
        return ""
    key = {"open_loop": "open_loop", "pi_thesis": "pi"}.get(row)
    if key is None:
        return ""
    e_t, std, e_r, time_s = (t.get(f"{key}_{k}") for k in ("e_t_mm", "e_t_std_mm", "e_r_mm", "time_s"))
    if e_t is None:
        return ""
    s = f"{e_t:.3f}" + (f" ({std:.2f})" if std is not None else "")
    if e_r is not None:
        s += f" e_r {e_r:.2f}"
    if time_s is not None:
        s += f", {time_s:.3f} s"
    return s


def block_table(block):
    out = ["| case | row | e_t mm (std) | e_r mm | max mm | time s | lost | events | vs OL | thesis |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for c in block["cases"]:
        for r in c["rows"]:
            run = r["run"]
            if not run.get("ok", False):
                out.append(f"| {c['case']} | {r['label']} | error: {run.get('error', '?')} | | | | | | | |")
                continue
            e_r = run.get("e_r_mm")
            ratio = r.get("ratio_vs_open_loop")
            vs = "-" if ratio is None else f"{(ratio - 1.0) * 100:+.1f}%"
            out.append(
                f"| {c['case']} | {r['label']} | {f4(run['e_t_mm'])} ({f4(run['e_t_std_mm'])}) | "
                f"{'—' if e_r is None or not c['case'].startswith('circle') else f4(e_r)} | "
                f"{f4(run['e_max_mm'])} | {run['time_s']:.3f} | {run['lost_full_steps']} | "
                f"{run['lost_step_events']} | {vs} | {thesis_text(c.get('thesis'), r['row'])} |")
    return "\n".join(out)


def delta_table(delta):
    cells = {}
    for d in delta:
        cells[((d["x_mm"], d["y_mm"]), d["shape"], d["feedforward"])] = d["run"].get("e_t_mm")
    places = []
    for d in delta:
        key = ((d["x_mm"], d["y_mm"]), d["shape"])
        if key not in places:
            places.append(key)
    out = ["| centre | shape | none | fixed centre (virtual work) | LPV (virtual work) | LPV vs fixed | "
           "fixed centre (paper) | LPV (paper) | LPV vs fixed |",
           "|---|---|---|---|---|---|---|---|---|"]

    def ratio(a, b):
        return "-" if a is None or b is None or b == 0 else f"{(a / b - 1.0) * 100:+.1f}%"

    for (xy, shape) in places:
        g = lambda ff: cells.get((xy, shape, ff))  # noqa: E731
        out.append(f"| ({xy[0]:g}, {xy[1]:g}) | {shape} | {f4(g('none'))} | {f4(g('lpv_centre_vw'))} | "
                   f"{f4(g('lpv_vw'))} | {ratio(g('lpv_vw'), g('lpv_centre_vw'))} | {f4(g('lpv_centre'))} | "
                   f"{f4(g('lpv'))} | {ratio(g('lpv'), g('lpv_centre'))} |")
    return "\n".join(out)


LOOPS = [("device_1k", "device loop 1 kHz"), ("device_10k", "device loop 10 kHz"),
         ("host_2ms", "host loop, 2 ms lead"), ("host_25ms", "host loop, 25 ms lead")]


def loops_tables(loops):
    out = []
    for controller, title in (("pi", "PI thesis (0.5, 20), F = 1"),
                              ("lpv_pi", "LPV feedforward + PI thesis (0.5, 20)")):
        rows = [x for x in loops if x["controller"] == controller]
        cases = []
        for x in rows:
            if x["case"] not in cases:
                cases.append(x["case"])
        out += [f"{title}:", "", "| case | " + " | ".join(t for _, t in LOOPS) + " |",
                "|---|" + "---|" * len(LOOPS)]
        for c in cases:
            cells = []
            for loop, _ in LOOPS:
                m = [x for x in rows if x["case"] == c and x["loop"] == loop]
                if not m or not m[0]["run"].get("ok", False):
                    cells.append("-")
                    continue
                r = m[0]["run"]
                cells.append(f"{f4(r['e_t_mm'])} / {f4(r['e_max_mm'])}, {r['lost_full_steps']} ({r['lost_step_events']})")
            out.append(f"| {c} | " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out)


def criteria_table(criteria):
    out = ["| criterion | block | row | value | result |", "|---|---|---|---|---|"]
    for c in criteria:
        out.append(f"| {c['criterion']} | {c['block']} | {c['row']} | {c['value']} | {c['result']} |")
    return "\n".join(out)


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: json_to_md.py BENCH_CONTROL_JSON")
    with open(sys.argv[1]) as fh:
        d = json.load(fh)
    titles = {"nominal": "Nominal simulator",
              "effects": "With unmodelled effects (the LPV rows with the identified friction in the model)"}
    for b in d.get("blocks", []):
        print(f"### {titles.get(b['block'], b['block'])}\n\n{block_table(b)}\n")
    if d.get("delta"):
        print(f"### Delta (open loop, e_t mm)\n\n{delta_table(d['delta'])}\n")
    if d.get("loops"):
        print("### Where the loop runs\n\nThe thesis cases with the unmodelled effects; e_t mean / max mm, "
              "lost full steps (events):\n")
        print(loops_tables(d["loops"]))
    if d.get("criteria"):
        passed = sum(1 for c in d["criteria"] if c["result"] == "PASS")
        counted = sum(1 for c in d["criteria"] if not c["result"].startswith("info"))
        print(f"### Criteria ({passed} of {counted} PASS; the info rows are shown for comparison)\n\n"
              f"{criteria_table(d['criteria'])}")


if __name__ == "__main__":
    main()
