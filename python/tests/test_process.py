"""tilecurv.process, info, the exceptions, Ctrl-C and the `tilecurv` console script, against the
standalone binary: the same bytes, events, messages and exit codes."""

import json
import os
import pathlib
import signal
import subprocess
import sys
import time

import pytest

import tilecurv
from conftest import run_cli

VENV_BIN = pathlib.Path(sys.executable).parent


def events_of(path):
    return [json.loads(line) for line in pathlib.Path(path).read_text().splitlines()]


def shape(events):
    """The phases and events, without the progress steps between them (their count follows
    the timing of the tiles)."""
    return [(e["event"], e.get("phase")) for e in events if e["event"] != "progress"]


@pytest.mark.parametrize(
    "kw,flags,ext",
    [
        ({}, [], "las"),
        (
            {"columns": ["normals", "H", "K", "k1", "k2", "flags"], "estimator": "jet", "k": 20},
            ["--columns", "normals,H,K,k1,k2,flags", "--estimator", "jet", "-k", "20"],
            "laz",
        ),
    ],
)
def test_process_writes_the_command_lines_bytes_and_events(cli, sample, tmp_path, kw, flags, ext):
    a, b = tmp_path / f"cli.{ext}", tmp_path / f"py.{ext}"
    run_cli(cli, "process", sample, "-o", a, "--quiet", "--progress-json", tmp_path / "ev.jsonl", *flags)
    got = []
    summary = tilecurv.process(sample, b, progress=got.append, quiet=True, threads=1, **kw)
    assert a.read_bytes() == b.read_bytes()
    want = events_of(tmp_path / "ev.jsonl")
    assert shape(got) == shape(want)
    assert [e["phase"] for e in got if e["event"] == "phase_start"] == ["scan", "curvature", "write"]
    for e in got:
        if e["event"] == "phase_end":
            assert e["done"] == e["total"] == 21932
    last = got[-1]
    assert last["event"] == "summary" and last["points"] == summary["points"] == 21932
    assert last["undefined"] == summary["undefined"] == want[-1]["undefined"]
    assert summary["outputs"] == [b]
    assert not (tmp_path / f".py.{ext}.tilecurv").exists(), "the work directory is removed"


def test_an_interrupted_process_keeps_its_work_and_resumes_to_the_same_bytes(cli, tmp_path):
    """A callback that raises stops the run like Ctrl-C: the exception comes back, no output,
    the work directory is kept beside the output; the same call resumes from the finished tiles
    and writes the bytes of an uninterrupted run."""
    terrain = tmp_path / "terrain.laz"
    run_cli(cli, "generate", "terrain", "-o", terrain, "--points", "150k")
    full = tmp_path / "full.laz"
    run_cli(cli, "process", terrain, "-o", full, "--quiet", "-k", "auto", "--tile", "40m")

    class Stop(Exception):
        pass

    def stop_in_curvature(e):
        if e["event"] == "progress" and e["phase"] == "curvature" and e["done"] > 0:
            raise Stop()

    out = tmp_path / "py.laz"
    opts = dict(k="auto", tile="40m", quiet=True, threads=2)
    with pytest.raises(Stop):
        tilecurv.process(terrain, out, progress=stop_in_curvature, **opts)
    assert not out.exists()
    assert (tmp_path / ".py.laz.tilecurv").is_dir()
    summary = tilecurv.process(terrain, out, **opts)
    assert summary["tiles_resumed"] > 0
    assert out.read_bytes() == full.read_bytes()


def test_info_is_what_info_json_prints(cli, sample):
    want = json.loads(run_cli(cli, "info", "--json", sample).stdout)
    assert tilecurv.info(sample) == want[0]
    assert tilecurv.info([sample, sample]) == want * 2
    assert want[0]["points"] == 21932


@pytest.mark.parametrize(
    "args,call,cls,code",
    [
        (["-k", "3"], lambda s, o: tilecurv.process(s, o, k=3), tilecurv.UsageError, 2),
        (
            ["--f32", "--f64"],
            lambda s, o: tilecurv.process(s, o, f32=True, f64=True),
            tilecurv.UsageError,
            2,
        ),
        (None, lambda s, o: tilecurv.process("/nonexistent/in.las", o), tilecurv.BadInputError, 3),
        ("notadir", lambda s, o: tilecurv.process(s, o), tilecurv.OutputError, 4),
    ],
)
def test_errors_raise_the_exit_classes_with_the_command_lines_messages(
    cli, sample, tmp_path, args, call, cls, code
):
    out = tmp_path / "out.las"
    inp = sample
    if args is None:
        inp, args = "/nonexistent/in.las", []
    elif args == "notadir":
        (tmp_path / "file").write_text("x")
        out, args = tmp_path / "file" / "out.las", []
    p = run_cli(cli, "process", inp, "-o", out, "--quiet", *args, check=False)
    assert p.returncode == code
    with pytest.raises(cls) as e:
        call(sample, out)
    assert isinstance(e.value, tilecurv.TilecurvError) and e.value.exit_code == code
    msg = [l for l in p.stderr.splitlines() if l.startswith("tilecurv: error: ")][0]
    assert msg == f"tilecurv: error: {e.value}"


def test_exception_classes():
    for cls, code in [
        (tilecurv.UsageError, 2),
        (tilecurv.BadInputError, 3),
        (tilecurv.OutputError, 4),
        (tilecurv.TasksMissingError, 5),
        (tilecurv.InternalError, 1),
    ]:
        assert issubclass(cls, tilecurv.TilecurvError) and cls.exit_code == code


def test_the_console_script_is_the_command_line(cli, sample, tmp_path):
    script = VENV_BIN / "tilecurv"
    assert script.is_file(), "the wheel installs the tilecurv command"
    for args in (["--version"], ["info", "--json", sample]):
        a = subprocess.run([script, *map(str, args)], capture_output=True, text=True)
        b = run_cli(cli, *args)
        assert (a.returncode, a.stdout) == (0, b.stdout)
    a, b = tmp_path / "script.laz", tmp_path / "cli.laz"
    run_cli(cli, "process", sample, "-o", b, "--quiet", "--columns", "H,k1,k2,flags")
    r = subprocess.run(
        [script, "process", sample, "-o", a, "--quiet", "--columns", "H,k1,k2,flags"],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    assert a.read_bytes() == b.read_bytes()
    bad = subprocess.run([script, "process", sample, "-o", a, "-k", "3"], capture_output=True, text=True)
    want = run_cli(cli, "process", sample, "-o", a, "-k", "3", check=False)
    assert (bad.returncode, bad.stderr) == (2, want.stderr)


CHILD = r"""
import sys, time
import numpy as np
import tilecurv
n = 1_500_000
rng = np.random.default_rng(1)
xy = rng.uniform(0, 400, size=(n, 2))
xyz = np.column_stack([xy, np.sin(xy[:, 0] / 20) * 3 + np.cos(xy[:, 1] / 15) * 2])
print("start", flush=True)
t = time.time()
try:
    tilecurv.curvature(xyz, k="auto", threads=2)
    print("finished", time.time() - t, flush=True)
except KeyboardInterrupt:
    print("interrupted", time.time(), flush=True)
"""


def test_ctrl_c_raises_keyboard_interrupt_within_a_second(tmp_path):
    """SIGINT during a long computation (1.5M points, -k auto: about a minute of CPU) raises
    KeyboardInterrupt within a second of the signal, and the temporary work directory goes."""
    env = dict(os.environ, TMPDIR=str(tmp_path))
    p = subprocess.Popen(
        [sys.executable, "-c", CHILD], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
    )
    assert p.stdout.readline().strip() == "start"
    time.sleep(2.0)
    sent = time.time()
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=60)
    assert out.startswith("interrupted"), (out, err)
    caught = float(out.split()[1])
    assert caught - sent < 1.0, f"KeyboardInterrupt {caught - sent:.2f} s after the signal"
    assert not any(tmp_path.iterdir()), list(tmp_path.iterdir())
