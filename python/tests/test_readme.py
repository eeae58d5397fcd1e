"""The README's Python examples, run as written: the laspy example (its output file's columns
are those of `process --f64`) and the PDAL filters.python function (on the dict of arrays and
the structured array PDAL passes)."""

import os
import pathlib
import re

import numpy as np
import pytest

import tilecurv
from conftest import assert_bit_identical, cli_columns, laspy

README = pathlib.Path(__file__).resolve().parents[2] / "README.md"


def python_blocks():
    text = README.read_text()
    section = text[text.index("\n## Python\n") :]
    section = section[: section.index("\n## ", 5)]
    return re.findall(r"```python\n(.*?)```", section, re.S)


def test_the_laspy_example(cli, sample, tmp_path, monkeypatch):
    example = next(b for b in python_blocks() if "laspy.read" in b)
    laspy.read(sample).write(tmp_path / "scan.laz")
    monkeypatch.chdir(tmp_path)
    exec(compile(example, "README laspy example", "exec"), {})
    written = laspy.read(tmp_path / "scan_curv.laz")
    names = ["NormalX", "NormalY", "NormalZ", "H", "K", "CurvatureFlags"]
    got = {n: np.asarray(written[n]) for n in names}
    want = cli_columns(cli, tmp_path, tmp_path / "scan.laz", ["--columns", "normals,H,K,flags"], names)
    assert_bit_identical(got, want, "README laspy example")


def test_the_pdal_filters_python_function(sample):
    recipe = next(b for b in python_blocks() if b.startswith("# curv.py"))
    scope = {}
    exec(compile(recipe, "curv.py", "exec"), scope)
    las = laspy.read(sample)
    xyz = np.stack([las.x, las.y, las.z], axis=1)
    want = tilecurv.curvature(xyz, k=30)
    # filters.python's `ins`: one array per dimension, PDAL's names.
    ins = {
        "X": np.asarray(las.x), "Y": np.asarray(las.y), "Z": np.asarray(las.z),
        "Intensity": np.asarray(las.intensity), "Classification": np.asarray(las.classification),
    }
    outs = {}
    assert scope["curvature"](ins, outs) is True
    assert_bit_identical(outs, {n: want[n] for n in ("H", "K", "CurvatureFlags")}, "ins dict")
    # A structured array (pipeline.arrays[0] in PDAL's bindings) goes through the same function.
    dt = np.dtype([("X", "<f8"), ("Y", "<f8"), ("Z", "<f8"), ("Intensity", "<u2"), ("Classification", "u1")])
    arr = np.zeros(len(xyz), dtype=dt)
    for name in dt.names:
        arr[name] = ins[name]
    outs = {}
    scope["curvature"](arr, outs)
    assert_bit_identical(outs, {n: want[n] for n in ("H", "K", "CurvatureFlags")}, "structured")
