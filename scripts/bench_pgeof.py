#!/usr/bin/env python3
"""pgeof end to end on a LAS/LAZ file, the way a user would run it, for scripts/bench_pgeof.sh.

usage: bench_pgeof.py INPUT OUTPUT [K]

Reads INPUT with laspy, finds the K nearest neighbours of every point with pgeof.knn_search (the
point itself included, as tilecurv's -k counts it), computes pgeof's 11 local geometric features
(linearity, planarity, scattering, verticality, normal x/y/z, length, surface, volume, curvature)
with pgeof.compute_features, and writes INPUT's points plus those features as float32 extra
dimensions to OUTPUT with laspy. pgeof works in float32, so the coordinates are centred on their
mean first (UTM coordinates in float32 would lose centimetres). pgeof uses every core by itself.

Prints one line per phase and a final line "pgeof: N points in T s (P points/s)" on stderr.
"""
import sys
import time

import laspy
import numpy as np
import pgeof

FEATURES = [
    "linearity",
    "planarity",
    "scattering",
    "verticality",
    "normal_x",
    "normal_y",
    "normal_z",
    "length",
    "surface",
    "volume",
    "curvature",
]


def main() -> int:
    if len(sys.argv) not in (3, 4):
        print(__doc__, file=sys.stderr)
        return 2
    src, dst = sys.argv[1], sys.argv[2]
    k = int(sys.argv[3]) if len(sys.argv) == 4 else 30
    t0 = time.perf_counter()
    las = laspy.read(src)
    xyz64 = np.column_stack((las.x, las.y, las.z))
    xyz = np.ascontiguousarray(xyz64 - xyz64.mean(axis=0), dtype=np.float32)
    del xyz64
    n = len(xyz)
    t1 = time.perf_counter()
    print(f"read: {n} points in {t1 - t0:.1f} s", file=sys.stderr)
    nn, _dist = pgeof.knn_search(xyz, xyz, k)
    del _dist
    nn_ptr = np.arange(0, n * k + 1, k, dtype=np.uint32)
    t2 = time.perf_counter()
    print(f"knn_search k={k}: {t2 - t1:.1f} s", file=sys.stderr)
    feats = pgeof.compute_features(xyz, nn.reshape(-1).astype(np.uint32, copy=False), nn_ptr, k_min=3)
    del nn
    t3 = time.perf_counter()
    print(f"compute_features: {t3 - t2:.1f} s", file=sys.stderr)
    las.add_extra_dims([laspy.ExtraBytesParams(name=f, type=np.float32) for f in FEATURES])
    for i, f in enumerate(FEATURES):
        las[f] = feats[:, i]
    las.write(dst)
    t4 = time.perf_counter()
    print(f"write: {t4 - t3:.1f} s", file=sys.stderr)
    print(f"pgeof: {n} points in {t4 - t0:.1f} s ({n / (t4 - t0):.0f} points/s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
