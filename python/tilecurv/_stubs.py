"""Writes the package's type stubs (``__init__.pyi``) from the engine's option table, so that
the keyword options in the stubs are the table's rows with their defaults. Regenerate with
``python -m tilecurv._stubs > python/tilecurv/__init__.pyi`` after a new option; a test checks
that the stubs in the package are what this writes."""

from typing import Any, Dict

from . import CURVATURE_OPTIONS, OPTIONS

# The Python types an option's value may take (its text form always works too).
_TYPES: Dict[str, str] = {
    "estimator": "str",
    "k": "Union[int, str, None]",
    "k_range": "Union[str, Tuple[int, int], None]",
    "radius": "Union[float, str, None]",
    "seed": "int",
    "triangles": "int",
    "jet_degree": "int",
    "orient": "str",
    "tile": "Union[float, str]",
    "columns": "Union[str, Sequence[str]]",
    "classes": "Union[str, Sequence[int], None]",
    "skip_classes": "Union[str, Sequence[int]]",
    "sample_faces": "Union[int, str, None]",
}

_HEAD = '''"""Type stubs of tilecurv (written by tilecurv._stubs from the option table)."""

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
'''


def _params(keys) -> str:
    out = []
    for k in keys:
        o = OPTIONS[k]
        ty = "bool" if o.switch else _TYPES.get(k, "Any")
        out.append(f"    {k}: {ty} = {o.python_default()!r},\n")
    return "".join(out)


def render() -> str:
    """The stubs' text."""
    return (
        _HEAD
        + "\ndef curvature(\n    points: Any,\n    *,\n"
        + "    normals: Optional[np.ndarray] = None,\n"
        + "    threads: Optional[int] = None,\n"
        + "    memory: Optional[Union[str, int]] = None,\n"
        + "    work_dir: Optional[_Path] = None,\n"
        + _params(CURVATURE_OPTIONS)
        + ") -> Dict[str, np.ndarray]: ...\n"
        + "\ndef process(\n    inputs: Union[_Path, Sequence[_Path]],\n    output: _Path,\n    *,\n"
        + "    progress: Optional[Callable[[Dict[str, Any]], None]] = None,\n"
        + "    work_dir: Optional[_Path] = None,\n"
        + "    dry_run: bool = False,\n"
        + "    threads: Optional[int] = None,\n"
        + "    memory: Optional[Union[str, int]] = None,\n"
        + "    quiet: bool = False,\n"
        + "    raster: Optional[Union[str, float]] = None,\n"
        + "    raster_dir: Optional[_Path] = None,\n"
        + "    raster_columns: Optional[Union[str, Sequence[str]]] = None,\n"
        + "    raster_stat: str = 'mean',\n"
        + _params(OPTIONS)
        + ") -> Dict[str, Any]: ...\n"
        + "\ndef raster(\n    inputs: Union[_Path, Sequence[_Path]],\n    output: _Path,\n    *,\n"
        + "    cell: Union[str, float],\n"
        + "    columns: Optional[Union[str, Sequence[str]]] = None,\n"
        + "    stat: str = 'mean',\n"
        + "    memory: Optional[Union[str, int]] = None,\n"
        + "    quiet: bool = True,\n"
        + ") -> Dict[str, Any]: ...\n"
        + "\ndef info(path: Union[_Path, Sequence[_Path]]) -> Any: ...\n"
    )


if __name__ == "__main__":
    print(render(), end="")
