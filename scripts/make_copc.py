#!/usr/bin/env python3
"""Writes a COPC-LAZ test file from a LAS 1.4 file of point format 6, 7 or 8, with copclib.

usage: make_copc.py INPUT.las OUTPUT.copc.laz

All points go into the octree's root node (key 0-0-0-0): a valid, if shallow, COPC file with
the "copc" info VLR and a hierarchy EVLR, which is what tilecurv must not copy to its output.
The point records are copied byte for byte.
"""
import sys

import copclib as copc
import laspy


def main() -> int:
    src, dst = sys.argv[1:3]
    las = laspy.read(src)
    h = las.header
    if h.point_format.id not in (6, 7, 8):
        print(f"{src}: COPC needs point format 6, 7 or 8, not {h.point_format.id}")
        return 1
    cfg = copc.CopcConfigWriter(h.point_format.id, copc.Vector3(*h.scales), copc.Vector3(*h.offsets))
    info = cfg.copc_info
    mins, maxs = h.mins, h.maxs
    info.center_x, info.center_y, info.center_z = [(a + b) / 2 for a, b in zip(mins, maxs)]
    info.halfsize = max(b - a for a, b in zip(mins, maxs)) / 2 + 1
    info.spacing = info.halfsize / 64
    cfg.las_header.min = copc.Vector3(*mins)
    cfg.las_header.max = copc.Vector3(*maxs)
    w = copc.FileWriter(dst, cfg)
    w.AddNode(copc.VoxelKey(0, 0, 0, 0), copc.VectorChar(memoryview(las.points.array.tobytes()).cast("b")))
    w.Close()
    print(f"wrote {dst}: {len(las.points)} points in one COPC node")
    return 0


if __name__ == "__main__":
    sys.exit(main())
