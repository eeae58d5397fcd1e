"""``tilecurv.raster`` and ``process(raster=...)``: the command line's rasters, byte for byte,
read back by rasterio (GDAL) with their points counted."""

import os
import subprocess

import numpy as np
import pytest

import tilecurv

from conftest import SAMPLE

rasterio = (
    pytest.importorskip("rasterio") if os.environ.get("CI") != "true" else __import__("rasterio")
)


def test_raster_and_process_raster_write_the_command_lines_bytes(cli, tmp_path):
    out = tmp_path / "h.laz"
    r = tilecurv.process(SAMPLE, out, quiet=True, k=20, raster="2m", raster_dir=tmp_path / "py")
    assert r["points"] == 21932
    subprocess.run(
        [cli, "raster", out, "--cell", "2m", "-o", tmp_path / "cli", "-q"], check=True
    )
    again = tilecurv.raster(out, tmp_path / "again", cell="2m")
    assert again["points"] == 21932 and again["cell"] == 2.0
    names = sorted(p.name for p in again["files"])
    assert names == sorted(
        f"{c}.{e}" for c in ("H", "K", "PointCount") for e in ("tif", "png")
    ), names
    for name in ("H.tif", "K.tif", "PointCount.tif"):
        cli_bytes = (tmp_path / "cli" / name).read_bytes()
        assert (tmp_path / "py" / name).read_bytes() == cli_bytes, name
        assert (tmp_path / "again" / name).read_bytes() == cli_bytes, name
    with rasterio.open(tmp_path / "again" / "PointCount.tif") as src:
        counts = src.read(1, masked=True)
        assert counts.sum() == 21932
        assert (src.width, src.height) == (again["width"], again["height"])
        assert np.isclose(src.transform.a, 2.0) and src.transform.c % 2.0 == 0


def test_columns_may_be_text_and_lengths_numbers(cli, tmp_path):
    """``columns="H,K"`` is the list ["H", "K"], as --columns H,K is; a cell of 2.0 is 2 file
    units and a memory of 100000000 is bytes: the command line's bytes."""
    out = tmp_path / "h.laz"
    tilecurv.process(SAMPLE, out, quiet=True, k=20, raster=2.0, raster_columns="H,K",
                     raster_dir=tmp_path / "py", memory=100_000_000)
    subprocess.run([cli, "raster", out, "--cell", "2", "--columns", "H,K", "-o",
                    tmp_path / "cli", "-q"], check=True)
    again = tilecurv.raster(out, tmp_path / "again", cell=2, columns="H, K", memory=1 << 27)
    assert sorted(p.name for p in again["files"] if p.suffix == ".tif") == [
        "H.tif", "K.tif", "PointCount.tif"]
    for name in ("H.tif", "K.tif", "PointCount.tif"):
        cli_bytes = (tmp_path / "cli" / name).read_bytes()
        assert (tmp_path / "py" / name).read_bytes() == cli_bytes, name
        assert (tmp_path / "again" / name).read_bytes() == cli_bytes, name
    with pytest.raises(tilecurv.UsageError, match="neither a number"):
        tilecurv.raster(out, tmp_path / "r", cell=[2])
    with pytest.raises(tilecurv.UsageError, match="at least 1M"):
        tilecurv.raster(out, tmp_path / "r", cell="2m", memory=1024)
    assert not (tmp_path / "r").exists()


def test_raster_errors_are_usage_errors(tmp_path):
    with pytest.raises(tilecurv.UsageError, match="no curvature column"):
        tilecurv.raster(SAMPLE, tmp_path / "r", cell="1m")
    with pytest.raises(tilecurv.UsageError, match="median"):
        tilecurv.raster(SAMPLE, tmp_path / "r", cell="1m", columns=["z"], stat="middle")
    with pytest.raises(tilecurv.UsageError, match="at least one input"):
        tilecurv.raster([], tmp_path / "r", cell="1m", columns=["z"])
    assert not (tmp_path / "r").exists()
    # A raster statistic without a raster would be ignored: refused, as --raster-stat is.
    with pytest.raises(tilecurv.UsageError, match="raster_stat need raster"):
        tilecurv.process(SAMPLE, tmp_path / "o.laz", raster_stat="median")
    assert not (tmp_path / "o.laz").exists()
