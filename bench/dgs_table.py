#!/usr/bin/python3
"""Turns `moslam dgs --json` lines (scripts/bench-dgs.sh) into a Markdown table and a plot.

    bench/dgs_table.py build-bench-dgs/dgs_bench.jsonl --plot docs/dgs_scaling.png

Table: one row per run (dataset, robots, eta): sweeps of the rotation and pose stages and of the
refinement (with its Gauss-Newton steps), the cost F after the two stages, after the refinement
and of centralized Gauss-Newton (from the chordal initialisation, same gauge) with the ratios to
the latter, the bytes sent (two stages / refinement) and the wall time per sweep.
Plot (two panels): robots vs sweeps and robots vs bytes, per dataset; the two stages for both
etas, the whole run with the refinement for eta = 1e-2.
"""
import argparse
import json
import sys
from collections import defaultdict

DATASET_ORDER = ["blocks_world", "sphere2500", "torus3D", "cubicle"]


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
    for unit in ["B", "kB", "MB", "GB"]:
        if abs(n) < 1000 or unit == "GB":
            return ("%.0f %s" if unit == "B" else "%.1f %s") % (n, unit)
        n /= 1000.0


def sort_key(row):
    d = dataset_of(row)
    rank = DATASET_ORDER.index(d) if d in DATASET_ORDER else len(DATASET_ORDER)
    return (rank, d, row["robots"], -row["eta_rotation"])


def table(rows):
    out = []
    out.append("| dataset | robots | eta | sweeps rot / pose / refine (GN steps) | "
               "cost two-stage | cost refined | cost centralized GN | two-stage / GN | "
               "refined / GN - 1 | bytes two-stage | bytes refine | ms per sweep |")
    out.append("|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in sorted(rows, key=sort_key):
        central = r["centralized_cost"]
        two_stage_bytes = r["bytes_rotation"] + r["bytes_pose"]
        refine = "%d (%d)" % (r["iterations_refine"], r.get("refine_steps", 0))
        if r.get("termination_refine", "not run") not in ("converged", "not run"):
            refine += " " + r["termination_refine"]
        stages = []
        for stage in ("rotation", "pose"):
            s = str(r["iterations_" + stage])
            if r["termination_" + stage] != "converged":
                s += "*"  # stopped at max iterations
            stages.append(s)
        out.append("| %s | %d | %s | %s / %s / %s | %.6g | %.10g | %.10g | %.4f | %.1e | %s | %s | %.3g |" % (
            dataset_of(r), r["robots"], eta_of(r), stages[0], stages[1], refine,
            r["two_stage_cost"], r["final_cost"], central, r["two_stage_cost"] / central,
            r["final_cost"] / central - 1.0, human_bytes(two_stage_bytes),
            human_bytes(r["bytes_refine"]), 1e3 * r["seconds_per_iteration"]))
    out.append("")
    out.append("Sweeps: one solve by every robot (rotation and pose: DGS.md; refine: "
               "the sweeps of all Gauss-Newton steps, each step's linear system solved by "
               "conjugate gradients preconditioned with a forward and a backward block "
               "Gauss-Seidel sweep). `*`: the stage stopped at --max-iter. Costs: "
               "F = sum 1/2 r^T Omega r; centralized GN from the chordal initialisation. "
               "Bytes: every serialized message (refine: increments and 32-byte control messages). "
               "ms per sweep: wall time of the in-process run (all robots on one core) over all "
               "sweeps.")
    return "\n".join(out)


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    series = defaultdict(list)  # (dataset, eta) -> rows
    for r in rows:
        series[(dataset_of(r), eta_of(r))].append(r)
    datasets = sorted({d for d, _ in series},
                      key=lambda d: DATASET_ORDER.index(d) if d in DATASET_ORDER else 99)
    colors = dict(zip(datasets, ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple"]))
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.2))
    panels = [
        (axes[0], "sweeps", lambda r: r["iterations_rotation"] + r["iterations_pose"],
         lambda r: r["iterations_total"]),
        (axes[1], "bytes sent", lambda r: r["bytes_rotation"] + r["bytes_pose"],
         lambda r: r["bytes"]),
    ]
    for ax, label, two_stage, total in panels:
        for (dataset, eta), rs in sorted(series.items(),
                                         key=lambda item: (datasets.index(item[0][0]),
                                                           -float(item[0][1].split("/")[0]))):
            rs = sorted(rs, key=lambda r: r["robots"])
            x = [r["robots"] for r in rs]
            style = "-" if eta == "0.01" else "--"
            ax.plot(x, [two_stage(r) for r in rs], style, marker="o", color=colors[dataset],
                    label="%s, two stages, eta %s" % (dataset, eta))
            if eta == "0.01" and any(r.get("refine") for r in rs):
                ax.plot(x, [total(r) for r in rs], ":", marker="s", color=colors[dataset],
                        label="%s, with refinement, eta %s" % (dataset, eta))
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel("robots")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_title("DGS sweeps vs robots")
    axes[1].set_title("DGS traffic vs robots")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=3, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.16, 1, 1))
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
