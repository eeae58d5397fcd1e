"""tilecurv.curvature against pgeof and jakteristics on the same points in one Python process,
for scripts/bench_python.sh.

usage: bench_python.py INPUT [K] [THREADS] [ROUNDS]

Reads INPUT (LAS/LAZ) with laspy into an (n, 3) float64 array, then times, ROUNDS times in turn
(the order rotated each round, so that no tool always runs first on a warm or cold cache):

- tilecurv: tilecurv.curvature(xyz, k=K, threads=THREADS): PCA normals and the default
  CNC-Avg-Hexagram's H and K with the flags (a run through the work directory in the temporary
  directory: the same engine as `process`);
- pgeof: pgeof.knn_search (K nearest, the point itself included, as tilecurv's -k) and
  pgeof.compute_features (its 11 covariance features; PCA only), on float32 coordinates
  centred on their mean (pgeof works in float32); it uses every core by itself;
- jakteristics: jakteristics.compute_features with max_k_neighbors=K and a search radius that
  holds at least K points for 99% of the points (the 99th percentile of pgeof's K-th neighbour
  distance): every one of its covariance features (jakteristics.FEATURE_NAMES) with THREADS threads, on centred float64 coordinates.

Prints each run's seconds and, per tool, its best time and the ratio to tilecurv's best
(peer seconds / tilecurv seconds: above 1, tilecurv is faster).
"""

import sys
import time

import laspy
import numpy as np

import jakteristics
import pgeof
import tilecurv


def main() -> int:
    if not 2 <= len(sys.argv) <= 5:
        print(__doc__, file=sys.stderr)
        return 2
    src = sys.argv[1]
    k = int(sys.argv[2]) if len(sys.argv) > 2 else 30
    threads = int(sys.argv[3]) if len(sys.argv) > 3 else 2
    rounds = int(sys.argv[4]) if len(sys.argv) > 4 else 2
    las = laspy.read(src)
    xyz = np.ascontiguousarray(np.column_stack((las.x, las.y, las.z)))
    centred = xyz - xyz.mean(axis=0)
    xyz32 = np.ascontiguousarray(centred, dtype=np.float32)
    n = len(xyz)
    _, dist = pgeof.knn_search(xyz32, xyz32, k)
    radius = float(np.percentile(dist[:, -1], 99))
    print(f"{n} points, k = {k}, {threads} threads; jakteristics radius {radius:.3f}", flush=True)

    def run_tilecurv():
        cols = tilecurv.curvature(xyz, k=k, threads=threads)
        assert len(cols["H"]) == n

    def run_pgeof():
        nn, _ = pgeof.knn_search(xyz32, xyz32, k)
        nn_ptr = np.arange(0, n * k + 1, k, dtype=np.uint32)
        f = pgeof.compute_features(xyz32, nn.reshape(-1).astype(np.uint32, copy=False), nn_ptr, k_min=3)
        assert len(f) == n

    def run_jakteristics():
        f = jakteristics.compute_features(
            centred,
            search_radius=radius,
            max_k_neighbors=k,
            num_threads=threads,
            feature_names=jakteristics.FEATURE_NAMES,
        )
        assert len(f) == n

    tools = [("tilecurv", run_tilecurv), ("pgeof", run_pgeof), ("jakteristics", run_jakteristics)]
    times = {name: [] for name, _ in tools}
    for r in range(rounds):
        for name, f in tools[r % 3 :] + tools[: r % 3]:
            t = time.perf_counter()
            f()
            s = time.perf_counter() - t
            times[name].append(s)
            print(f"round {r + 1}: {name} {s:.2f} s ({n / s / 1e3:.0f}k points/s)", flush=True)
    best = {name: min(v) for name, v in times.items()}
    print("\n| tool | best of %d (s) | points/s | ratio to tilecurv |" % rounds)
    print("|---|---|---|---|")
    for name, _ in tools:
        ratio = best[name] / best["tilecurv"]
        print(f"| {name} | {best[name]:.2f} | {n / best[name] / 1e3:.0f}k | {ratio:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
