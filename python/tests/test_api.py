"""The package's keyword options are the engine's option table: the signatures, the stubs and
the command line's `process --help` all list the same options with the same defaults."""

import inspect
import pathlib
import re

import tilecurv
import tilecurv._stubs
from conftest import run_cli

STUBS = pathlib.Path(__file__).resolve().parents[1] / "tilecurv" / "__init__.pyi"


def test_the_stubs_are_written_from_the_table():
    assert STUBS.read_text() == tilecurv._stubs.render(), (
        "python/tilecurv/__init__.pyi is stale: regenerate it with "
        "`python -m tilecurv._stubs > python/tilecurv/__init__.pyi`"
    )


def test_the_keywords_are_the_command_lines_options(cli):
    """Every option flag of `process --help` that changes the output is a keyword of
    tilecurv.process with the help's default; curvature takes them all but the file-encoding
    ones."""
    help_text = run_cli(cli, "process", "--help").stdout
    for key, o in tilecurv.OPTIONS.items():
        assert re.search(rf"{re.escape(o.flag)}\b", help_text), o.flag
        if o.default is not None:
            assert f"[default: {o.default}]" in help_text, (key, o.default)
    proc = inspect.signature(tilecurv.process).parameters
    curv = inspect.signature(tilecurv.curvature).parameters
    for key, o in tilecurv.OPTIONS.items():
        assert proc[key].default == o.python_default()
        assert (key in curv) == (key not in ("f32", "f64", "keep_version", "ply_las_names", "sample_faces"))
    assert curv["estimator"].default == "cnc-avg-hexagram" and curv["k"].default is None
    assert "k (-k, default None): Neighbours per point" in tilecurv.curvature.__doc__
