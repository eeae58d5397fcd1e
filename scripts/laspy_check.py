#!/usr/bin/env python3
"""Independent read-back of a tilecurv output with laspy (lazrs backend).

usage: laspy_check.py INPUT OUTPUT [--f32 | --f64] [--directions]

Checks that OUTPUT has the same point count and the same values in every dimension of INPUT
(standard fields and existing extra bytes), and the new dimensions by name and type: by default
scaled integers (i16 unit vectors at 1/32767, i32 curvatures, each with a scale and the type's
minimum as no-data, held exactly where the flags say undefined), floats with --f32 or --f64.
Exits 0 and prints one line "ok ..." on success; prints what differs and exits 1 otherwise.
"""
import sys

import laspy
import numpy as np


def main() -> int:
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    flags = {a for a in sys.argv[1:] if a.startswith("--")}
    src, out = args
    a = laspy.read(src)
    b = laspy.read(out)
    problems = []
    if len(a.points) != len(b.points):
        problems.append(f"point count {len(b.points)} != {len(a.points)}")
    if a.header.point_format.id != b.header.point_format.id:
        problems.append(f"point format {b.header.point_format.id} != {a.header.point_format.id}")
    for name in a.point_format.dimension_names:
        x, y = np.asarray(a[name]), np.asarray(b[name])
        if x.shape != y.shape or x.tobytes() != y.tobytes():
            problems.append(f"dimension {name} differs")
    floats = {"--f32": np.float32, "--f64": np.float64}
    ftype = next((t for f, t in floats.items() if f in flags), None)
    new = ["NormalX", "NormalY", "NormalZ", "H", "K", "k1", "k2"]
    if "--directions" in flags:
        new += ["d1x", "d1y", "d1z", "d2x", "d2y", "d2z"]
    extra = list(b.point_format.extra_dimension_names)
    for name in new:
        unit = name.startswith("Normal") or name.startswith("d")
        want = ftype or (np.int16 if unit else np.int32)
        if name not in extra:
            problems.append(f"new dimension {name} missing (have {extra})")
        elif b.points.array[name].dtype != want:
            problems.append(f"{name} has type {b.points.array[name].dtype}, expected {want.__name__}")
    if "CurvatureFlags" not in extra or np.asarray(b["CurvatureFlags"]).dtype != np.uint8:
        problems.append("CurvatureFlags missing or not uint8")
    else:
        flags_col = np.asarray(b["CurvatureFlags"])
        undefined = (flags_col & (1 | 2 | 4 | 128)) != 0  # few, normal, estimator, not computed
        raw = b.points.array["H"]
        missing = np.isnan(raw) if ftype else raw == np.iinfo(np.int32).min
        if not np.array_equal(missing, undefined):
            problems.append("H is undefined (NaN or no-data) elsewhere than where the flags say")
    for v in b.header.vlrs:
        if v.user_id == "copc":
            problems.append("a COPC VLR was copied to a non-COPC output")
    if problems:
        print(f"{out}: " + "; ".join(problems))
        return 1
    print(f"ok {out}: {len(b.points)} points, {len(list(a.point_format.dimension_names))} original dimensions equal, new {len(new) + 1} present")
    return 0


if __name__ == "__main__":
    sys.exit(main())
