"""Reading a model and loading the hinge kinds leave the CAD kernel unloaded (issue 35, item 3).

build123d and OCP take ~2.5 s to import; a rerun that reads every result back, a study's
plan or ``--help`` must not pay for them. They load when a solid is built
(``cad.general.make_general_hinge``, ``cad.bearing.make_bearing_hinge``), and the
parameter dataclasses live apart (``cad.general_params``, ``cad.bearing_geometry``).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[2] / "studies" / "examples"

HEAVY = ("build123d", "OCP", "gmsh", "sklearn", "scipy.stats")

CODE = """
import sys
from fe.kinds import hinge_kind, kind_names
from model.file import read_model
from model.spec import DesignPoint, ModelSpec, result_key
from cad.general_params import GeneralHingeParams
import studies.cli.main

kinds = [hinge_kind(n) for n in kind_names()]
specs = [read_model(p) for p in {files!r}]
specs.append(ModelSpec("general", GeneralHingeParams(clearance_mm=0.1)))
keys = [result_key(s, DesignPoint(300.0)) for s in specs]
studies.cli.main.build_parser()
print(sorted(m for m in {heavy!r} if m in sys.modules))
import importlib.util  # installed, so its absence above means something
print(importlib.util.find_spec("build123d") is not None)
"""


def test_kinds_model_files_and_the_parser_do_not_import_the_cad_kernel() -> None:
    files = [
        str(EXAMPLES / n) for n in ("MODEL.toml", "MODEL_bearing.toml", "MODEL_bearing_fits.toml")
    ]
    code = CODE.format(files=files, heavy=HEAVY)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    loaded, after = out.stdout.strip().splitlines()
    assert loaded == "[]"
    assert after == "True"
