"""Type stubs of tilecurv (written by tilecurv._stubs from the option table)."""

import os
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

__version__: str

class TilecurvError(Exception):
    exit_code: int

class UsageError(TilecurvError): ...
class BadInputError(TilecurvError): ...
class OutputError(TilecurvError): ...
class TasksMissingError(TilecurvError): ...
class InternalError(TilecurvError): ...
class TilecurvWarning(UserWarning): ...

class Option:
    key: str
    flag: str
    default: Optional[str]
    help: str
    switch: bool
    def python_default(self) -> Any: ...

OPTIONS: Dict[str, Option]
CURVATURE_OPTIONS: Tuple[str, ...]

_Path = Union[str, os.PathLike]

def curvature(
    points: Any,
    *,
    normals: Optional[np.ndarray] = None,
    threads: Optional[int] = None,
    memory: Optional[Union[str, int]] = None,
    work_dir: Optional[_Path] = None,
    estimator: str = 'cnc-avg-hexagram',
    k: Union[int, str, None] = None,
    k_range: Union[str, Tuple[int, int], None] = None,
    radius: Union[float, str, None] = None,
    seed: int = 0,
    triangles: int = 100,
    jet_degree: int = 2,
    ignore_file_normals: bool = False,
    orient: str = 'up',
    tile: Union[float, str] = '50m',
    columns: Union[str, Sequence[str]] = 'H,K,flags',
    directions: bool = False,
    features: bool = False,
    classes: Union[str, Sequence[int], None] = None,
    skip_classes: Union[str, Sequence[int]] = '7,18',
    skip_withheld: bool = False,
) -> Dict[str, np.ndarray]: ...

def process(
    inputs: Union[_Path, Sequence[_Path]],
    output: _Path,
    *,
    progress: Optional[Callable[[Dict[str, Any]], None]] = None,
    work_dir: Optional[_Path] = None,
    dry_run: bool = False,
    threads: Optional[int] = None,
    memory: Optional[Union[str, int]] = None,
    quiet: bool = False,
    raster: Optional[Union[str, float]] = None,
    raster_dir: Optional[_Path] = None,
    raster_columns: Optional[Union[str, Sequence[str]]] = None,
    raster_stat: str = 'mean',
    estimator: str = 'cnc-avg-hexagram',
    k: Union[int, str, None] = None,
    k_range: Union[str, Tuple[int, int], None] = None,
    radius: Union[float, str, None] = None,
    seed: int = 0,
    triangles: int = 100,
    jet_degree: int = 2,
    ignore_file_normals: bool = False,
    orient: str = 'up',
    tile: Union[float, str] = '50m',
    columns: Union[str, Sequence[str]] = 'H,K,flags',
    directions: bool = False,
    features: bool = False,
    f32: bool = False,
    f64: bool = False,
    keep_version: bool = False,
    ply_las_names: bool = False,
    classes: Union[str, Sequence[int], None] = None,
    skip_classes: Union[str, Sequence[int]] = '7,18',
    skip_withheld: bool = False,
    sample_faces: Union[int, str, None] = None,
) -> Dict[str, Any]: ...

def raster(
    inputs: Union[_Path, Sequence[_Path]],
    output: _Path,
    *,
    cell: Union[str, float],
    columns: Optional[Union[str, Sequence[str]]] = None,
    stat: str = 'mean',
    memory: Optional[Union[str, int]] = None,
    quiet: bool = True,
) -> Dict[str, Any]: ...

def info(path: Union[_Path, Sequence[_Path]]) -> Any: ...
