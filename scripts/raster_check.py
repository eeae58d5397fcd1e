"""Checks tilecurv's rasters against an independent binning of the point file they came from.

    python3 scripts/raster_check.py POINTS.laz RASTER_DIR --cell C --stat mean --columns H,K

laspy reads the points and their columns (a scaled column's raw type minimum is its declared
no-data value, as tilecurv writes them), numpy bins them into cells of C file units aligned to
multiples of C, and rasterio (GDAL) reads every GeoTIFF: its CRS (compared with GDAL's reading
of the point file's WKT or GeoTIFF keys), transform, no-data value, and each cell against the
binning. Prints one line per raster; exits non-zero on the first mismatch.
"""

import argparse
import sys

import laspy
import numpy as np
import rasterio
from rasterio.crs import CRS


def column(las, name):
    """The column's values as f64, NaN where undefined (NaN, or a scaled column's raw type
    minimum), and whether tilecurv tallies them as integers (an extra dimension of an integer
    type of at most 32 bits, scaled or not)."""
    if name.lower() in ("x", "y", "z"):
        return np.asarray(getattr(las, name.lower()), dtype=np.float64), False
    dim = next(d for d in las.point_format.dimensions if d.name.lower() == name.lower())
    raw = np.asarray(las.points.array[dim.name])
    values = np.asarray(las[dim.name], dtype=np.float64)
    integer = np.issubdtype(raw.dtype, np.integer)
    if integer and dim.scales is not None:
        values[raw == np.iinfo(raw.dtype).min] = np.nan
    extra = dim.name in las.point_format.extra_dimension_names
    return values, extra and integer and raw.dtype.itemsize <= 4


# ProjLinearUnitsGeoKey's EPSG unit codes: metre, foot, US survey foot.
UNIT_METRES = {9001: 1.0, 9002: 0.3048, 9003: 1200 / 3937}


def point_crs(las):
    """GDAL's reading of the point file's CRS (WKT VLR, else GeoTIFF keys via its EPSG code),
    or for user-defined projected keys (code 32767, the parameters in the keys) the metres in
    its linear unit, which the raster's CRS must be projected in."""
    for v in las.header.vlrs + list(las.header.evlrs or []):
        if v.record_id == 2112 and v.user_id == "LASF_Projection":
            # laspy parses the WKT record of LAS 1.4 files; of older ones it keeps the bytes.
            text = getattr(v, "string", None) or bytes(v.record_data).decode("latin-1")
            return CRS.from_wkt(text.rstrip("\0"))
    for v in las.header.vlrs:
        if v.record_id == 34735:
            keys = {k.id: k.value_offset for k in v.geo_keys}
            code = keys.get(3072, keys.get(2048))
            if code == 32767:
                return UNIT_METRES[keys[3076]]
            return None if code is None else CRS.from_epsg(code)
    return None


def check_crs(name, got, expect):
    """The raster's CRS as GDAL reads it against the point file's (point_crs)."""
    if expect is None:
        # No key directory: GDAL reports no CRS, so that a GIS asks for one.
        assert got is None, (name, got)
    elif isinstance(expect, float):
        assert got is not None and got.is_projected, (name, got)
        assert abs(got.linear_units_factor[1] - expect) < 1e-9, (name, got.linear_units_factor)
    elif expect.to_epsg() is None:
        # A WKT without an EPSG code (autzen's Lambert conic in feet): the same projection,
        # parameters and unit as PROJ states them.
        assert got is not None and same_params(got.to_dict(), expect.to_dict()), (
            name, got.to_dict() if got else None, expect.to_dict())
    else:
        assert got is not None and got.to_epsg() == expect.to_epsg(), (name, got, expect.to_epsg())


def same_params(a, b):
    """PROJ parameter dictionaries equal, numbers to 1e-9 relative."""
    def same(x, y):
        if isinstance(x, (int, float)) and isinstance(y, (int, float)):
            return abs(x - y) <= 1e-9 * max(abs(x), abs(y), 1.0)
        return x == y
    return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)


def crs_text(expect):
    """How the report names the expected CRS."""
    if isinstance(expect, float):
        return f"user-defined in units of {expect} m"
    if expect is not None and expect.to_epsg() is None:
        return f"{expect.to_dict().get('proj')} in {expect.to_dict().get('units')}"
    return None if expect is None else expect.to_epsg()


def reduce(stat, values, circular, integers):
    """The cell value of `values` (defined ones only), as tilecurv documents it: the values of
    32-bit floats, but the mean of scaled integers is the mean of the values they stand for."""
    defined = values[~np.isnan(values)]
    v = np.sort(defined.astype(np.float32))
    if stat == "count":
        return float(len(v))
    if len(v) == 0:
        return np.nan
    if stat == "mean" and integers and not circular:
        return float(defined.mean())
    if circular:
        r = np.radians(v.astype(np.float64))
        s, c = np.sin(r).sum(), np.cos(r).sum()
        if np.hypot(s, c) < 1e-9 * len(v):
            return np.nan
        mean = float(np.degrees(np.arctan2(s, c)) % 360.0)
        if stat == "mean":
            return mean
        # Median, min and max of the angles unwrapped to within 180 degrees of their mean.
        start = float(np.float32(mean)) - 180.0
        u = (v.astype(np.float64) - start) % 360.0
        k = np.lexsort((v, u))
        n = len(v)
        if stat == "min":
            x = float(v[k[0]])
        elif stat == "max":
            x = float(v[k[-1]])
        elif n % 2:
            x = float(v[k[n // 2]])
        else:
            x = ((u[k[n // 2 - 1]] + u[k[n // 2]]) / 2 + start) % 360.0
        return x % 360.0
    if stat == "mean":
        return float(v.astype(np.float64).mean())
    if stat == "median":
        n = len(v)
        return float(v[n // 2]) if n % 2 else (float(v[n // 2 - 1]) + float(v[n // 2])) / 2
    return float(v[0] if stat == "min" else v[-1])


def main():
    p = argparse.ArgumentParser()
    p.add_argument("points")
    p.add_argument("rasters")
    p.add_argument("--cell", type=float, required=True)
    p.add_argument("--stat", default="mean")
    p.add_argument("--columns", required=True)
    p.add_argument("--no-crs", action="store_true",
                   help="expect rasters without a CRS (a malformed WKT naming no EPSG code, "
                        "which neither GeoTIFF keys nor GDAL's sidecar can carry)")
    a = p.parse_args()
    las = laspy.read(a.points)
    ix = np.floor(np.asarray(las.x) / a.cell).astype(np.int64)
    iy = np.floor(np.asarray(las.y) / a.cell).astype(np.int64)
    west, north = ix.min(), iy.max()
    width, height = ix.max() - west + 1, north - iy.min() + 1
    rows, cols = north - iy, ix - west
    flat = rows * width + cols
    order = np.argsort(flat, kind="stable")
    cells, starts = np.unique(flat[order], return_index=True)
    ends = np.append(starts[1:], len(order))
    expect_crs = None if a.no_crs else point_crs(las)
    names = a.columns.split(",") + ["PointCount"]
    for name in names:
        with rasterio.open(f"{a.rasters}/{name}.tif") as r:
            t = r.transform
            assert (r.width, r.height) == (width, height), (name, r.width, r.height, width, height)
            assert (t.a, t.e, t.b, t.d) == (a.cell, -a.cell, 0, 0), (name, t)
            assert (t.c, t.f) == (west * a.cell, (north + 1) * a.cell), (name, t, west, north)
            assert r.nodata == float(np.finfo(np.float32).min), (name, r.nodata)
            assert r.dtypes[0] == "float32" and r.compression is not None, (name, r.dtypes)
            check_crs(name, r.crs, expect_crs)
            assert r.descriptions == (name,), (name, r.descriptions)
            grid = r.read(1, masked=True)
        want = np.full(width * height, np.nan)
        if name == "PointCount":
            want[cells] = ends - starts
        else:
            values, integers = column(las, name)
            values = values[order]
            circular = name.lower() == "aspect"
            for c, s, e in zip(cells, starts, ends):
                want[c] = reduce(a.stat, values[s:e], circular, integers)
        want = want.reshape(height, width)
        got = np.where(grid.mask, np.nan, grid.data.astype(np.float64))
        same_nodata = np.isnan(want) == np.isnan(got)
        assert same_nodata.all(), (name, int((~same_nodata).sum()), "cells differ in no-data")
        d = np.isfinite(want)
        want32 = want[d].astype(np.float32).astype(np.float64)
        err = np.abs(got[d] - want32)
        tol = 1e-6 * np.maximum(np.abs(want32), 1e-30)
        if name.lower() == "aspect" and a.stat in ("mean", "median"):
            err = np.minimum(err, 360 - err)
            tol = np.full_like(err, 1e-3)
        bad = err > tol
        assert not bad.any(), (name, int(bad.sum()), float(err.max()))
        print(f"ok {name}: {d.sum()} cells of {width}x{height}, largest difference {err.max():.3g}, "
              f"crs {crs_text(expect_crs)}")


if __name__ == "__main__":
    sys.exit(main())
