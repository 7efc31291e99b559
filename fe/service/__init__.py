"""The model service: one place that turns a model specification and design points into cycles.

* :mod:`fe.service.spec` — ``ModelSpec`` (what a MODEL.toml holds), ``DesignPoint``,
  ``HingeKind`` and the content hashes that key geometries and results;
* :mod:`fe.service.geometry` — CAD → mesh → STEP/.msh/.vtu/PNG files;
* :mod:`fe.service.store` — computed cycles kept by result key, written atomically;
* :mod:`fe.service.runner` — ``ModelService``: each geometry prepared once, every point
  run on it (or read back from the store), failures recorded, duplicates run once.
"""

from fe.service.runner import ModelService, PointRun, Prepared, check_spec, design_points
from fe.service.spec import (
    DesignPoint,
    HingeKind,
    ModelSpec,
    content_hash,
    geometry_key,
    result_key,
    with_clearance,
)
from fe.service.store import ResultStore

__all__ = [
    "DesignPoint",
    "HingeKind",
    "ModelService",
    "ModelSpec",
    "PointRun",
    "Prepared",
    "ResultStore",
    "check_spec",
    "content_hash",
    "design_points",
    "geometry_key",
    "result_key",
    "with_clearance",
]
