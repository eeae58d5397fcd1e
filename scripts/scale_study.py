"""Analysis of the scale study (scripts/scale_study.sh, docs/scale.md).

  scale_study.py header                     the CSV header line
  scale_study.py measure --cloud C --mode M --param P --border B --times U S E OUT.las
                                            one CSV row: errors of OUT.las against its truth
  scale_study.py report --csv CSV --table MD --plot PNG
                                            the Markdown tables and the H RMS vs K plot
  scale_study.py survey --name N --mode M --times U S E OUT.las
                                            one Markdown row about a real survey's output
  scale_study.py map --column H --title T --png PNG OUT.las
                                            a top-view map of one column (H clipped at the
                                            2-98 percentiles; ScaleK on a log scale)

Errors are against the closed-form columns TrueH and TrueK that `tilecurv generate` writes, over
the points where both the estimate and the truth are defined, away from a border band of B
metres from the cloud's bounding box in x and y (--border B; the terrain's square has one-sided
neighbourhoods near its edges), or for a torus processed with --orient outward away from the
seams where that orientation flips, with the flipped H's sign restored (--torus-seam BAND).
"""

import argparse
import csv
import io
import math
import sys

import numpy as np

FIELDS = [
    "cloud", "mode", "param", "points", "scored", "undefined_frac", "boundary_frac",
    "h_rms", "k_rms", "h_rms_west", "h_rms_east", "user_s", "sys_s", "wall_s", "cpu_us_per_point",
    "scalek_median", "scalek_mean", "saturated_frac", "rung_fracs",
]
UNDEFINED = 1 | 2 | 4 | 128  # CurvatureFlags bits under which H, K, k1, k2 are NaN
BOUNDARY = 8
SATURATED = 1  # ScaleFlags bit: top rung chosen while the criterion was still falling


def header(_args):
    print(",".join(FIELDS))


def read(path, names):
    import laspy

    las = laspy.read(path)
    dims = set(las.point_format.dimension_names)
    cols = {n: np.asarray(las[n], dtype=np.float64) for n in names if n in dims}
    return np.asarray(las.x), np.asarray(las.y), np.asarray(las.z), cols


def rms(v):
    return float(np.sqrt(np.mean(v * v))) if v.size else float("nan")


def torus_seam(x, y, z, band_m, big_r=6.0, r=2.0):
    """For a torus processed with --orient outward (normals away from the centroid, the origin):
    the sign that turns its H into the outward normal's, and the points farther than band_m
    (along the tube) from the seams where that orientation flips. The outward normal n at
    tube angle theta has <n | p> = R cos(theta) + r, so `outward` flips the normals where
    cos(theta) < -r/R; neighbourhoods across that circle mix both signs and are left out."""
    ct = (np.hypot(x, y) - big_r) / np.hypot(np.hypot(x, y) - big_r, z)
    theta = np.arccos(np.clip(ct, -1.0, 1.0))  # 0..pi, symmetric in z
    seam = math.acos(-r / big_r)
    return np.where(big_r * ct + r < 0, -1.0, 1.0), np.abs(theta - seam) * r > band_m


def measure(a):
    x, y, z, c = read(a.output, ["H", "K", "TrueH", "TrueK", "CurvatureFlags", "ScaleK", "ScaleFlags"])
    n = x.size
    flags = c["CurvatureFlags"].astype(np.int64)
    inside = np.ones(n, dtype=bool)
    if a.border > 0:
        inside = (
            (x >= x.min() + a.border) & (x <= x.max() - a.border)
            & (y >= y.min() + a.border) & (y <= y.max() - a.border)
        )
    if a.torus_seam > 0:
        sign, inside = torus_seam(x, y, z, a.torus_seam)
        c["H"] = c["H"] * sign
    truth = np.isfinite(c["TrueH"]) & np.isfinite(c["TrueK"]) & inside
    defined = np.isfinite(c["H"]) & np.isfinite(c["K"]) & ((flags & UNDEFINED) == 0)
    ok = truth & defined
    eh = c["H"][ok] - c["TrueH"][ok]
    ek = c["K"][ok] - c["TrueK"][ok]
    # West and east halves (the half-noisy terrain is clean west of the middle).
    mid = 0.5 * (x.min() + x.max())
    west = x[ok] < mid
    user, sys_, wall = a.times
    row = {
        "cloud": a.cloud, "mode": a.mode, "param": a.param, "points": n, "scored": int(ok.sum()),
        "undefined_frac": f"{(truth & ~defined).sum() / max(truth.sum(), 1):.5f}",
        "boundary_frac": f"{((flags & BOUNDARY) != 0)[truth].mean():.5f}",
        "h_rms": f"{rms(eh):.5g}", "k_rms": f"{rms(ek):.5g}",
        "h_rms_west": f"{rms(eh[west]):.5g}", "h_rms_east": f"{rms(eh[~west]):.5g}",
        "user_s": user, "sys_s": sys_, "wall_s": wall,
        "cpu_us_per_point": f"{1e6 * (float(user) + float(sys_)) / n:.3f}",
        "scalek_median": "", "scalek_mean": "", "saturated_frac": "", "rung_fracs": "",
    }
    if "ScaleK" in c:
        sk = c["ScaleK"][truth & defined]
        row["scalek_median"] = f"{np.median(sk):.0f}"
        row["scalek_mean"] = f"{np.mean(sk):.1f}"
        rungs, counts = np.unique(sk.astype(int), return_counts=True)
        row["rung_fracs"] = " ".join(f"{r}:{k / sk.size:.3f}" for r, k in zip(rungs, counts))
    if "ScaleFlags" in c:
        sat = (c["ScaleFlags"].astype(np.int64) & SATURATED) != 0
        row["saturated_frac"] = f"{sat[truth & defined].mean():.4f}"
    w = csv.DictWriter(sys.stdout, FIELDS, lineterminator="\n")
    w.writerow(row)


def load(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        for k in ("h_rms", "k_rms", "h_rms_west", "h_rms_east", "cpu_us_per_point",
                  "undefined_frac", "boundary_frac"):
            r[k] = float(r[k])
    return rows


def label(r):
    return {"fixed": f"K = {r['param']}", "radius": f"radius {r['param']}", "auto": "-k auto"}[r["mode"]]


def report(a):
    rows = load(a.csv)
    clouds = list(dict.fromkeys(r["cloud"] for r in rows))
    out = []
    best = {}
    for c in clouds:
        fixed = [r for r in rows if r["cloud"] == c and r["mode"] == "fixed"]
        best[c] = min(fixed, key=lambda r: r["h_rms"])
    # Summary, as the table of algorithms.md 9.5.
    out.append("| cloud | best fixed K (H RMS) | K = 30 | best radius | -k auto | auto: median K | auto: saturated |")
    out.append("|---|---|---:|---:|---:|---:|---:|")
    for c in clouds:
        b = best[c]
        here = [r for r in rows if r["cloud"] == c]
        k30 = next((r for r in here if r["mode"] == "fixed" and r["param"] == "30"), None)
        rad = min((r for r in here if r["mode"] == "radius"), key=lambda r: r["h_rms"], default=None)
        auto = next((r for r in here if r["mode"] == "auto"), None)
        ratio = lambda r: f"{r['h_rms'] / b['h_rms']:.2f}" if r else "-"
        rad_cell = f"{ratio(rad)} ({rad['param']})" if rad else "-"
        median_k = auto["scalek_median"] if auto and auto["scalek_median"] else "-"
        sat = f"{100 * float(auto['saturated_frac']):.0f}%" if auto and auto["saturated_frac"] else "-"
        out.append(
            f"| {c} | {b['param']} ({b['h_rms']:.3g}) | {ratio(k30)} | {rad_cell} | {ratio(auto)} "
            f"| {median_k} | {sat} |"
        )
    out.append("")
    out.append("Every run: H and K RMS against the closed form over the scored points, the ratio of H RMS "
               "(and K RMS) to the best fixed K of that cloud, the undefined fraction, and CPU time per point.")
    out.append("")
    out.append("| cloud | mode | H RMS | H / best | K RMS | K / best | H RMS west / east | undefined | scored | CPU us/point |")
    out.append("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for c in clouds:
        b = best[c]
        for r in [r for r in rows if r["cloud"] == c]:
            out.append(
                f"| {c} | {label(r)} | {r['h_rms']:.3g} | {r['h_rms'] / b['h_rms']:.2f} | {r['k_rms']:.3g} "
                f"| {r['k_rms'] / b['k_rms']:.2f} | {r['h_rms_west']:.3g} / {r['h_rms_east']:.3g} "
                f"| {100 * r['undefined_frac']:.2f}% | {r['scored']} | {r['cpu_us_per_point']:.2f} |"
            )
    out.append("")
    out.append("CPU time per point of each mode (user + sys of the whole `process` run, median over the clouds):")
    out.append("")
    out.append("| mode | CPU us/point (median) | min | max | / K = 30 |")
    out.append("|---|---:|---:|---:|---:|")
    modes = list(dict.fromkeys((r["mode"], r["param"] if r["mode"] != "radius" else "") for r in rows))
    base = np.median([r["cpu_us_per_point"] for r in rows if r["mode"] == "fixed" and r["param"] == "30"] or [float("nan")])
    for m, p in modes:
        t = [r["cpu_us_per_point"] for r in rows if r["mode"] == m and (m == "radius" or r["param"] == p)]
        name = {"fixed": f"K = {p}", "radius": "radius (all values)", "auto": "-k auto"}[m]
        out.append(f"| {name} | {np.median(t):.2f} | {min(t):.2f} | {max(t):.2f} | {np.median(t) / base:.1f} |")
    with open(a.table, "w") as f:
        f.write("\n".join(out) + "\n")
    plot(rows, clouds, a.plot)


def save_png(fig, path, colors=96):
    """Saves a figure as a palette PNG (small enough for the repository)."""
    from PIL import Image

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=fig.dpi)
    buf.seek(0)
    img = Image.open(buf).convert("RGB").quantize(colors=colors, method=Image.Quantize.MEDIANCUT)
    img.save(path, optimize=True)


def plot(rows, clouds, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    cols = 3
    fig, axes = plt.subplots(math.ceil(len(clouds) / cols), cols, figsize=(11, 6.4), dpi=90, squeeze=False)
    for ax, c in zip(axes.flat, clouds):
        fixed = sorted((int(r["param"]), r["h_rms"]) for r in rows if r["cloud"] == c and r["mode"] == "fixed")
        ax.loglog([k for k, _ in fixed], [h for _, h in fixed], "o-", color="black", label="fixed K")
        styles = iter(["--", "-.", ":"])
        for r in [r for r in rows if r["cloud"] == c and r["mode"] == "radius"]:
            ax.axhline(r["h_rms"], color="tab:blue", ls=next(styles, "--"), lw=1, label=f"radius {r['param']}")
        for r in [r for r in rows if r["cloud"] == c and r["mode"] == "auto"]:
            ax.axhline(r["h_rms"], color="tab:red", lw=2, label="-k auto")
        ax.set_title(c, fontsize=10)
        ax.set_xlabel("K")
        ax.set_ylabel("H RMS (1/m)")
        ax.set_xticks([20, 40, 80, 160, 320])
        ax.set_xticklabels(["20", "40", "80", "160", "320"])
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    for ax in list(axes.flat)[len(clouds):]:
        ax.axis("off")
    fig.tight_layout()
    save_png(fig, path)


def survey(a):
    x, _, _, c = read(a.output, ["H", "CurvatureFlags", "ScaleK", "ScaleFlags"])
    ok = np.isfinite(c["H"]) & ((c["CurvatureFlags"].astype(np.int64) & UNDEFINED) == 0)
    h = c["H"][ok]
    p2, p50, p98 = np.percentile(h, [2, 50, 98])
    scale, sat = "-", "-"
    if "ScaleK" in c:
        sk = c["ScaleK"][ok].astype(int)
        rungs, counts = np.unique(sk, return_counts=True)
        scale = ", ".join(f"{r}: {100 * k / sk.size:.0f}%" for r, k in zip(rungs, counts))
        sat = f"{100 * ((c['ScaleFlags'][ok].astype(np.int64) & SATURATED) != 0).mean():.0f}%"
    user, sys_, _ = (float(t) for t in a.times)
    print(f"| {a.name} | {a.mode} | {ok.sum()} | {p2:.3g} / {p50:.3g} / {p98:.3g} | {h.std():.3g} "
          f"| {scale} | {sat} | {1e6 * (user + sys_) / ok.sum():.2f} |")


def binned(idx, v, nx, ny):
    """The mean of v per pixel (NaN where empty), as an ny x nx image."""
    total = np.bincount(idx, weights=v, minlength=nx * ny)
    count = np.bincount(idx, minlength=nx * ny)
    with np.errstate(invalid="ignore", divide="ignore"):
        return (total / count).reshape(ny, nx)


def map_(a):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker
    from matplotlib.colors import LogNorm

    x, y, _, c = read(a.output, [a.column, "CurvatureFlags"])
    v = c[a.column]
    # Undefined and not-computed points hold the column's no-data value: left out.
    keep = np.isfinite(v) & ((c["CurvatureFlags"].astype(np.int64) & UNDEFINED) == 0)
    x, y, v = x[keep] - x.min(), y[keep] - y.min(), v[keep]
    # Binned to pixels about one point spacing wide (at most 450 across): the mean per pixel
    # (of log2 K for ScaleK), empty pixels left white.
    w, h = x.max(), y.max()
    cell = max(max(w, h) / 450, math.sqrt(w * h / v.size))
    nx, ny = int(w / cell) + 1, int(h / cell) + 1
    idx = (y / cell).astype(int) * nx + (x / cell).astype(int)
    fig, ax = plt.subplots(figsize=(6.2, 5.2), dpi=90)
    extent = (0, nx * cell, 0, ny * cell)
    if a.column == "ScaleK":
        rungs = np.unique(v)
        img = binned(idx, np.log2(v), nx, ny)
        norm = LogNorm(vmin=max(rungs.min(), 1), vmax=max(rungs.max(), 2))
        im = ax.imshow(2.0 ** img, origin="lower", extent=extent, cmap="viridis", norm=norm,
                       interpolation="nearest")
        cb = fig.colorbar(im, ax=ax, ticks=rungs)
        cb.ax.set_yticklabels([f"{r:.0f}" for r in rungs])
        cb.ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        cb.set_label("chosen K (pixel mean of log2 K)")
    else:
        lo, hi = np.percentile(v, [2, 98])
        m = max(abs(lo), abs(hi))
        img = binned(idx, np.clip(v, lo, hi), nx, ny)
        im = ax.imshow(img, origin="lower", extent=extent, cmap="RdBu_r", vmin=-m, vmax=m,
                       interpolation="nearest")
        cb = fig.colorbar(im, ax=ax)
        cb.set_label(f"{a.column} (1/m), clipped at the 2-98 percentiles [{lo:.3g}, {hi:.3g}]")
    ax.set_aspect("equal")
    ax.set_xlabel("x - min (m)")
    ax.set_ylabel("y - min (m)")
    ax.set_title(f"{a.title} ({v.size} points, {cell:.2g} m pixels)", fontsize=10)
    fig.tight_layout()
    save_png(fig, a.png)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)

    def command(name, f, required=(), output=True, times=False):
        """A subcommand with required string options `required`, the output file argument and
        GNU time's three numbers if asked."""
        c = sub.add_parser(name)
        for opt in required:
            c.add_argument(opt, required=True)
        if times:
            c.add_argument("--times", nargs=3, required=True, metavar=("USER", "SYS", "WALL"))
        if output:
            c.add_argument("output")
        c.set_defaults(f=f)
        return c

    command("header", header, output=False)
    m = command("measure", measure, ["--cloud", "--param"], times=True)
    m.add_argument("--mode", required=True, choices=["fixed", "radius", "auto"])
    m.add_argument("--border", type=float, default=0.0)
    m.add_argument("--torus-seam", type=float, default=0.0,
                   help="torus with --orient outward: score away from the seams by this many m")
    command("report", report, ["--csv", "--table", "--plot"], output=False)
    command("survey", survey, ["--name", "--mode"], times=True)
    command("map", map_, ["--column", "--title", "--png"])
    args = p.parse_args()
    args.f(args)


if __name__ == "__main__":
    main()
