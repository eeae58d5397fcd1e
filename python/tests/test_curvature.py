"""tilecurv.curvature against the command line: the same values bit for bit, for a float
array (against `process --f64` on a double-precision PLY of it) and for a laspy LasData
(against `process --f64` on its LAS or LAZ file), for every estimator, -k auto and --radius."""

import mmap

import numpy as np
import pytest

import tilecurv
MAP_NORESERVE = getattr(mmap, "MAP_NORESERVE", 0x4000)

from conftest import assert_bit_identical, cli_columns, laspy, write_ply

ESTIMATORS = [
    "cnc-avg-hexagram",
    "cnc-hexagram",
    "cnc-uniform",
    "cnc-delaunay",
    "apss",
    "aso",
    "wme",
    "jet",
    "vcm",
]
ALL = "normals,H,K,k1,k2,directions,flags"


def columns_for(kw):
    """ALL, without the directions for APSS, whose sphere has none (refused with it)."""
    return ALL.replace(",directions", "") if kw.get("estimator") == "apss" else ALL


# (keyword options, the same as command-line flags)
CASES = [({"estimator": e}, ["--estimator", e]) for e in ESTIMATORS] + [
    ({"estimator": "vcm", "features": True}, ["--estimator", "vcm", "--features"]),
    ({"k": "auto"}, ["-k", "auto"]),
    ({"radius": "5m"}, ["--radius", "5m"]),
    ({"radius": 12.5, "k": 40}, ["--radius", "12.5", "-k", "40"]),
    ({"orient": "propagate", "k": 20}, ["--orient", "propagate", "-k", "20"]),
    ({"orient": "outward", "tile": "30m"}, ["--orient", "outward", "--tile", "30m"]),
]
IDS = ["-".join(f"{k}={v}" for k, v in kw.items()) for kw, _ in CASES]


class Window:
    """The `n` points of the sample nearest its middle (Chebyshev distance in x, y) as a LAS
    file (the sample's header: scale, offset, CRS), its LasData, its coordinates and a
    double-precision PLY of them."""

    def __init__(self, sample, n, folder):
        full = laspy.read(sample)
        x, y = np.asarray(full.x), np.asarray(full.y)
        d = np.maximum(abs(x - np.median(x)), abs(y - np.median(y)))
        keep = d < np.sort(d)[n]
        self.path = folder / f"window{n}.las"
        sub = laspy.LasData(full.header)
        sub.points = full.points[keep]
        sub.write(self.path)
        self.las = laspy.read(self.path)
        self.xyz = np.stack([self.las.x, self.las.y, self.las.z], axis=1)
        self.ply = folder / f"window{n}.ply"
        write_ply(self.ply, self.xyz)


@pytest.fixture(scope="module")
def window(sample, tmp_path_factory):
    made = {}

    def get(n):
        if n not in made:
            made[n] = Window(sample, n, tmp_path_factory.mktemp(f"w{n}"))
        return made[n]

    return get


def points_for(kw):
    # The VCM takes about 1.4 ms of CPU a point (its Voronoi cells): a smaller window.
    return 800 if kw.get("estimator") == "vcm" else 3000


@pytest.fixture(scope="module")
def las(sample):
    return laspy.read(sample)


@pytest.fixture(scope="module")
def xyz(las):
    return np.stack([las.x, las.y, las.z], axis=1)


def _names(got):
    return [n for n in got]


@pytest.mark.parametrize("kw,flags", CASES, ids=IDS)
def test_array_is_bit_identical_to_process_on_a_ply(cli, tmp_path, window, kw, flags):
    w = window(points_for(kw))
    got = tilecurv.curvature(w.xyz, columns=columns_for(kw), threads=2, **kw)
    assert len(got["H"]) == len(w.xyz)
    want = cli_columns(cli, tmp_path, w.ply, ["--columns", columns_for(kw), "--ply-las-names", *flags], _names(got))
    assert_bit_identical(got, want, kw)
    # A real computation: most points are defined, and the values vary.
    defined = (got["CurvatureFlags"] & 7) == 0
    assert defined.mean() > 0.5 and np.nanstd(got["H"]) > 0


@pytest.mark.parametrize("kw,flags", CASES, ids=IDS)
def test_lasdata_is_bit_identical_to_process_on_its_file(cli, tmp_path, window, kw, flags):
    w = window(points_for(kw))
    got = tilecurv.curvature(w.las, columns=columns_for(kw), threads=2, **kw)
    want = cli_columns(cli, tmp_path, w.path, ["--columns", columns_for(kw), *flags], _names(got))
    assert_bit_identical(got, want, kw)


@pytest.fixture(scope="module")
def noisy_laz(tmp_path_factory, window):
    """The sample as LAZ with another offset, some points of the noise classes 7 and 18 and
    some withheld: the class filter's default and the LAZ route."""
    las = window(3000).las
    out = laspy.LasData(laspy.LasHeader(point_format=6, version="1.4"))
    out.header.scales = las.header.scales
    out.header.offsets = np.array([1999000.0, 201000.0, -5.0])
    out.header.vlrs.extend(las.header.vlrs)  # the GeoTIFF keys: the CRS and its unit
    out.x, out.y, out.z = las.x, las.y, las.z
    cls = np.zeros(len(las.x), dtype=np.uint8)
    cls[::37] = 7
    cls[5::53] = 18
    cls[11::29] = 2
    out.classification = cls
    out.withheld = (np.arange(len(cls)) % 41) == 3
    p = tmp_path_factory.mktemp("laz") / "noisy.laz"
    out.write(p)
    return p


@pytest.mark.parametrize(
    "kw,flags",
    [
        ({}, []),
        ({"skip_withheld": True, "classes": [0, 2]}, ["--skip-withheld", "--classes", "0,2"]),
        ({"skip_classes": "none", "k": "auto"}, ["--skip-classes", "none", "-k", "auto"]),
    ],
)
def test_laz_with_classes_is_bit_identical(cli, tmp_path, noisy_laz, kw, flags):
    data = laspy.read(noisy_laz)
    got = tilecurv.curvature(data, columns=ALL, **kw)
    want = cli_columns(cli, tmp_path, noisy_laz, ["--columns", ALL, *flags], _names(got))
    assert_bit_identical(got, want, kw)
    skipped = got["CurvatureFlags"] & 128 != 0
    if not kw:
        assert np.array_equal(skipped, np.isin(np.asarray(data.classification), [7, 18]))


def test_pdal_structured_array(xyz):
    """A structured array as PDAL's Python bindings return it (X, Y, Z as float64 among other
    dimensions) is read in place and gives the (n, 3) array's values."""
    n = len(xyz)
    dt = np.dtype(
        [("X", "<f8"), ("Y", "<f8"), ("Z", "<f8"), ("Intensity", "<u2"), ("ReturnNumber", "u1"),
         ("NumberOfReturns", "u1"), ("Classification", "u1"), ("GpsTime", "<f8")]
    )
    arr = np.zeros(n, dtype=dt)
    arr["X"], arr["Y"], arr["Z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    arr["Intensity"] = np.arange(n) % 65535
    arr["Classification"] = 7  # no class filter on arrays: PDAL's classes are its own business
    plain = tilecurv.curvature(xyz, k=25)
    structured = tilecurv.curvature(arr, k=25)
    assert_bit_identical(structured, plain, "structured")
    # Read in place: the view's fields are the array's bytes, nothing to copy.
    assert arr.flags.c_contiguous and arr.dtype.fields["X"][0] == np.dtype("<f8")



def test_input_order_is_kept(xyz):
    """The result of a point is the same whatever the order of the input (the results depend
    on the point set), and comes back at the point's place."""
    perm = np.random.default_rng(3).permutation(len(xyz))
    a = tilecurv.curvature(xyz, columns="H,K,k1,flags")
    b = tilecurv.curvature(xyz[perm], columns="H,K,k1,flags")
    for name in a:
        assert np.array_equal(a[name][perm], b[name], equal_nan=True), name


def test_flag_columns_are_uint8(xyz):
    """Every flag column comes back as uint8, as the files store it; TerrainFlags bit 2 (no
    curvature) marks exactly the points whose curvature is undefined (CurvatureFlags 1, 2, 4
    or 128)."""
    got = tilecurv.curvature(xyz[:3000], columns="H,flags,slope", k=20)
    assert got["CurvatureFlags"].dtype == np.uint8 and got["TerrainFlags"].dtype == np.uint8
    undefined = (got["CurvatureFlags"] & (1 | 2 | 4 | 128)) != 0
    assert undefined.any() and not undefined.all()
    assert np.array_equal((got["TerrainFlags"] & 2) != 0, undefined)


def test_normals_are_used_as_file_normals(xyz):
    """Given normals flag the points FILE_NORMAL (32), and a sphere with its exact outward
    normals has H = 1/r: checked against the closed form."""
    rng = np.random.default_rng(7)
    v = rng.normal(size=(20000, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    r = 4.0
    got = tilecurv.curvature(v * r, normals=v, columns="H,K,flags")
    assert np.all(got["CurvatureFlags"] & 32)
    assert abs(np.median(got["H"]) - 1 / r) < 0.02 / r
    assert abs(np.median(got["K"]) - 1 / r**2) < 0.05 / r**2


def test_bad_arguments_raise_usage_errors(xyz):
    with pytest.raises(tilecurv.UsageError, match="-k 3 is too small"):
        tilecurv.curvature(xyz, k=3)
    with pytest.raises(tilecurv.UsageError, match="unknown option 'kk'"):
        tilecurv.curvature(xyz, kk=3)
    with pytest.raises(tilecurv.UsageError, match="f64 is about output files"):
        tilecurv.curvature(xyz, f64=True)
    with pytest.raises(tilecurv.UsageError, match=r"\(n, 3\)"):
        tilecurv.curvature(xyz[:, :2])
    with pytest.raises(tilecurv.UsageError, match="unknown estimator"):
        tilecurv.curvature(xyz, estimator="nope")
    with pytest.raises(tilecurv.UsageError, match="no LAS classes"):
        tilecurv.curvature(xyz, classes=[2])
    with pytest.raises(tilecurv.UsageError, match="X, Y and Z"):
        tilecurv.curvature(np.zeros(4, dtype=[("a", "f8")]))
    assert issubclass(tilecurv.UsageError, tilecurv.TilecurvError)


def test_columns_that_do_not_fit_raise_instead_of_aborting():
    """An input whose result columns cannot be allocated raises OutputError (a limit of the
    machine: exit 4 on the command line) with the sizes, before any work, not an abort. The
    input is 2^35 points (768 GiB) of a mapping that reserves no memory, read in place."""
    n = 1 << 35
    m = mmap.mmap(-1, n * 24, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS | MAP_NORESERVE)
    huge = np.frombuffer(m, dtype="<f8").reshape(n, 3)
    with pytest.raises(tilecurv.OutputError, match="cannot allocate .* MiB for the column H"):
        tilecurv.curvature(huge)
    del huge
    m.close()


def test_offsets_by_whole_steps_give_the_same_bits(window, tmp_path):
    """The same points stored with offsets that differ by whole steps (another writer's
    choice) give the same values bit for bit: laspy's integers go through the LAS reader's
    grid (core::grid), not a formula of their own."""
    las = window(3000).las
    moved = laspy.LasData(laspy.LasHeader(point_format=las.header.point_format.id, version="1.2"))
    moved.header.scales = las.header.scales
    moved.header.offsets = las.header.offsets + np.array([-1234.56, 987.0, 3.21])
    moved.header.vlrs.extend(las.header.vlrs)
    for dim in ("X", "Y", "Z"):
        step = las.header.scales["XYZ".index(dim)]
        shift = (moved.header.offsets - las.header.offsets)["XYZ".index(dim)] / step
        moved[dim] = np.asarray(las[dim], dtype=np.int64) - int(round(shift))
    assert not np.array_equal(np.asarray(moved.X), np.asarray(las.X))
    a = tilecurv.curvature(las, columns=ALL)
    b = tilecurv.curvature(moved, columns=ALL)
    assert_bit_identical(b, a, "moved offsets")


def test_file_normals_of_a_lasdata_are_used_as_the_file_route_uses_them(cli, tmp_path):
    """A LAS file with NormalX/Y/Z (a sphere's outward normals as f64 extra dimensions): the
    LasData's normals are the file's, as process uses them (flag 32, same bits)."""
    rng = np.random.default_rng(11)
    v = rng.normal(size=(3000, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    las = laspy.LasData(laspy.LasHeader(point_format=0, version="1.4"))
    las.header.scales = [1e-4] * 3
    las.header.offsets = [0.0] * 3
    las.x, las.y, las.z = (5 * v).T
    las.add_extra_dims([laspy.ExtraBytesParams(n, type=np.float64) for n in ("NormalX", "NormalY", "NormalZ")])
    las.NormalX, las.NormalY, las.NormalZ = v.T
    path = tmp_path / "sphere.las"
    las.write(path)
    got = tilecurv.curvature(laspy.read(path), columns="H,K,k1,k2,flags")
    assert np.all(got["CurvatureFlags"] & 32)
    want = cli_columns(cli, tmp_path, path, ["--columns", "H,K,k1,k2,flags"], list(got))
    assert_bit_identical(got, want, "file normals")


def test_a_tilecurv_output_is_computed_as_a_rerun_on_it(cli, tmp_path, window):
    """A tilecurv output's own NormalX/Y/Z are its output, not file normals: the LasData of an
    output gives what process gives on that output (a re-run), PCA normals."""
    out = tmp_path / "first.las"
    from conftest import run_cli

    run_cli(cli, "process", window(3000).path, "-o", out, "--quiet", "--columns", "normals,H,flags")
    got = tilecurv.curvature(laspy.read(out), columns="normals,H,K,flags", estimator="jet")
    assert not np.any(got["CurvatureFlags"] & 32)
    want = cli_columns(cli, tmp_path, out, ["--columns", "normals,H,K,flags", "--estimator", "jet"], list(got))
    assert_bit_identical(got, want, "re-run")


def test_directions_of_apss_are_refused(window):
    """APSS fits a sphere: it has no principal directions, so asking for them is a usage error
    (exit 2 on the command line), as it is for options an estimator does not use."""
    w = window(3000)
    with pytest.raises(tilecurv.UsageError, match="no principal directions"):
        tilecurv.curvature(w.xyz, columns=ALL, estimator="apss")
    with pytest.raises(tilecurv.UsageError, match="sets --estimator jet"):
        tilecurv.curvature(w.xyz, jet_degree=3)
