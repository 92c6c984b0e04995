#!/usr/bin/python3
"""Turns `moslam dgs --refine --json` lines (scripts/bench-dgs.sh) into Markdown tables and a plot.

    bench/dgs_table.py build-bench-dgs/dgs_bench.jsonl --plot docs/dgs_scaling.png

Every row was run with two pipelines (the "pipeline" field): "paper" (one-level DGS, refinement
preconditioned by the sweeps) and "two-level" (two-level DGS, refinement preconditioned by the
sweeps around a coarse correction). Per row and pipeline: the sweeps of the two stages and of the
refinement (Gauss-Newton steps), the bytes of the two stages, the bytes when the estimate first
came within 1e-6 relative of the centralized optimum (two stages included; the first accepted
Gauss-Newton step within it), the bytes of the whole run (which stops when a step gains less than
1e-10 relative), and the final cost against the centralized optimum; then the sums over the rows.
Plot (two panels): robots vs sweeps and robots vs bytes to 1e-6, per dataset, both pipelines,
eta = 1e-2.
"""
import argparse
import json
import sys
from collections import defaultdict

DATASET_ORDER = ["blocks_world", "sphere2500", "torus3D", "cubicle"]
PIPELINES = ["paper", "two-level"]


def load(path):
    rows = []
    with (sys.stdin if path == "-" else open(path)) as f:
        for line in f:
            line = line.strip()
            if line:
                rows.append(json.loads(line))
    return rows


def dataset_of(row):
    if "dataset" in row:
        return row["dataset"]
    path = row["input"].rstrip("/")
    return path.split("/")[-2] if path.endswith("robots") else path.split("/")[-1].split(".")[0]


def eta_of(row):
    if row["eta_rotation"] == row["eta_pose"]:
        return "%g" % row["eta_rotation"]
    return "%g/%g" % (row["eta_rotation"], row["eta_pose"])


def human_bytes(n):
    if n is None:
        return "never"
    for unit in ["B", "kB", "MB", "GB"]:
        if abs(n) < 1000 or unit == "GB":
            return ("%.0f %s" if unit == "B" else "%.1f %s") % (n, unit)
        n /= 1000.0


def key_of(row):
    d = dataset_of(row)
    rank = DATASET_ORDER.index(d) if d in DATASET_ORDER else len(DATASET_ORDER)
    return (rank, d, row["robots"], -row["eta_rotation"])


def sweeps(r):
    stages = []
    for stage in ("rotation", "pose"):
        s = str(r["iterations_" + stage])
        if r["termination_" + stage] != "converged":
            s += "*"  # stopped at max iterations
        stages.append(s)
    refine = "%d (%d)" % (r["iterations_refine"], r.get("refine_steps", 0))
    if r.get("termination_refine", "not run") not in ("converged", "not run"):
        refine += " " + r["termination_refine"]
    return "%s / %s / %s" % (stages[0], stages[1], refine)


def to_optimum(r):
    return r.get("bytes_to_optimum_1e-6")


def pairs(rows):
    by_key = defaultdict(dict)
    for r in rows:
        by_key[key_of(r)][r.get("pipeline", "paper")] = r
    return [by_key[k] for k in sorted(by_key)]


def table(rows):
    out = []
    out.append("| dataset | robots | eta | paper: sweeps rot / pose / refine (GN steps) | paper: "
               "bytes two-stage / to 1e-6 / run | two-level: sweeps rot / pose / refine (GN "
               "steps) | two-level: bytes two-stage / to 1e-6 / run | two-level refined / GN - 1 "
               "| bytes to 1e-6 paper / two-level |")
    out.append("|---|---:|---:|---|---|---|---|---:|---:|")
    sums = {p: {"to": 0, "run": 0, "missing": 0} for p in PIPELINES}
    for pair in pairs(rows):
        any_row = next(iter(pair.values()))
        cells = [dataset_of(any_row), str(any_row["robots"]), eta_of(any_row)]
        for p in PIPELINES:
            r = pair.get(p)
            if r is None:
                cells += ["", ""]
                continue
            two_stage = r["bytes_rotation"] + r["bytes_pose"]
            cells.append(sweeps(r))
            cells.append("%s / %s / %s" % (human_bytes(two_stage), human_bytes(to_optimum(r)),
                                           human_bytes(r["bytes"])))
            sums[p]["run"] += r["bytes"]
            if to_optimum(r) is None:
                sums[p]["missing"] += 1
            else:
                sums[p]["to"] += to_optimum(r)
        new = pair.get("two-level")
        cells.append("%.1e" % (new["final_cost"] / new["centralized_cost"] - 1.0) if new else "")
        old = pair.get("paper")
        if old and new and to_optimum(old) and to_optimum(new):
            cells.append("%.1fx" % (to_optimum(old) / to_optimum(new)))
        else:
            cells.append("")
        out.append("| " + " | ".join(cells) + " |")
    out.append("")
    for p in PIPELINES:
        s = sums[p]
        out.append("- %s, summed over the rows: %s to 1e-6 of the optimum%s, %s in the whole runs." %
                   (p, human_bytes(s["to"]),
                    " (%d rows never within 1e-6)" % s["missing"] if s["missing"] else "",
                    human_bytes(s["run"])))
    if sums["two-level"]["to"] > 0:
        out.append("- paper / two-level: %.1fx to 1e-6, %.1fx in the whole runs." %
                   (sums["paper"]["to"] / sums["two-level"]["to"],
                    sums["paper"]["run"] / max(1, sums["two-level"]["run"])))
    out.append("")
    out.append("Sweeps: one solve by every robot (rotation and pose: DGS.md, one-level or with the "
               "coarse correction; refine: the sweeps of all Gauss-Newton steps, each step's linear "
               "system solved by conjugate gradients preconditioned with a forward and a backward "
               "block Gauss-Seidel sweep, two-level: with a coarse correction between them). `*`: "
               "the stage stopped at --max-iter. Bytes: every serialized message (refine: "
               "increments, coarse messages and 32-byte control messages); to 1e-6: up to the "
               "first Gauss-Newton step whose cost is within 1e-6 relative of centralized GN "
               "(from the chordal initialisation); run: until the refinement stops by itself "
               "(a step gains <= 1e-10 relative).")
    return "\n".join(out)


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    series = defaultdict(list)  # (dataset, pipeline) -> rows at eta 1e-2
    for r in rows:
        if eta_of(r) == "0.01":
            series[(dataset_of(r), r.get("pipeline", "paper"))].append(r)
    datasets = sorted({d for d, _ in series},
                      key=lambda d: DATASET_ORDER.index(d) if d in DATASET_ORDER else 99)
    colors = dict(zip(datasets, ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple"]))
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.2))
    panels = [
        (axes[0], "sweeps (two stages + refinement)", lambda r: r["iterations_total"]),
        (axes[1], "bytes to 1e-6 of the optimum", lambda r: to_optimum(r) or r["bytes"]),
    ]
    for ax, label, value in panels:
        for (dataset, pipeline), rs in sorted(series.items(),
                                              key=lambda item: (datasets.index(item[0][0]),
                                                                item[0][1])):
            rs = sorted(rs, key=lambda r: r["robots"])
            style = "--" if pipeline == "paper" else "-"
            ax.plot([r["robots"] for r in rs], [value(r) for r in rs], style, marker="o",
                    color=colors[dataset], label="%s, %s" % (dataset, pipeline))
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel("robots")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_title("Sweeps to the optimum vs robots (eta 1e-2)")
    axes[1].set_title("Traffic to the optimum vs robots (eta 1e-2)")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.14, 1, 1))
    fig.savefig(path, dpi=110)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("jsonl", help="moslam dgs --json lines ('-': stdin)")
    parser.add_argument("--plot", help="write the two-panel PNG here")
    args = parser.parse_args()
    rows = load(args.jsonl)
    if not rows:
        sys.exit("dgs_table.py: no JSON lines in " + args.jsonl)
    print(table(rows))
    if args.plot:
        plot(rows, args.plot)


if __name__ == "__main__":
    main()
