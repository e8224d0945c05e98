#!/usr/bin/env python3
"""Writes small PLY and LAS/LAZ files with *other* tools (plyfile, laspy) for
omcl's reader tests, plus a plain-text `<file>.expected.txt` beside each one
holding what the file contains, read back by the same tool.

Run from the crate root:

    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install plyfile laspy lazrs numpy
    /tmp/venv/bin/python tools/make_io_testdata.py

Outputs go to tests/data/io/ (see the README there). Deterministic: fixed
seed, no timestamps in the files (laspy's creation date is pinned).
"""

import datetime
import os

import laspy
import numpy as np
from plyfile import PlyData, PlyElement

OUT = os.path.join(os.path.dirname(__file__), "..", "tests", "data", "io")
rng = np.random.default_rng(20261122)


def save_expected(path, columns, fmt):
    """One line per point: the columns side by side, %.17g for floats."""
    table = np.column_stack(columns)
    np.savetxt(path + ".expected.txt", table, fmt=fmt)


def ply_files():
    n = 37
    xyz = rng.normal(0.0, 5.0, size=(n, 3))
    rgb = rng.integers(0, 256, size=(n, 3), dtype=np.uint8)
    label = rng.integers(0, 260, size=n).astype(np.int32)
    feat = rng.normal(0.0, 1.0, size=(n, 4)).astype(np.float32)

    # 1. ASCII, float xyz, uchar colour, int "label".
    v = np.empty(
        n,
        dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("red", "u1"), ("green", "u1"),
               ("blue", "u1"), ("label", "i4")],
    )
    for k, a in enumerate("xyz"):
        v[a] = xyz[:, k]
    v["red"], v["green"], v["blue"] = rgb[:, 0], rgb[:, 1], rgb[:, 2]
    v["label"] = label
    p = os.path.join(OUT, "plyfile_ascii_rgb_label.ply")
    PlyData([PlyElement.describe(v, "vertex")], text=True).write(p)
    r = PlyData.read(p)["vertex"]
    save_expected(
        p,
        [r["x"].astype(np.float64), r["y"], r["z"], r["red"], r["green"], r["blue"], r["label"]],
        ["%.17g"] * 3 + ["%d"] * 4,
    )

    # 2. Binary little-endian, double xyz, ushort "class", float features f0..f3,
    #    then a face element the reader must ignore.
    v = np.empty(
        n,
        dtype=[("x", "f8"), ("y", "f8"), ("z", "f8"), ("class", "u2")]
        + [(f"f{k}", "f4") for k in range(4)],
    )
    for k, a in enumerate("xyz"):
        v[a] = xyz[:, k] + 1000.0
    v["class"] = label
    for k in range(4):
        v[f"f{k}"] = feat[:, k]
    faces = np.empty(2, dtype=[("vertex_indices", "i4", (3,))])
    faces["vertex_indices"] = [[0, 1, 2], [2, 3, 4]]
    p = os.path.join(OUT, "plyfile_binle_double_class_feat.ply")
    PlyData(
        [PlyElement.describe(v, "vertex"), PlyElement.describe(faces, "face")],
        byte_order="<",
    ).write(p)
    r = PlyData.read(p)["vertex"]
    save_expected(
        p,
        [r["x"], r["y"], r["z"], r["class"]] + [r[f"f{k}"].astype(np.float64) for k in range(4)],
        ["%.17g"] * 3 + ["%d"] + ["%.9g"] * 4,
    )

    # 3. Binary big-endian, float xyz, uchar colour, uint "scalar_label",
    #    plus an extra property (intensity) the reader must skip.
    v = np.empty(
        n,
        dtype=[("x", ">f4"), ("y", ">f4"), ("z", ">f4"), ("intensity", ">f4"), ("red", "u1"),
               ("green", "u1"), ("blue", "u1"), ("scalar_label", ">u4")],
    )
    for k, a in enumerate("xyz"):
        v[a] = xyz[:, k]
    v["intensity"] = rng.random(n)
    v["red"], v["green"], v["blue"] = rgb[:, 0], rgb[:, 1], rgb[:, 2]
    v["scalar_label"] = label
    p = os.path.join(OUT, "plyfile_binbe_rgb_scalar_label.ply")
    PlyData([PlyElement.describe(v, "vertex")], byte_order=">").write(p)
    r = PlyData.read(p)["vertex"]
    save_expected(
        p,
        [r["x"].astype(np.float64), r["y"], r["z"], r["red"], r["green"], r["blue"],
         r["scalar_label"]],
        ["%.17g"] * 3 + ["%d"] * 4,
    )


def las_files():
    n = 53
    # Georeferenced-looking coordinates: precision matters (f32 would lose mm).
    x = 637_000.0 + rng.random(n) * 500.0
    y = 851_000.0 + rng.random(n) * 500.0
    z = 400.0 + rng.random(n) * 30.0
    cls = rng.choice([1, 2, 5, 6, 9], size=n)
    rgb16 = rng.integers(0, 65536, size=(n, 3), dtype=np.uint16)

    # 4. LAS 1.2, point format 3 (RGB), 16-bit colour; and the same as LAZ.
    for ext in ("las", "laz"):
        h = laspy.LasHeader(point_format=3, version="1.2")
        h.scales = np.array([0.001, 0.001, 0.001])
        h.offsets = np.array([637_000.0, 851_000.0, 0.0])
        h.creation_date = datetime.date(2026, 11, 22)
        las = laspy.LasData(h)
        las.x, las.y, las.z = x, y, z
        las.classification = cls
        las.red, las.green, las.blue = rgb16[:, 0], rgb16[:, 1], rgb16[:, 2]
        p = os.path.join(OUT, f"laspy_pf3_rgb.{ext}")
        las.write(p)
        r = laspy.read(p)
        save_expected(
            p,
            [np.asarray(r.x), np.asarray(r.y), np.asarray(r.z), np.asarray(r.classification),
             np.asarray(r.red) >> 8, np.asarray(r.green) >> 8, np.asarray(r.blue) >> 8],
            ["%.17g"] * 3 + ["%d"] * 4,
        )

    # 5. LAS 1.4, point format 6 (no colour), classification codes above 31
    #    (only the extended formats can hold them).
    h = laspy.LasHeader(point_format=6, version="1.4")
    h.scales = np.array([0.01, 0.01, 0.01])
    h.offsets = np.array([0.0, 0.0, 0.0])
    h.creation_date = datetime.date(2026, 11, 22)
    las = laspy.LasData(h)
    las.x, las.y, las.z = x - 637_000.0, y - 851_000.0, z
    las.classification = rng.choice([2, 40, 64, 200], size=n).astype(np.uint8)
    p = os.path.join(OUT, "laspy_14_pf6_extended_class.las")
    las.write(p)
    r = laspy.read(p)
    save_expected(
        p,
        [np.asarray(r.x), np.asarray(r.y), np.asarray(r.z), np.asarray(r.classification)],
        ["%.17g"] * 3 + ["%d"],
    )


if __name__ == "__main__":
    os.makedirs(OUT, exist_ok=True)
    ply_files()
    las_files()
    print("wrote", sorted(os.listdir(OUT)))
