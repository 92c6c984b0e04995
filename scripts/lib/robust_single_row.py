"""One row of scripts/robust-single.sh: `solve --robust` of a spoiled single-robot file, with and
without the loop closures' check through the odometry, and `dgs --robots R --robust` of it, each
against the clean file's optimum, as JSON.
Usage: robust_single_row.py NAME P THRESHOLD OUTLIERS CLEAN_G2O ALONE_JSON ALONE_DIR CHECK_JSON
CHECK_DIR [R DGS_JSON DGS_DIR]..."""
import glob
import json
import math
import os
import sys


def positions(paths):
    """Pose index -> position, from VERTEX_SE2 / VERTEX_SE3:QUAT lines (a Symbol key's index is
    its low 56 bits: the spoiled folder writes robot 0's poses as Symbols, the clean file plain)."""
    out = {}
    for path in paths:
        with open(path) as f:
            for line in f:
                parts = line.split()
                if parts and parts[0] in ("VERTEX_SE2", "VERTEX_SE3:QUAT"):
                    n = 2 if parts[0] == "VERTEX_SE2" else 3
                    out[int(parts[1]) & ((1 << 56) - 1)] = [float(v) for v in parts[2:2 + n]]
    return out


def pose_pair(names):
    """A factor as the sorted indices of its two poses (key names as moslam prints them: a robot
    letter and an index; a split file's blocks are robots)."""
    return tuple(sorted(int(name.lstrip("abcdefghijklmnopqrstuvwxyz")) for name in names))


def judged(result_json, folder, wrong, clean):
    result = json.load(open(result_json))
    robust = result["robust"] if isinstance(result["robust"], dict) else result  # solve / dgs
    rejected = {pose_pair(p) for p in robust["rejected"]}
    estimate = positions(glob.glob(os.path.join(folder, "*.g2o")))
    diff = max(math.dist(clean[k], estimate[k]) for k in clean)
    return {"wrong_kept": len(wrong - rejected), "right_rejected": len(rejected - wrong),
            "max_position_difference": diff, "status": robust["status"],
            "rounds": robust["rounds"]}


name, fraction, threshold, outliers, clean_g2o, alone_json, alone_dir, check_json, check_dir = \
    sys.argv[1:10]
wrong = {pose_pair(line.split()) for line in open(outliers) if line.strip()}
clean = positions([clean_g2o])
row = {"dataset": name, "fraction": float(fraction), "gnc_threshold": float(threshold),
       "wrong": len(wrong),
       "gnc_alone": judged(alone_json, alone_dir, wrong, clean),
       "checked": judged(check_json, check_dir, wrong, clean)}
row["loop_closures"] = json.load(open(check_json))["robust"]["robust_factors"]
dgs = sys.argv[10:]
row["dgs"] = {dgs[i]: judged(dgs[i + 1], dgs[i + 2], wrong, clean) for i in range(0, len(dgs), 3)}
print(json.dumps(row))
