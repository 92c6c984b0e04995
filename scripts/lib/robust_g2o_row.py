"""One row of scripts/robust-g2o.sh: a robust dgs run against the clean optimum, as JSON."""
import glob
import json
import math
import os
import sys


def vertices(folder):
    out = {}
    for path in glob.glob(os.path.join(folder, "*.g2o")):
        with open(path) as f:
            for line in f:
                parts = line.split()
                if parts and parts[0] == "VERTEX_SE3:QUAT":
                    out[parts[1]] = tuple(float(v) for v in parts[2:5])
    return out


robots, fraction, clean_json, clean_dir, outliers, dgs_json, est_dir = sys.argv[1:]
clean = json.load(open(clean_json))
dgs = json.load(open(dgs_json))
wrong = {tuple(line.split()) for line in open(outliers) if line.strip()}
rejected = {tuple(pair) for pair in dgs["rejected"]}
rejected |= {(b, a) for a, b in rejected}
a, b = vertices(clean_dir), vertices(est_dir)
ate = math.sqrt(sum(sum((x - y) ** 2 for x, y in zip(a[k], b[k])) for k in a) / len(a))
print(json.dumps({
    "robots": int(robots), "fraction": float(fraction),
    "separators": dgs["robust_factors"], "wrong": len(wrong),
    "check_rejected": dgs["consistency_rejected"], "rejected": dgs["outliers"],
    "wrong_kept": sum(1 for w in wrong if w not in rejected),
    "right_rejected": dgs["outliers"] - sum(1 for w in wrong if w in rejected),
    "rounds": dgs["rounds"],
    "cost_rel": dgs["kept_cost"] / clean["final_cost"] - 1.0,
    "ate": ate, "bytes": dgs["bytes"],
    "extra_bytes": dgs["bytes_weights"] + dgs["bytes_control"] + dgs["bytes_consistency"],
}))
