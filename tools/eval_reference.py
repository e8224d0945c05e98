#!/usr/bin/env python3
"""Reference values for omcl's trajectory metrics, computed with evo.

Writes tests/data/eval/evo_reference.json, which tests/eval_reference.rs
compares omcl's numbers against (to 1e-6).

Inputs are the real trajectories in ../shared/data/trajectories/ (copied from
evo's own test data; KITTI 00 ground truth and ORB-SLAM2 estimate, TUM RGB-D
fr1_xyz and fr2_desk ground truth with RGBD-SLAM / ORB-SLAM estimates;
licences: KITTI CC BY-NC-SA 3.0, TUM RGB-D CC BY 4.0).

APE, RPE, Umeyama / origin alignment and time-stamp association come from
evo's Python API (evo.core.metrics, PosePath3D.align / align_origin,
evo.core.sync.associate_trajectories); evo is GPL-3.0 and is only run here,
never shipped. evo has no KITTI odometry metric, so that one comes from
kitti_devkit_metric() below, a line-by-line port of the KITTI devkit's
evaluate_odometry.cpp (calcSequenceErrors), written independently of the Rust
code: it inverts the raw 4x4 matrices with np.linalg.inv as the devkit does
and accumulates path lengths in float32 as the devkit does; errors are float64.

Usage (evo from PyPI; the test suite does not need it):
    python3 -m venv /tmp/evo-venv && /tmp/evo-venv/bin/pip install evo
    /tmp/evo-venv/bin/python tools/eval_reference.py
"""

import copy
import json
import os
import sys

import numpy as np
import evo
from evo.core import metrics, sync
from evo.core.metrics import PoseRelation, Unit
from evo.core.trajectory import PosePath3D
from evo.tools import file_interface

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "..", "shared", "data")
OUT = os.path.join(ROOT, "tests", "data", "eval", "evo_reference.json")

RELATIONS = {
    "translation": PoseRelation.translation_part,
    "rotation_angle_deg": PoseRelation.rotation_angle_deg,
}


def load(rel):
    path = os.path.join(DATA, rel)
    with open(path) as f:
        first = next(l for l in f if l.strip() and not l.startswith("#"))
    if len(first.split()) == 12:
        return project_rotations(file_interface.read_kitti_poses_file(path))
    return file_interface.read_tum_trajectory_file(path)


def project_rotations(path):
    """KITTI files print rotations to 7-9 digits, so they are off SO(3) by
    up to ~1e-7 (KITTI_00_ORB's first pose has diagonal 0.99999994). evo uses
    them raw; omcl's reader projects each onto the nearest rotation (SVD), as
    done here, so that both are given the same poses. Without this, evo's
    origin alignment multiplies the whole trajectory by a matrix with scale
    0.99999994 and APE moves by ~2e-5 m over KITTI 00's 500 m extent: an
    input-rounding effect, not a difference of the algorithms."""
    poses = []
    for p in path.poses_se3:
        u, _, vt = np.linalg.svd(p[:3, :3])
        d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
        q = p.copy()
        q[:3, :3] = u @ d @ vt
        poses.append(q)
    return PosePath3D(poses_se3=poses)


def run_case(case):
    ref = load(case["reference"])
    est = load(case["estimate"])
    assoc = case.get("associate")
    if assoc is not None:
        ref, est = sync.associate_trajectories(
            ref, est, max_diff=assoc["max_diff"], offset_2=assoc["offset"]
        )
    est = copy.deepcopy(est)
    align = case["align"]
    n = case.get("n_to_align") or -1
    out = dict(case)
    if align in ("se3", "sim3"):
        r, t, s = est.align(ref, correct_scale=(align == "sim3"), n=n)
        out["alignment"] = {"rotation": r.tolist(), "translation": t.tolist(), "scale": float(s)}
    elif align == "origin":
        m = est.align_origin(ref)
        out["alignment"] = {
            "rotation": m[:3, :3].tolist(),
            "translation": m[:3, 3].tolist(),
            "scale": 1.0,
        }
    relation = RELATIONS[case["relation"]]
    if case["metric"] == "ape":
        metric = metrics.APE(relation)
    else:
        metric = metrics.RPE(
            relation,
            delta=case["delta"],
            delta_unit={"f": Unit.frames, "m": Unit.meters}[case["delta_unit"]],
            all_pairs=case["all_pairs"],
        )
    metric.process_data((ref, est))
    out["matches"] = int(ref.num_poses)
    if assoc is not None:
        out["first_stamps"] = [float(ref.timestamps[0]), float(est.timestamps[0])]
        out["last_stamps"] = [float(ref.timestamps[-1]), float(est.timestamps[-1])]
    out["stats"] = {k: float(v) for k, v in metric.get_all_statistics().items()}
    out["count"] = int(len(metric.error))
    out["first_errors"] = [float(e) for e in metric.error[:5]]
    return out


def kitti_devkit_metric(gt_path, est_path, lengths=range(100, 900, 100), step=10, project=True):
    """Port of evaluate_odometry.cpp: calcSequenceErrors + the mean of
    saveStats (t_err in %, r_err converted from rad/m to deg/m).

    project=True gives it the SO(3)-projected poses omcl and evo get;
    project=False uses the printed matrices as the devkit does. The rotation
    error acos((trace - 1) / 2) of a small angle is ill-conditioned, so the
    printed matrices' 1e-7 non-orthonormality moves the rotation metric by
    ~3e-5 relative (KITTI 00)."""

    def poses(path):
        m = np.loadtxt(path)
        out = []
        for r in m:
            p = np.eye(4)
            p[:3, :] = r.reshape(3, 4)
            if project:
                u, _, vt = np.linalg.svd(p[:3, :3])
                p[:3, :3] = u @ np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))]) @ vt
            out.append(p)
        return out

    gt, est = poses(gt_path), poses(est_path)
    # trajectoryDistances: vector<float>; dx is a double difference stored
    # in a float, sqrt and the sum are float. Segment ends depend on it.
    f32 = np.float32
    dist = [f32(0.0)]
    for i in range(1, len(gt)):
        dx, dy, dz = (f32(gt[i - 1][k, 3] - gt[i][k, 3]) for k in range(3))
        dist.append(f32(dist[-1] + np.sqrt(f32(f32(f32(dx * dx) + f32(dy * dy)) + f32(dz * dz)))))
    errs = []
    for first in range(0, len(gt), step):
        for length in lengths:
            last = -1
            for i in range(first, len(dist)):
                if dist[i] > f32(dist[first] + f32(length)):
                    last = i
                    break
            if last == -1:
                continue
            d_gt = np.linalg.inv(gt[first]) @ gt[last]
            d_est = np.linalg.inv(est[first]) @ est[last]
            e = np.linalg.inv(d_est) @ d_gt
            c = 0.5 * (e[0, 0] + e[1, 1] + e[2, 2] - 1.0)
            r_err = np.arccos(max(min(c, 1.0), -1.0))
            t_err = np.linalg.norm(e[:3, 3])
            errs.append((first, last, length, t_err / length, r_err / length))
    per_length = []
    for length in lengths:
        s = [e for e in errs if e[2] == length]
        if s:
            per_length.append(
                {
                    "length": float(length),
                    "segments": len(s),
                    "translation_percent": 100.0 * float(np.mean([e[3] for e in s])),
                    "rotation_deg_per_m": float(np.rad2deg(np.mean([e[4] for e in s]))),
                }
            )
    return {
        "translation_percent": 100.0 * float(np.mean([e[3] for e in errs])),
        "rotation_deg_per_m": float(np.rad2deg(np.mean([e[4] for e in errs]))),
        "segments": len(errs),
        "per_length": per_length,
        "first_segment": {"first_frame": errs[0][0], "last_frame": errs[0][1]},
        # Catches a single segment ending at another frame.
        "last_frame_sum": int(sum(e[1] for e in errs)),
    }


def cases():
    kitti = {"reference": "trajectories/KITTI_00_gt.txt", "estimate": "trajectories/KITTI_00_ORB.txt"}
    fr1 = {
        "reference": "trajectories/freiburg1_xyz-groundtruth.txt",
        "estimate": "trajectories/freiburg1_xyz-rgbdslam.txt",
        "associate": {"max_diff": 0.01, "offset": 0.0},
    }
    fr2 = {
        "reference": "trajectories/fr2_desk_groundtruth.txt",
        "estimate": "trajectories/fr2_desk_ORB.txt",
        "associate": {"max_diff": 0.01, "offset": 0.0},
    }
    base = {"n_to_align": None, "delta": 1, "delta_unit": "f", "all_pairs": False,
            "relation": "translation"}
    out = []

    def add(name, src, **kw):
        c = dict(base)
        c.update(src)
        c.update(kw)
        c["name"] = name
        out.append(c)

    for align in ("none", "se3", "sim3", "origin"):
        add(f"kitti00_ape_{align}", kitti, metric="ape", align=align)
    add("kitti00_ape_sim3_n100", kitti, metric="ape", align="sim3", n_to_align=100)
    add("kitti00_ape_rot_se3", kitti, metric="ape", align="se3", relation="rotation_angle_deg")
    add("kitti00_rpe_d1", kitti, metric="rpe", align="none")
    add("kitti00_rpe_rot_d1", kitti, metric="rpe", align="none", relation="rotation_angle_deg")
    add("kitti00_rpe_d10_all", kitti, metric="rpe", align="none", delta=10, all_pairs=True)
    add("kitti00_rpe_d7", kitti, metric="rpe", align="none", delta=7)
    add("kitti00_rpe_100m", kitti, metric="rpe", align="none", delta=100.0, delta_unit="m")
    add("kitti00_rpe_rot_50m_all", kitti, metric="rpe", align="none", delta=50.0,
        delta_unit="m", all_pairs=True, relation="rotation_angle_deg")
    for align in ("none", "se3", "sim3", "origin"):
        add(f"fr1xyz_ape_{align}", fr1, metric="ape", align=align)
    add("fr1xyz_rpe_d1", fr1, metric="rpe", align="none")
    add("fr1xyz_rpe_rot_d5", fr1, metric="rpe", align="none", delta=5, relation="rotation_angle_deg")
    add("fr1xyz_ape_se3_offset", fr1, metric="ape", align="se3",
        associate={"max_diff": 0.02, "offset": 0.05})
    for align in ("se3", "sim3"):
        add(f"fr2desk_ape_{align}", fr2, metric="ape", align=align)
    add("fr2desk_rpe_d1_sim3", fr2, metric="rpe", align="sim3")
    add("fr2desk_rpe_0.2m_sim3_all", fr2, metric="rpe", align="sim3", delta=0.2,
        delta_unit="m", all_pairs=True)
    add("fr2desk_ape_rot_origin", fr2, metric="ape", align="origin", relation="rotation_angle_deg")
    return out


def main():
    result = {
        "provenance": (
            "Generated by tools/eval_reference.py with evo " + evo.__version__
            + " (PyPI, GPL-3.0; run only, not shipped) on ../shared/data/trajectories "
            "(evo's test data: KITTI 00 CC BY-NC-SA 3.0, TUM RGB-D CC BY 4.0); "
            "KITTI rotations projected onto SO(3) before evo sees them, as omcl's reader does. "
            "kitti_metric: port of the KITTI devkit evaluate_odometry.cpp in that script."
        ),
        "evo_version": evo.__version__,
        "numpy_version": np.__version__,
        "cases": [run_case(c) for c in cases()],
        "kitti_metric": [
            dict(
                reference="trajectories/KITTI_00_gt.txt",
                estimate="trajectories/KITTI_00_ORB.txt",
                **kitti_devkit_metric(
                    os.path.join(DATA, "trajectories/KITTI_00_gt.txt"),
                    os.path.join(DATA, "trajectories/KITTI_00_ORB.txt"),
                ),
                devkit_raw_matrices=kitti_devkit_metric(
                    os.path.join(DATA, "trajectories/KITTI_00_gt.txt"),
                    os.path.join(DATA, "trajectories/KITTI_00_ORB.txt"),
                    project=False,
                ),
            )
        ],
    }
    os.makedirs(os.path.dirname(OUT), exist_ok=True)
    tmp = OUT + ".tmp"
    with open(tmp, "w") as f:
        json.dump(result, f, indent=1)
        f.write("\n")
    os.replace(tmp, OUT)
    print(f"wrote {OUT}: {len(result['cases'])} cases", file=sys.stderr)


if __name__ == "__main__":
    main()
