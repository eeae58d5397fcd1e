"""tilecurv: per-point mean, Gaussian and principal curvature of point clouds.

- ``curvature(points, **options)``: the columns of points held in memory (an (n, 3) float64
  array, a structured array with X, Y, Z fields as PDAL hands them out, or a laspy ``LasData``),
  as a dict of numpy arrays keyed by the LAS column names, in the input's order. The values are
  bit for bit those ``tilecurv process --f64`` writes for the same points.
- ``process(inputs, output, **options, progress=callback)``: the command line's run of files
  (same output bytes, same work directory and resume); ``progress`` gets each
  ``--progress-json`` event as a dict.
- ``info(path)``: what ``tilecurv info --json`` prints for the file.

The keyword options are the command line's options that change the output, with the same names
(``k_range`` for ``--k-range``) and defaults; ``OPTIONS`` lists them with their help. Errors raise
subclasses of ``TilecurvError`` named after the command line's exit classes, with its messages.
"""

from __future__ import annotations

import inspect
import json
import os
import warnings
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Union

import numpy as np

from . import _tilecurv
from ._tilecurv import (
    BadInputError,
    InternalError,
    OutputError,
    TasksMissingError,
    TilecurvError,
    UsageError,
    __version__,
)

__all__ = [
    "curvature",
    "process",
    "raster",
    "info",
    "OPTIONS",
    "CURVATURE_OPTIONS",
    "TilecurvError",
    "UsageError",
    "BadInputError",
    "OutputError",
    "TasksMissingError",
    "InternalError",
    "TilecurvWarning",
    "__version__",
]

# The command line's exit code of each class.
TilecurvError.exit_code = 1
InternalError.exit_code = 1
UsageError.exit_code = 2
BadInputError.exit_code = 3
OutputError.exit_code = 4
TasksMissingError.exit_code = 5


class TilecurvWarning(UserWarning):
    """A warning of a run (the command line prints it as ``warning: ...``)."""


class Option:
    """One option that changes the output: a row of the engine's option table."""

    __slots__ = ("key", "flag", "default", "help", "switch")

    def __init__(self, key: str, flag: str, default: Optional[str], help: str, switch: bool):
        self.key, self.flag, self.default, self.help, self.switch = key, flag, default, help, switch

    def python_default(self) -> Any:
        """The default as a Python value: False for a switch, an int for a whole number, the
        text otherwise (None where the option has no default)."""
        if self.switch:
            return False
        if self.default is not None and self.default.isdigit():
            return int(self.default)
        return self.default

    def __repr__(self) -> str:
        return f"Option({self.key!r}, {self.flag!r}, default={self.default!r})"


#: Every option of ``process`` that changes the output, in the table's order.
OPTIONS: Dict[str, Option] = {row[0]: Option(*row) for row in _tilecurv.options()}

# Options about files only: how an output file stores the columns (curvature returns float64
# arrays, as --f64 stores them) and meshes' faces.
_FILE_ONLY = ("f32", "f64", "keep_version", "ply_las_names", "sample_faces")

#: The options ``curvature`` takes: every row but those about files.
CURVATURE_OPTIONS = tuple(k for k in OPTIONS if k not in _FILE_ONLY)

Points = Any  # numpy.ndarray or laspy.LasData


def _text(key: str, value: Any) -> str:
    """An option's value as the command line's text."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (str, os.PathLike)):
        return os.fspath(value)
    if key == "k_range" and isinstance(value, (tuple, list)) and len(value) == 2:
        return f"{value[0]}..{value[1]}"
    if isinstance(value, (list, tuple, set, frozenset)):
        return ",".join(_text(key, v) for v in value)
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    return str(value)


def _names(value: Optional[Union[str, Sequence[str]]]) -> Optional[List[str]]:
    """Column names given as a list or as the command line's comma-separated text."""
    if value is None:
        return None
    if isinstance(value, str):
        return [n.strip() for n in value.split(",")]
    return [str(n) for n in value]


def _amount(key: str, value: Any) -> Optional[str]:
    """A length or a byte count given as text (``"1m"``, ``"4G"``) or as a number (file units,
    bytes), as the command line's text."""
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        return _text(key, value)
    raise UsageError(f"{key}: {value!r} is neither a number nor a text such as \"1m\" or \"4G\"")


def _pairs(options: Dict[str, Any], allowed: Sequence[str], where: str) -> List[tuple]:
    """The ``(key, text)`` pairs of ``options``, refusing keywords that are not ``allowed``."""
    for key in options:
        if key not in allowed:
            hint = (
                f"{key} is about output files: use tilecurv.process"
                if key in OPTIONS
                else f"unknown option {key!r}"
            )
            raise UsageError(f"{where}: {hint}; the options are {', '.join(allowed)}")
    return [(k, _text(k, v)) for k, v in options.items()]


def _field(dtype: np.dtype, names: Sequence[str]) -> Optional[str]:
    return next((n for n in names if n in (dtype.names or ())), None)


def _las_input(las: Any, ignore_normals: bool):
    """A laspy LasData: its point records in place (X, Y, Z as the file's integers with the
    header's scale and offset), point format, VLRs and EVLRs, and NormalX/Y/Z if it has them."""
    arr = las.points.array
    if not arr.flags.c_contiguous:
        arr = np.ascontiguousarray(arr)
    at = [arr.dtype.fields[n][1] for n in ("X", "Y", "Z")]
    scale = [float(v) for v in las.header.scales]
    offset = [float(v) for v in las.header.offsets]
    records = list(las.header.vlrs) + list(getattr(las, "evlrs", None) or [])
    vlrs = [(str(v.user_id), int(v.record_id), bytes(v.record_data_bytes())) for v in records]
    names = set(las.point_format.dimension_names)
    normals = None
    own = _previous_runs_normals([data for user, rid, data in vlrs if (user, rid) == ("tilecurv", 1)])
    if not ignore_normals and not own and {"NormalX", "NormalY", "NormalZ"} <= names:
        normals = np.stack(
            [np.asarray(las[n], dtype=np.float64) for n in ("NormalX", "NormalY", "NormalZ")],
            axis=1,
        )
    spec = ("las", at, scale, offset)
    return arr, spec, (int(las.header.point_format.id), vlrs), normals


def _previous_runs_normals(records: List[bytes]) -> bool:
    """Whether NormalX/Y/Z are a previous tilecurv run's output (its newest `process`
    provenance record lists them, or lists no columns and says its normals were not the
    file's): those are recomputed, as a re-run on the file does, not used as file normals."""
    texts = [r.rstrip(b"\0").decode("utf-8", "replace") for r in records]
    runs = [t for t in texts if t.startswith("tilecurv ") and "\ninputs=" in t]
    if not runs:
        return False
    lines = runs[-1].splitlines()
    listed = [l.split("=", 1)[0][len("column."):] for l in lines if l.startswith("column.")]
    if listed:
        return "NormalX" in listed
    return "normals=file" not in lines


def _array_input(points: Any):
    """An (n, 3) array, a structured array with X, Y, Z (or x, y, z) fields, or a dict of
    arrays with those keys (PDAL filters.python's `ins`): read in place when they are
    little-endian float64 in a C-contiguous array, else copied once into one."""
    if isinstance(points, Mapping):
        # PDAL filters.python's `ins`: one array per dimension.
        names = [next((n for n in (c, c.lower()) if n in points), None) for c in "XYZ"]
        if None in names:
            raise UsageError(
                f"a dict of arrays needs X, Y and Z (PDAL's names) or x, y, z; it has {', '.join(map(str, points))}"
            )
        points = np.stack([np.asarray(points[n], dtype=np.float64) for n in names], axis=1)
    arr = np.asarray(points)
    if arr.dtype.names:
        names = [_field(arr.dtype, (c, c.lower())) for c in "XYZ"]
        if None in names:
            raise UsageError(
                f"a structured array needs X, Y and Z fields (PDAL's names) or x, y, z; it has {', '.join(arr.dtype.names)}"
            )
        f64 = np.dtype("<f8")
        if arr.ndim == 1 and arr.flags.c_contiguous and all(arr.dtype.fields[n][0] == f64 for n in names):
            return arr, ("f64", [arr.dtype.fields[n][1] for n in names], None, None)
        arr = np.stack([np.asarray(arr[n], dtype=np.float64) for n in names], axis=1)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise UsageError(f"points must be an (n, 3) array of x, y, z; got shape {arr.shape}")
    arr = np.ascontiguousarray(arr, dtype="<f8")
    return arr, ("f64", [0, 8, 16], None, None)


def _is_lasdata(points: Any) -> bool:
    header = getattr(points, "header", None)
    return hasattr(points, "points") and hasattr(header, "scales") and hasattr(header, "offsets")


def curvature(
    points: Points,
    *,
    normals: Optional[np.ndarray] = None,
    threads: Optional[int] = None,
    memory: Optional[Union[str, int]] = None,
    work_dir: Optional[Union[str, os.PathLike]] = None,
    **options: Any,
) -> Dict[str, np.ndarray]:
    """The curvature columns of ``points``, as a dict of numpy arrays keyed by the LAS column
    names (``H``, ``K``, ``CurvatureFlags``, and ``NormalX``... ``k1``, ``k2``, ``d1x``... with
    ``columns``), one value per point in the input's order: float64 with NaN where undefined,
    the flags as uint8 (``ScaleK`` uint16).

    ``points``: an (n, 3) float64 array of x, y, z; a structured array with X, Y, Z fields (as
    PDAL's Python bindings and ``filters.python`` hand them out); or a laspy ``LasData`` (its
    integer records with the header's scale and offset, as the file route reads them, its CRS
    for the units of ``tile`` and ``radius`` and for heights in another unit, its
    classification for ``classes``, ``skip_classes`` and ``skip_withheld``, and its NormalX/Y/Z
    if it has them). Float64 arrays and laspy records are read in place, not copied.

    The values are bit for bit those of ``tilecurv process --f64`` on the same points (a
    double-precision PLY of the array, or the LAS/LAZ file of the LasData), whatever
    ``threads`` and ``memory``.

    ``normals``: an (n, 3) array of normals to use as a file's (a point whose normal is not
    finite or zero gets a PCA normal); ``threads``: worker threads (default every core);
    ``memory``: the budget as text (``"2G"``) or in bytes (default half the machine's memory, at
    most 4G);
    ``work_dir``: where the run's temporary work directory goes (default the system's temporary
    directory; removed after the run).

    Memory: the input is read in place; the run holds about 32 bytes a point of buckets while
    they fit 2/5 of ``memory`` (then they go to the work directory), the tiles in flight within
    the budget, and the result arrays, 8 bytes a point a float column (1 for the flags): about
    57 bytes a point for the default columns H, K and the flags beyond the input. An array
    whose results do not fit raises OutputError before any work.

    Every other keyword is an option of ``process`` with the same name and default
    (``tilecurv.OPTIONS`` has their help): """
    ignore = bool(options.get("ignore_file_normals", False))
    if _is_lasdata(points):
        arr, spec, las, file_normals = _las_input(points, ignore)
        if normals is None:
            normals = file_normals
    else:
        arr, spec = _array_input(points)
        las = None
    if normals is not None:
        normals = np.ascontiguousarray(normals, dtype=np.float64)
        if normals.ndim != 2 or normals.shape[1] != 3:
            raise UsageError(f"normals must be an (n, 3) array; got shape {normals.shape}")
        normals = normals.ravel()
    pairs = _pairs(options, CURVATURE_OPTIONS, "tilecurv.curvature")
    columns, notes = _tilecurv.curvature(
        arr,
        arr.dtype.itemsize if arr.dtype.names else 24,
        spec,
        las,
        normals,
        pairs,
        threads,
        _amount("memory", memory),
        None if work_dir is None else os.fspath(work_dir),
    )
    for note in notes:
        # An array has no CRS: the default tile edge, 50m, is 50 of its units, which changes
        # nothing in the values; say so only when the tile was given.
        if "tile" not in options and "--tile" in note:
            continue
        warnings.warn(note, TilecurvWarning, stacklevel=2)
    return columns


def process(
    inputs: Union[str, os.PathLike, Sequence[Union[str, os.PathLike]]],
    output: Union[str, os.PathLike],
    *,
    progress: Optional[Callable[[Dict[str, Any]], None]] = None,
    work_dir: Optional[Union[str, os.PathLike]] = None,
    dry_run: bool = False,
    threads: Optional[int] = None,
    memory: Optional[Union[str, int]] = None,
    quiet: bool = False,
    raster: Optional[Union[str, float]] = None,
    raster_dir: Optional[Union[str, os.PathLike]] = None,
    raster_columns: Optional[Union[str, Sequence[str]]] = None,
    raster_stat: Optional[str] = None,
    **options: Any,
) -> Dict[str, Any]:
    """``tilecurv process``: the command line's run of the input files into ``output`` (a file
    for one input, a directory for several), the same bytes, work directory and resume.

    ``raster="1m"`` also writes the GeoTIFF rasters and PNG quick looks of ``--raster``
    (``raster_dir``, ``raster_columns``, ``raster_stat`` as ``--raster-dir``,
    ``--raster-columns``, ``--raster-stat``: mean unless named; each needs ``raster``), binned
    as the outputs are written.

    ``progress`` is called with each ``--progress-json`` event as a dict (``phase_start``,
    ``progress``, ``phase_end``, then ``summary``). ``quiet`` keeps only warnings on stderr, as
    ``--quiet`` does. Returns the summary: points, undefined, tiles, tiles_resumed, retried,
    seconds, outputs (a list of pathlib.Path). Ctrl-C raises KeyboardInterrupt and keeps the work directory: the same
    call resumes.

    Every other keyword is an option of the command line with the same name and default
    (``tilecurv.OPTIONS`` has their help): """
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    pairs = _pairs(options, tuple(OPTIONS), "tilecurv.process")

    def on_line(line: str) -> None:
        if progress is not None:
            progress(json.loads(line))

    return _tilecurv.process(
        [os.fspath(i) for i in inputs],
        os.fspath(output),
        pairs,
        None if work_dir is None else os.fspath(work_dir),
        dry_run,
        threads,
        _amount("memory", memory),
        quiet,
        on_line if progress is not None else None,
        (
            _amount("raster", raster),
            None if raster_dir is None else os.fspath(raster_dir),
            _names(raster_columns),
            raster_stat,
        ),
    )


def raster(
    inputs: Union[str, os.PathLike, Sequence[Union[str, os.PathLike]]],
    output: Union[str, os.PathLike],
    *,
    cell: Union[str, float],
    columns: Optional[Union[str, Sequence[str]]] = None,
    stat: str = "mean",
    memory: Optional[Union[str, int]] = None,
    quiet: bool = True,
) -> Dict[str, Any]:
    """``tilecurv raster``: one float32 GeoTIFF per column of the point files ``inputs`` (one
    scene) in the directory ``output``, plus ``PointCount.tif``, each with a PNG quick look.

    ``cell`` is a length with a unit (``"1m"``, ``"3ft"``) or in file units (``"0.5"``, ``0.5``);
    cells are whole multiples of it in the CRS. ``columns`` names the columns, as a list or as
    text (``"H,Slope"``; default: every curvature column the first file holds); ``stat`` is
    ``mean``, ``median``, ``min``, ``max`` or ``count``. Returns files (a list of pathlib.Path), points, cells, width, height and cell
    (in file units)."""
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    return _tilecurv.raster(
        [os.fspath(i) for i in inputs],
        os.fspath(output),
        _amount("cell", cell),
        _names(columns),
        stat,
        _amount("memory", memory),
        quiet,
    )


def info(path: Union[str, os.PathLike, Sequence[Union[str, os.PathLike]]]) -> Any:
    """What ``tilecurv info --json`` prints: for one path, the file's object (format, version,
    point count, bounds, CRS and units, extra dimensions, provenance); for a list of paths, the
    list of them."""
    if isinstance(path, (str, os.PathLike)):
        return json.loads(_tilecurv.info_json([os.fspath(path)]))[0]
    return json.loads(_tilecurv.info_json([os.fspath(p) for p in path]))


def _option_parameters(keys: Sequence[str]) -> List[inspect.Parameter]:
    kw = inspect.Parameter.KEYWORD_ONLY
    return [inspect.Parameter(k, kw, default=OPTIONS[k].python_default()) for k in keys]


def _option_doc(keys: Sequence[str]) -> str:
    lines = []
    for k in keys:
        o = OPTIONS[k]
        first = o.help.split("\n\n")[0]
        lines.append(f"\n    {k} ({o.flag}, default {o.python_default()!r}): {first}")
    return "".join(lines) + "\n"


def _with_options(f: Callable, keys: Sequence[str]) -> None:
    """Gives ``f`` the table's options as keyword parameters in its signature and docstring:
    the one definition of the options stays the engine's table."""
    sig = inspect.signature(f)
    params = [p for p in sig.parameters.values() if p.kind != inspect.Parameter.VAR_KEYWORD]
    f.__signature__ = sig.replace(parameters=params + _option_parameters(keys))
    f.__doc__ = (f.__doc__ or "") + _option_doc(keys)


_with_options(curvature, CURVATURE_OPTIONS)
_with_options(process, tuple(OPTIONS))
