"""Shared fixtures: the standalone command-line binary (the independent route the package is
compared with), the shipped sample, and the command-line runs read back with laspy."""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

laspy = pytest.importorskip("laspy") if os.environ.get("CI") != "true" else __import__("laspy")

ROOT = pathlib.Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "data" / "Haystack_Rock.las"


def _binary() -> pathlib.Path:
    """The `tilecurv` binary cargo built: $TILECURV_BIN (scripts/test.sh sets it), else the
    release binary in cargo's target directory."""
    if os.environ.get("TILECURV_BIN"):
        return pathlib.Path(os.environ["TILECURV_BIN"])
    meta = subprocess.run(
        ["cargo", "metadata", "--format-version", "1", "--no-deps"],
        cwd=ROOT,
        check=True,
        capture_output=True,
        text=True,
    )
    return pathlib.Path(json.loads(meta.stdout)["target_directory"]) / "release" / "tilecurv"


@pytest.fixture(scope="session")
def cli() -> pathlib.Path:
    b = _binary()
    if not b.is_file():
        pytest.fail(f"no tilecurv binary at {b}: run `cargo build --release` first")
    return b


@pytest.fixture(scope="session")
def sample() -> pathlib.Path:
    return SAMPLE


def run_cli(cli, *args, check=True):
    """Runs the binary; returns the completed process."""
    p = subprocess.run([str(cli), *map(str, args)], capture_output=True, text=True)
    if check and p.returncode != 0:
        raise AssertionError(f"tilecurv {' '.join(map(str, args))} exited {p.returncode}: {p.stderr}")
    return p


def write_ply(path, xyz):
    """A binary little-endian PLY of x, y, z as doubles: the coordinates bit for bit."""
    xyz = np.ascontiguousarray(xyz, dtype="<f8")
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(xyz)}\n"
        "property double x\nproperty double y\nproperty double z\nend_header\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(xyz.tobytes())


def cli_columns(cli, tmp_path, input_path, flags, names):
    """The columns `names` of `tilecurv process INPUT --f64 FLAGS`, read back with laspy."""
    out = tmp_path / f"cli_{abs(hash((str(input_path), tuple(flags))))}.las"
    run_cli(cli, "process", input_path, "-o", out, "--f64", "--quiet", *flags)
    f = laspy.read(out)
    return {n: np.asarray(f[n]) for n in names}


def assert_bit_identical(got, want, what=""):
    """Every column of `want` in `got` with the same bits (NaN where the other is NaN)."""
    assert set(want) <= set(got), (sorted(got), sorted(want))
    for name, w in want.items():
        g = got[name]
        assert g.shape == w.shape, (what, name, g.shape, w.shape)
        if g.dtype.kind == "f":
            w = w.astype(np.float64)
            nan = np.isnan(w)
            assert np.array_equal(np.isnan(g), nan), (what, name, "NaN at other points")
            diff = g[~nan].view(np.uint64) != w[~nan].view(np.uint64)
            assert not diff.any(), (
                what,
                name,
                f"{diff.sum()} of {len(w)} values differ, first at {np.flatnonzero(diff)[:5]}: "
                f"{g[~nan][diff][:3]} vs {w[~nan][diff][:3]}",
            )
        else:
            assert np.array_equal(g, w.astype(g.dtype)), (what, name)
