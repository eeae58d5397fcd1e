#!/usr/bin/env python3
"""Writes the points of a LAS/LAZ file again with other offsets on the same grid, for the tests
that results do not depend on how a file stores its points.

usage: regrid.py INPUT OUTPUT --steps DX DY DZ [--shuffle SEED] [--format N] [--copc]

The offsets move by whole multiples of the scale (DX, DY, DZ steps), so every point keeps its
position and the stored integers change by -DX, -DY, -DZ. --shuffle permutes the records
(seeded), --format converts the point format with laspy (1 <-> 6 keeps every field the other
has). OUTPUT ending in .laz is compressed (lazrs). --copc writes a COPC-LAZ through
scripts/make_copc.py's writer instead (point format 6, 7 or 8).
"""
import argparse
import os
import subprocess
import sys
import tempfile

import laspy
import numpy as np


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("input")
    ap.add_argument("output")
    ap.add_argument("--steps", type=int, nargs=3, required=True)
    ap.add_argument("--shuffle", type=int)
    ap.add_argument("--format", type=int)
    ap.add_argument("--copc", action="store_true")
    a = ap.parse_args()
    las = laspy.read(a.input)
    if a.format is not None and a.format != las.header.point_format.id:
        las = laspy.convert(las, point_format_id=a.format)
    h = las.header
    steps = np.array(a.steps, dtype=np.int64)
    ints = [np.asarray(las.X, np.int64), np.asarray(las.Y, np.int64), np.asarray(las.Z, np.int64)]
    out = laspy.LasData(laspy.LasHeader(point_format=h.point_format, version=h.version))
    out.header.scales = h.scales
    out.header.offsets = h.offsets + steps * h.scales
    # The point format carries the extra dimensions: laspy writes their VLR from it.
    for vlr in h.vlrs:
        if not (vlr.user_id == "LASF_Spec" and vlr.record_id == 4):
            out.header.vlrs.append(vlr)
    points = las.points.copy()
    if a.shuffle is not None:
        perm = np.random.default_rng(a.shuffle).permutation(len(points))
        points = points[perm]
        ints = [q[perm] for q in ints]
    out.points = points
    for name, q, d in zip("XYZ", ints, steps):
        moved = q - d
        if moved.min() < -(2**31) or moved.max() >= 2**31:
            print(f"{a.input}: {name} shifted by {d} steps leaves the 32-bit range", file=sys.stderr)
            return 1
        setattr(out, name, moved.astype(np.int32))
    out.update_header()
    if not a.copc:
        out.write(a.output)
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        las14 = os.path.join(tmp, "regrid.las")
        out.write(las14)
        here = os.path.dirname(os.path.abspath(__file__))
        return subprocess.run([sys.executable, os.path.join(here, "make_copc.py"), las14, a.output]).returncode


if __name__ == "__main__":
    sys.exit(main())
