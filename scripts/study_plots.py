#!/usr/bin/env python3
"""Plots and tables of the estimator study (docs/study.md) from the CSV of benches/study.rs.

Usage: python3 scripts/study_plots.py DIR   (reads DIR/results.csv, writes into DIR)

Writes SVG plots (error_vs_n.svg, error_vs_noise.svg, time_per_point.svg, window.svg) and
summary.md, the Markdown tables that docs/study.md quotes. Errors are in units of 1e-3.
Installs matplotlib from PyPI quietly if it is missing.
"""

import csv
import math
import os
import statistics
import subprocess
import sys

try:
    import matplotlib
except ImportError:
    subprocess.check_call(
        [sys.executable, "-m", "pip", "install", "--quiet", "--disable-pip-version-check",
         "--root-user-action=ignore", "matplotlib"],
        stdout=subprocess.DEVNULL,
    )
    import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

# Deterministic SVG output (no random ids, no date).
plt.rcParams["svg.hashsalt"] = "tilecurv-study"
plt.rcParams["font.size"] = 9
# Text as text, not paths: smaller files, searchable labels.
plt.rcParams["svg.fonttype"] = "none"

ORDER = ["cnc-avg-hexagram", "cnc-hexagram", "cnc-uniform", "cnc-delaunay", "apss", "aso",
         "wme", "jet", "jet-d4", "vcm"]
QUANTITIES = ["h", "k", "k1", "k2"]
LABELS = {"h": "H", "k": "K", "k1": "k1", "k2": "k2"}
SLOW = {"cnc-delaunay", "vcm"}


def load(path):
    rows = []
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            for key in ("n", "k", "evaluated", "undefined"):
                r[key] = int(r[key])
            for key in list(r):
                if key.endswith(("_rms", "_max", "_deg", "_point")) or key.startswith("sigma"):
                    r[key] = float(r[key])
            rows.append(r)
    return rows


def pick(rows, **kw):
    return [r for r in rows if all(r[k] == v for k, v in kw.items())]


def one(rows, **kw):
    found = pick(rows, **kw)
    return found[0] if found else None


def estimators(rows):
    present = {r["estimator"] for r in rows}
    return [e for e in ORDER if e in present] + sorted(present - set(ORDER))


def style(est):
    i = ORDER.index(est) if est in ORDER else len(ORDER)
    color = plt.get_cmap("tab10")(i % 10)
    marker = "os^vDP*Xhp"[i % 10]
    dash = "-" if est.startswith("cnc") else "--"
    return dict(color=color, marker=marker, linestyle=dash, markersize=4, linewidth=1.2)


def save(fig, out, name):
    fig.savefig(os.path.join(out, name), metadata={"Date": None})
    plt.close(fig)


def shapes(rows):
    return [s for s in ("goursat", "torus") if any(r["shape"] == s for r in rows)]


def plot_error_vs_n(rows, out):
    grid = pick(rows, series="grid", sigma_p=0.0, sigma_n=0.0, k=50)
    if not grid:
        return
    ss = shapes(grid)
    fig, axes = plt.subplots(len(ss), 4, figsize=(13, 3.2 * len(ss)), squeeze=False)
    for si, shape in enumerate(ss):
        for qi, q in enumerate(QUANTITIES):
            ax = axes[si][qi]
            for est in estimators(grid):
                pts = sorted((r["n"], 1e3 * r[q + "_rms"])
                             for r in pick(grid, shape=shape, estimator=est))
                if pts:
                    ax.plot(*zip(*pts), label=est, **style(est))
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_title(f"{shape}: RMS error of {LABELS[q]} (1e-3)")
            ax.set_xlabel("N (i.i.d. sample, no noise, K = 50)")
            ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=7, ncol=2)
    fig.tight_layout()
    save(fig, out, "error_vs_n.svg")


def plot_error_vs_noise(rows, out, n):
    grid = pick(rows, series="grid", n=n, k=50)
    if not grid:
        return
    ss = shapes(grid)
    panels = [
        ("sigma_p = sigma_n", lambda s: (s, s)),
        ("position noise only (sigma_n = 0)", lambda s: (s, 0.0)),
        ("normal noise only (sigma_p = 0)", lambda s: (0.0, s)),
    ]
    fig, axes = plt.subplots(len(ss), 3, figsize=(12, 3.4 * len(ss)), squeeze=False)
    for si, shape in enumerate(ss):
        for pi, (title, levels) in enumerate(panels):
            ax = axes[si][pi]
            for est in estimators(grid):
                pts = []
                for s in (0.0, 0.1, 0.2):
                    sp, sn = levels(s)
                    r = one(grid, shape=shape, estimator=est, sigma_p=sp, sigma_n=sn)
                    if r:
                        pts.append((s, 1e3 * r["h_rms"]))
                if pts:
                    ax.plot(*zip(*pts), label=est, **style(est))
            ax.set_yscale("log")
            ax.set_xticks([0.0, 0.1, 0.2])
            ax.set_title(f"{shape} N={n // 1000}k: RMS H (1e-3), {title}", fontsize=8)
            ax.set_xlabel("sigma")
            ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=7, ncol=2)
    fig.tight_layout()
    save(fig, out, "error_vs_noise.svg")


def time_stats(rows):
    """Median us/point of each estimator over the K = 50 i.i.d. grid, and of the k-NN."""
    grid = pick(rows, series="grid", k=50)
    est = {e: statistics.median(r["us_per_point"] for r in pick(grid, estimator=e))
           for e in estimators(grid)}
    knn = {}
    for r in grid:
        knn[(r["shape"], r["n"], r["sigma_p"], r["sigma_n"])] = r["knn_us_per_point"]
    return est, (statistics.median(knn.values()) if knn else float("nan"))


def plot_time(rows, out):
    est, knn = time_stats(rows)
    if not est:
        return
    names = list(est)
    fig, ax = plt.subplots(figsize=(7, 3.6))
    ax.barh(names, [est[e] for e in names], color=[style(e)["color"] for e in names])
    ax.axvline(knn, color="k", linestyle=":", label=f"k-NN (knn_brute, K=50): {knn:.1f} us")
    for i, e in enumerate(names):
        ax.text(est[e] * 1.1, i, f"{est[e]:.2f}", va="center", fontsize=7)
    ax.set_xscale("log")
    ax.invert_yaxis()
    ax.set_xlabel("us per point, curvature step only, one thread (median over the K=50 grid)")
    ax.set_xlim(right=max(est.values()) * 5)
    ax.legend(fontsize=7, loc="upper right")
    ax.grid(True, axis="x", which="both", alpha=0.3)
    fig.tight_layout()
    save(fig, out, "time_per_point.svg")


def plot_window(rows, out):
    win = pick(rows, series="window")
    if not win:
        return
    n = win[0]["n"]
    levels = sorted({(r["sigma_p"], r["sigma_n"]) for r in win})
    ss = shapes(win)
    fig, axes = plt.subplots(len(ss), len(levels), figsize=(3.2 * len(levels), 3.2 * len(ss)),
                             squeeze=False)
    for si, shape in enumerate(ss):
        for li, (sp, sn) in enumerate(levels):
            ax = axes[si][li]
            base = pick(rows, series="grid", shape=shape, n=n, sigma_p=sp, sigma_n=sn, k=50)
            for est in estimators(win):
                pts = sorted((r["k"], 1e3 * r["h_rms"])
                             for r in pick(win + base, shape=shape, estimator=est,
                                           sigma_p=sp, sigma_n=sn))
                if pts:
                    ax.plot(*zip(*pts), label=est, **style(est))
            ax.set_yscale("log")
            ax.set_xticks([50, 100, 200])
            ax.set_title(f"{shape} N={n // 1000}k sigma=({sp}, {sn})", fontsize=8)
            ax.set_xlabel("K")
            ax.set_ylabel("RMS H (1e-3)")
            ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    save(fig, out, "window.svg")


def fmt(x):
    if x is None or math.isnan(x):
        return "-"
    return f"{x:.3g}" if x < 100 else f"{x:.0f}"


def summary_table(rows, n, sp, sn, series="grid"):
    lines = []
    for shape in shapes(rows):
        sel = pick(rows, series=series, shape=shape, n=n, sigma_p=sp, sigma_n=sn, k=50)
        if not sel:
            continue
        lines.append(f"**{shape}, N = {n}, sigma_p = {sp}, sigma_n = {sn}, K = 50** "
                     "(errors in 1e-3; * = on a subset of points)\n")
        lines.append("| estimator | H rms | H max | K rms | K max | k1 rms | k1 max | k2 rms | "
                     "k2 max | d1 rms (deg) | us/pt | points |")
        lines.append("|---|" + "---:|" * 11)
        for est in estimators(sel):
            r = one(sel, estimator=est)
            cells = [fmt(1e3 * r[f"{q}_{m}"]) for q in QUANTITIES for m in ("rms", "max")]
            star = "*" if est in SLOW else ""
            lines.append(f"| {est} | " + " | ".join(cells) +
                         f" | {fmt(r['d1_rms_deg'] or math.nan)} | {r['us_per_point']:.2f} | "
                         f"{r['evaluated']}{star} |")
        knn = sel[0]["knn_us_per_point"]
        lines.append(f"\nk-NN (knn_brute, K = 50): {knn:.2f} us/point.\n")
    return "\n".join(lines)


def mean_table(rows, series, title):
    """Mean over the clouds of a series (the paper's average over N and noise) of RMS H."""
    sel = pick(rows, series=series, k=50)
    if not sel:
        return ""
    ss = shapes(sel)
    out = [f"{title}\n", "| estimator | " + " | ".join(
        f"{s}: mean RMS H | {s}: best CNC in" for s in ss) + " |",
        "|---|" + "---:|---:|" * len(ss)]
    cnc = [e for e in estimators(sel) if e.startswith("cnc")]
    for est in estimators(sel):
        cells = []
        for s in ss:
            mine = pick(sel, shape=s, estimator=est)
            cells.append(fmt(1e3 * statistics.mean(r["h_rms"] for r in mine)) if mine else "-")
            if est in cnc:
                clouds = {(r["n"], r["sigma_p"], r["sigma_n"]) for r in mine}
                wins = 0
                for c in clouds:
                    rs = [r for r in pick(sel, shape=s, n=c[0], sigma_p=c[1], sigma_n=c[2])
                          if r["estimator"] in cnc]
                    if min(rs, key=lambda r: r["h_rms"])["estimator"] == est:
                        wins += 1
                cells.append(f"{wins}/{len(clouds)}")
            else:
                cells.append("")
        out.append(f"| {est} | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


def noise_table(rows, n):
    """RMS H at each noise level, N = n: the robustness comparison."""
    grid = pick(rows, series="grid", n=n, k=50)
    if not grid:
        return ""
    levels = sorted({(r["sigma_p"], r["sigma_n"]) for r in grid})
    out = []
    for shape in shapes(grid):
        out.append(f"**{shape}, N = {n}, K = 50: RMS H (1e-3) by noise (sigma_p, sigma_n)**\n")
        out.append("| estimator | " + " | ".join(f"({a}, {b})" for a, b in levels) + " |")
        out.append("|---|" + "---:|" * len(levels))
        for est in estimators(grid):
            cells = []
            for sp, sn in levels:
                r = one(grid, shape=shape, estimator=est, sigma_p=sp, sigma_n=sn)
                cells.append(fmt(1e3 * r["h_rms"]) if r else "-")
            out.append(f"| {est} | " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out)


def window_table(rows):
    win = pick(rows, series="window")
    if not win:
        return ""
    n = win[0]["n"]
    levels = sorted({(r["sigma_p"], r["sigma_n"]) for r in win})
    out = []
    for shape in shapes(win):
        out.append(f"**{shape}, N = {n}: RMS H (1e-3) by K, at each noise (sigma_p, sigma_n)**\n")
        head = [f"({a}, {b}) K={k}" for a, b in levels for k in (50, 100, 200)]
        out.append("| estimator | " + " | ".join(head) + " |")
        out.append("|---|" + "---:|" * len(head))
        for est in estimators(win):
            cells = []
            for sp, sn in levels:
                for k in (50, 100, 200):
                    series = "grid" if k == 50 else "window"
                    r = one(rows, series=series, shape=shape, n=n, sigma_p=sp, sigma_n=sn,
                            k=k, estimator=est)
                    cells.append(fmt(1e3 * r["h_rms"]) if r else "-")
            out.append(f"| {est} | " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out)


def time_table(rows):
    est, knn = time_stats(rows)
    if not est:
        return ""
    out = ["| estimator | median us/point | min | max |", "|---|---:|---:|---:|"]
    grid = pick(rows, series="grid", k=50)
    for e, med in est.items():
        ts = [r["us_per_point"] for r in pick(grid, estimator=e)]
        out.append(f"| {e} | {med:.2f} | {min(ts):.2f} | {max(ts):.2f} |")
    ks = [r["knn_us_per_point"] for r in grid]
    out.append(f"| k-NN (knn_brute) | {knn:.2f} | {min(ks):.2f} | {max(ks):.2f} |")
    return "\n".join(out) + "\n"


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "docs/study"
    rows = load(os.path.join(out, "results.csv"))
    ns = sorted({r["n"] for r in pick(rows, series="grid")})
    n_table = 50_000 if 50_000 in ns else (ns[-1] if ns else 0)
    plot_error_vs_n(rows, out)
    plot_error_vs_noise(rows, out, n_table)
    plot_time(rows, out)
    plot_window(rows, out)
    parts = [
        "# Study tables (generated by scripts/study_plots.py)\n",
        "## Summary, no noise\n", summary_table(rows, n_table, 0.0, 0.0),
        "## Summary, sigma 0.1 / 0.1\n", summary_table(rows, n_table, 0.1, 0.1),
        "## Mean over the i.i.d. grid\n",
        mean_table(rows, "grid", "Mean over every N and noise level of the i.i.d. grid "
                   "(RMS H, 1e-3); 'best CNC in' counts the clouds where the variant has the "
                   "lowest RMS H among the CNC variants."),
        "## Mean over the Lloyd clouds\n",
        mean_table(rows, "lloyd", "Same over the reference Lloyd clouds (10k-75k, noise 0 "
                   "and 0.1/0.1)."),
        "## Noise\n", noise_table(rows, n_table),
        "## Large window\n", window_table(rows),
        "## Time\n", time_table(rows),
    ]
    with open(os.path.join(out, "summary.md"), "w") as f:
        f.write("\n".join(p for p in parts if p) + "\n")


if __name__ == "__main__":
    main()
