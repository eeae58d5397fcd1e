"""split_las.py IN.las OUTDIR N: split a LAS file into N files of west-to-east strips of equal point
count (the way a survey is delivered as adjacent tiles), keeping the header's scales, offsets and
VLRs. For the cluster benchmark: several input files are one scene to tilecurv."""
import sys

import laspy
import numpy as np


def main():
    src, outdir, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
    las = laspy.read(src)
    order = np.argsort(las.x, kind="stable")
    for i, part in enumerate(np.array_split(order, n)):
        out = laspy.LasData(las.header)
        out.points = las.points[np.sort(part)]
        out.write(f"{outdir}/part{i}.las")


if __name__ == "__main__":
    main()
