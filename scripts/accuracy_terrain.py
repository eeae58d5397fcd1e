"""Profile and plan curvature rasters of tilecurv and of WhiteboxTools against the closed form.

usage: accuracy_terrain.py wbt WORK TERRAIN.las        (WhiteboxTools' DEM and curvature rasters)
       accuracy_terrain.py table WORK SEED             (scores every raster, prints the table)

Called by scripts/accuracy_terrain.sh, which says what runs and why. WORK holds, per terrain T
(clean, noise3cm): T.las from `tilecurv generate terrain --terrain-truth`, tilecurv's raster
directories T.<label>/ (ProfileCurvature.tif, PlanCurvature.tif) and WhiteboxTools' T.wbt_*/.

The truth is the closed form at each cell's centre: the generator's surface is re-evaluated here
(the same bump placement from the same seed streams, src/tools/generate/terrain.rs and
src/core/rng.rs), and checked against the file's own truth columns before it is used.
"""

import csv
import math
import os
import sys

import laspy
import numpy as np
import rasterio
import whitebox_workflows as wbw
from rasterio.transform import from_origin

ORIGIN = (500000.0, 4100000.0)  # generate terrain's south-west corner (ORIGIN_M)
CELL = 1.0  # raster cell, metres
DENSITY = 8.0  # points per square metre, as accuracy_terrain.sh generates them
MIN_SLOPE_DEG = 3.0  # cells scored: true slope above this (plan curvature is kh / sin S)
BORDER_M = 10.0  # cells scored: centre this far inside the square (one-sided neighbourhoods)

# ---- the generator's surface (src/core/rng.rs, src/tools/generate/terrain.rs) ----------------
MASK64 = (1 << 64) - 1
BUMP_SALT = 0x62756D707321
BUMP_CELL_M = 200.0  # BUMP_RADIUS_M.1: the bump grid's cell
BASE_ELEVATION_M = 100.0


def splitmix64(state):
    state = (state + 0x9E3779B97F4A7C15) & MASK64
    z = state
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK64
    return state, z ^ (z >> 31)


def rotl(x, k):
    return ((x << k) | (x >> (64 - k))) & MASK64


class Rng:
    """xoshiro256** seeded by splitmix64, as core::rng::Rng."""

    def __init__(self, seed):
        self.s, sm = [], seed & MASK64
        for _ in range(4):
            sm, v = splitmix64(sm)
            self.s.append(v)

    @classmethod
    def for_point(cls, seed, key):
        _, a = splitmix64(seed & MASK64)
        _, b = splitmix64((a ^ key) & MASK64)
        return cls(b)

    def next_u64(self):
        s = self.s
        result = (rotl((s[1] * 5) & MASK64, 7) * 9) & MASK64
        t = (s[1] << 17) & MASK64
        s[2] ^= s[0]
        s[3] ^= s[1]
        s[1] ^= s[2]
        s[0] ^= s[3]
        s[2] ^= t
        s[3] = rotl(s[3], 45)
        return result

    def uniform(self):
        return (self.next_u64() >> 11) * (1.0 / (1 << 53))

    def below(self, n):
        return (self.next_u64() * n) >> 64


def terrain(side_m, seed):
    """The regional slope and the bumps (cx, cy, radius, height) of Terrain::new."""
    cells = math.ceil(side_m / BUMP_CELL_M) + 2
    head = Rng(seed ^ BUMP_SALT)
    slope = (0.03 * (2 * head.uniform() - 1), 0.03 * (2 * head.uniform() - 1))
    bumps = []
    for j in range(cells):
        for i in range(cells):
            rng = Rng.for_point(seed ^ BUMP_SALT, j * cells + i)
            for _ in range(1 + rng.below(4)):
                cx = (i - 1.0 + rng.uniform()) * BUMP_CELL_M
                cy = (j - 1.0 + rng.uniform()) * BUMP_CELL_M
                radius = 20.0 * (200.0 / 20.0) ** rng.uniform()
                top = min(30.0, 0.3 * radius)
                size = 2.0 + (top - 2.0) * rng.uniform()
                sign = -1.0 if rng.uniform() < 0.5 else 1.0
                bumps.append((cx, cy, radius, sign * size))
    return slope, bumps


def derivatives(x, y, surface):
    """p, q, r, s, t of the surface at local (x, y) (metres from the south-west corner)."""
    slope, bumps = surface
    p, q = np.full_like(x, slope[0]), np.full_like(x, slope[1])
    r, s, t = np.zeros_like(x), np.zeros_like(x), np.zeros_like(x)
    for cx, cy, radius, a in bumps:
        dx, dy = x - cx, y - cy
        r2 = radius * radius
        u = np.maximum(1.0 - (dx * dx + dy * dy) / r2, 0.0)
        c1, c2 = -8.0 * a * u**3 / r2, 48.0 * a * u**2 / (r2 * r2)
        p += c1 * dx
        q += c1 * dy
        r += c1 + c2 * dx * dx
        s += c2 * dx * dy
        t += c1 + c2 * dy * dy
    return p, q, r, s, t


def height(x, y, surface):
    """z of the surface at local (x, y), metres."""
    slope, bumps = surface
    z = BASE_ELEVATION_M + slope[0] * x + slope[1] * y
    for cx, cy, radius, a in bumps:
        u = np.maximum(1.0 - ((x - cx) ** 2 + (y - cy) ** 2) / (radius * radius), 0.0)
        z = z + a * u**4
    return z


def florinsky(p, q, r, s, t):
    """Profile, tangential, plan curvature (1/m, convex positive), slope (degrees), by the
    closed forms of docs/algorithms.md 10.4."""
    g2 = p * p + q * q
    w2 = 1.0 + g2
    across = q * q * r - 2.0 * p * q * s + p * p * t
    profile = -(p * p * r + 2.0 * p * q * s + q * q * t) / (g2 * w2 * np.sqrt(w2))
    plan = -across / (g2 * np.sqrt(g2))
    tangential = -across / (g2 * np.sqrt(w2))
    return {"profile": profile, "tangential": tangential, "plan": plan,
            "slope": np.degrees(np.arctan(np.sqrt(g2)))}


def check_surface(las_path, surface):
    """The re-evaluated surface must give the file's own truth columns (to 1e-9 relative)."""
    las = laspy.read(las_path)
    pick = np.arange(0, len(las.x), 97)
    x = np.asarray(las.x)[pick] - ORIGIN[0]
    y = np.asarray(las.y)[pick] - ORIGIN[1]
    mine = florinsky(*derivatives(x, y, surface))
    for key, column in (("profile", "TrueProfileCurvature"), ("plan", "TruePlanCurvature")):
        theirs = np.asarray(las[column])[pick]
        ok = np.isfinite(theirs)
        err = np.max(np.abs(mine[key][ok] - theirs[ok]) / (np.abs(theirs[ok]) + 1e-6))
        if not err < 1e-6:
            sys.exit(f"accuracy_terrain.py: the re-evaluated surface differs from {las_path}'s "
                     f"{column} by {err:.2g} (relative): has generate terrain changed?")


# ---- rasters ------------------------------------------------------------------------------------
def read_raster(path):
    with rasterio.open(path) as d:
        a = d.read(1).astype(np.float64)
        if d.nodata is not None:
            a[a == d.nodata] = np.nan
        a[~np.isfinite(a)] = np.nan
        return a, d.transform, d.crs


def whole_metre_grid(las_path):
    """The grid tilecurv uses: cells at whole multiples of CELL covering the file's bounds."""
    with laspy.open(las_path) as f:
        lo, hi = f.header.mins, f.header.maxs
    west, south = math.floor(lo[0] / CELL) * CELL, math.floor(lo[1] / CELL) * CELL
    east, north = math.ceil(hi[0] / CELL) * CELL, math.ceil(hi[1] / CELL) * CELL
    shape = (round((north - south) / CELL), round((east - west) / CELL))
    return from_origin(west, north, CELL, CELL), shape


def with_corner_anchors(las_path, out_path):
    """A copy of the points plus two at the whole-metre corners of the raster grid (south-west
    and north-east, each with the z of the nearest real point): lidar_tin_gridding starts its grid
    at the points' minimum x and maximum y, and these make those whole metres. They change the TIN
    only next to the corners, far outside the scored cells (print_table checks the DEM there
    against the true heights)."""
    las = laspy.read(las_path)
    x, y, z = np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)
    transform, shape = whole_metre_grid(las_path)
    corners = [(transform.c, transform.f + shape[0] * transform.e),
               (transform.c + shape[1] * transform.a, transform.f)]
    extra = laspy.ScaleAwarePointRecord.zeros(2, header=las.header)
    extra.x = np.array([c[0] for c in corners])
    extra.y = np.array([c[1] for c in corners])
    extra.z = np.array([z[np.argmin((x - cx) ** 2 + (y - cy) ** 2)] for cx, cy in corners])
    extra.classification = las.classification[:2]
    out = laspy.LasData(las.header)
    out.points = laspy.ScaleAwarePointRecord(
        np.concatenate([las.points.array, extra.array]), las.header.point_format,
        las.header.scales, las.header.offsets)
    out.write(out_path)


def run_wbt(work, las_path):
    """WhiteboxTools' 1 m DEMs of the points by lidar_tin_gridding (linear TIN interpolation at
    the cell centres), each with its profile, plan and tangential curvature.

    wbt_tin: on the points as they are (its grid starts at their minimum x and maximum y, not on
    whole metres here; scored against the truth at its own cell centres). wbt_tin_aligned: on the
    points plus two corner anchors (with_corner_anchors), which puts the grid on the whole metres
    tilecurv uses, cell for cell. (tin_interpolation with a base raster would align too, but in
    2.0.6 it returned heights off by metres on a quarter of the cells here.)
    """
    wbe = wbw.WbEnvironment()
    name = os.path.splitext(os.path.basename(las_path))[0]
    anchored = os.path.join(work, f"{name}.anchored.las")
    with_corner_anchors(las_path, anchored)
    for label, path in (("wbt_tin", las_path), ("wbt_tin_aligned", anchored)):
        dem = wbe.lidar.interpolation_gridding.lidar_tin_gridding(
            input=wbe.read_lidar(path), resolution=CELL, interpolation_parameter="elevation",
            returns_included="all")
        out = os.path.join(work, f"{name}.{label}")
        os.makedirs(out, exist_ok=True)
        wbe.write_raster(dem, os.path.join(out, "dem.tif"))
        derivs = wbe.terrain.derivatives
        for column, tool in (("ProfileCurvature", derivs.profile_curvature),
                             ("PlanCurvature", derivs.plan_curvature),
                             ("TangentialCurvature", derivs.tangential_curvature)):
            wbe.write_raster(tool(input=dem), os.path.join(out, f"{column}.tif"))
    os.remove(anchored)


# ---- scoring ------------------------------------------------------------------------------------
def truth_on_grid(transform, shape, surface, side_m):
    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]]
    x = transform.c + (cols + 0.5) * transform.a - ORIGIN[0]
    y = transform.f + (rows + 0.5) * transform.e - ORIGIN[1]
    truth = florinsky(*derivatives(x, y, surface))
    inside = (x > BORDER_M) & (y > BORDER_M) & (x < side_m - BORDER_M) & (y < side_m - BORDER_M)
    truth["scored"] = inside & (truth["slope"] > MIN_SLOPE_DEG)
    return truth


def rel_error(est, truth, mask):
    """median |est - truth| / median |truth| over mask."""
    return float(np.median(np.abs(est[mask] - truth[mask])) / np.median(np.abs(truth[mask])))


# Rows of the table: (directory label, method, how the cell value is formed).
ROWS = [
    ("wbt_tin_aligned", "WhiteboxTools 2.0.6 (`lidar_tin_gridding` 1 m DEM, 5x5 Florinsky)",
     "TIN at the cell centre, whole-metre grid"),
    ("wbt_tin", "WhiteboxTools 2.0.6 (`lidar_tin_gridding` 1 m DEM, 5x5 Florinsky)",
     "TIN at the cell centre, its own grid (truth at its centres)"),
    ("k30", "tilecurv `-k 30`", "mean of the cell's points"),
    ("auto", "tilecurv `-k auto`", "mean of the cell's points (`--raster 1m`)"),
    ("auto_median", "tilecurv `-k auto`", "median of the cell's points (`--stat median`)"),
    ("auto640", "tilecurv `-k auto --k-range 20..640`", "mean of the cell's points"),
    ("k320", "tilecurv `-k 320`", "mean of the cell's points"),
    ("jet3_auto640", "tilecurv `-k auto --k-range 20..640 --estimator jet --jet-degree 3`",
     "mean of the cell's points"),
    ("truth_mean", "the truth columns themselves (binning floor)", "mean of the cell's points"),
]
TERRAINS = [("clean", "clean"), ("noise3cm", "3 cm noise")]
QUANTITIES = [("profile", "ProfileCurvature"), ("plan", "PlanCurvature")]


def table(work, seed):
    scores, cells, checks, dem_checks = {}, {}, [], []
    for terrain_name, _ in TERRAINS:
        las_path = os.path.join(work, f"{terrain_name}.las")
        with laspy.open(las_path) as f:
            side_m = math.sqrt(f.header.point_count / DENSITY)
        surface = terrain(side_m, seed)
        check_surface(las_path, surface)
        ref_transform, ref_shape = whole_metre_grid(las_path)
        # One mask for every raster on the whole-metre grid: scored cells where all are defined.
        truth = truth_on_grid(ref_transform, ref_shape, surface, side_m)
        common = truth["scored"].copy()
        rasters = {}
        for label, _, _ in ROWS:
            for q, column in QUANTITIES:
                path = os.path.join(work, f"{terrain_name}.{label}", f"{column}.tif")
                est, transform, crs = read_raster(path)
                if crs is None or crs.to_epsg() != 32610:
                    sys.exit(f"accuracy_terrain.py: {path}: CRS {crs}, expected EPSG:32610")
                rasters[label, q] = (est, transform)
                if label == "wbt_tin":
                    continue  # its own grid, scored on its own below
                if transform != ref_transform or est.shape != ref_shape:
                    sys.exit(f"accuracy_terrain.py: {path}: grid {transform} {est.shape} is not "
                             f"the whole-metre grid {ref_transform} {ref_shape}")
                common &= np.isfinite(est)
        for label, _, _ in ROWS:
            for q, _ in QUANTITIES:
                est, transform = rasters[label, q]
                if label == "wbt_tin":
                    own = truth_on_grid(transform, est.shape, surface, side_m)
                    mask = own["scored"] & np.isfinite(est)
                    t = own[q]
                else:
                    mask, t = common, truth[q]
                scores[terrain_name, label, q] = rel_error(est, t, mask)
                cells[terrain_name, label] = int(mask.sum())
        # WhiteboxTools' DEMs against the true heights at their cell centres, over scored cells.
        for label in ("wbt_tin", "wbt_tin_aligned"):
            dem, transform, _ = read_raster(os.path.join(work, f"{terrain_name}.{label}",
                                                         "dem.tif"))
            rows, cols = np.mgrid[0 : dem.shape[0], 0 : dem.shape[1]]
            x = transform.c + (cols + 0.5) * transform.a - ORIGIN[0]
            y = transform.f + (rows + 0.5) * transform.e - ORIGIN[1]
            m = truth_on_grid(transform, dem.shape, surface, side_m)["scored"] & np.isfinite(dem)
            err = np.abs(dem - height(x, y, surface))[m]
            dem_checks.append((terrain_name, label, transform, float(np.median(err)),
                               float(err.max())))
        # Sign and unit check of WhiteboxTools against the truth: gain of a least-squares fit
        # est = gain * truth (1 when the convention and unit are ours), and its correlation.
        for q, column in QUANTITIES + [("tangential", "TangentialCurvature")]:
            est = read_raster(os.path.join(work, f"{terrain_name}.wbt_tin_aligned",
                                           f"{column}.tif"))[0]
            t = truth[q]
            m = common & np.isfinite(est)
            gain = float(np.sum(est[m] * t[m]) / np.sum(t[m] ** 2))
            corr = float(np.corrcoef(est[m], t[m])[0, 1])
            checks.append((terrain_name, q, gain, corr, rel_error(est, t, m)))
    return scores, cells, checks, dem_checks


def print_table(work, seed):
    scores, cells, checks, dem_checks = table(work, seed)
    print("WhiteboxTools' DEMs: |DEM - true height| over the scored cells (median, max), and "
          "the grid's north-west corner:")
    for terrain_name, label, transform, med, top in dem_checks:
        print(f"  {terrain_name:9s} {label:16s} {med * 1000:.2f} mm, {top * 1000:.1f} mm  "
              f"(x {transform.c:.3f}, y {transform.f:.3f})")
    print("WhiteboxTools against the closed form (least-squares gain of WBT = gain x truth, "
          "correlation, error), on the aligned DEM:")
    for terrain_name, q, gain, corr, err in checks:
        print(f"  {terrain_name:9s} {q:10s} gain {gain:+.3f}  corr {corr:+.4f}  error {err:.3f}")
    print()
    head = "| method | cell value | " + " | ".join(
        f"{t_label}, {q}" for _, t_label in TERRAINS for q, _ in QUANTITIES) + " |"
    print(head)
    print("|---|---|" + "---:|" * (len(TERRAINS) * len(QUANTITIES)))
    with open(os.path.join(work, "accuracy.csv"), "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(["label", "terrain", "quantity", "error", "ratio_to_wbt", "cells"])
        for label, method, value in ROWS:
            row = []
            for terrain_name, _ in TERRAINS:
                for q, _ in QUANTITIES:
                    e = scores[terrain_name, label, q]
                    ratio = e / scores[terrain_name, "wbt_tin_aligned", q]
                    out.writerow([label, terrain_name, q, f"{e:.5f}", f"{ratio:.3f}",
                                  cells[terrain_name, label]])
                    row.append(f"{e:.4f}" if label.startswith("wbt") else f"{e:.4f} ({ratio:.2f}x)")
            print(f"| {method} | {value} | " + " | ".join(row) + " |")
    print()
    print(f"Error: median |raster - truth| / median |truth| over the cells with true slope > "
          f"{MIN_SLOPE_DEG:g} degrees whose centre is over {BORDER_M:g} m inside the square "
          f"({cells['clean', 'auto']} cells clean, {cells['noise3cm', 'auto']} noisy, the same "
          f"cells for every raster on the whole-metre grid); truth: the generator's closed form "
          f"at the cell centre. (Nx): the error over the aligned WhiteboxTools raster's.")
    print()
    verdicts = []
    for terrain_name, bound in (("noise3cm", 0.3), ("clean", 1.5)):
        for q, _ in QUANTITIES:
            r = scores[terrain_name, "auto", q] / scores[terrain_name, "wbt_tin_aligned", q]
            verdicts.append(f"{terrain_name} {q} {r:.2f}x (target <= {bound}x: "
                            f"{'met' if r <= bound else 'NOT met'})")
    print("tilecurv -k auto, cell mean, against WhiteboxTools: " + "; ".join(verdicts))


def main():
    if len(sys.argv) == 4 and sys.argv[1] == "wbt":
        run_wbt(sys.argv[2], sys.argv[3])
    elif len(sys.argv) == 4 and sys.argv[1] == "table":
        print_table(sys.argv[2], int(sys.argv[3]))
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main()
