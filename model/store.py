"""A content-addressed store of computed cycles: one ``.npz`` file per result key.

A result is written to a temporary file in the same folder and renamed into place
(``os.replace`` is atomic on one file system), so a reader sees either no file or a
complete one: an interrupted write never passes for a finished result. What is kept is
what every consumer of a result needs — the protocol, the increments (the loop, the
works, the energies), the contact state of every increment (forces, relative
displacements, status, rigid amplitudes: enough for the ParaView series) and the
timings — but not the condensed operators, which belong to the geometry.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import tempfile
from pathlib import Path

import numpy as np

from cad.errors import DataError
from fe.contact.state import ContactState
from fe.cycle.protocol import CycleSettings
from fe.cycle.result import CycleResult, Increment

logger = logging.getLogger(__name__)

FORMAT_VERSION = 3
"""3: increments carry the work effects dissipate; 2: their tangent stiffness (older: read as
a miss)."""

_INC_FIELDS = tuple(f.name for f in dataclasses.fields(Increment))


class ResultStore:
    """Cycles by result key in a folder (``<key>.npz``).

    Args:
        root: The folder (created on first write).
    """

    def __init__(self, root: Path) -> None:
        self.root = Path(root)

    def path(self, key: str) -> Path:
        """Where the result with ``key`` lives."""
        return self.root / f"{key}.npz"

    def __contains__(self, key: str) -> bool:
        return self.path(key).is_file()

    def put(self, key: str, result: CycleResult) -> Path:
        """Store ``result`` under ``key`` atomically; return its path."""
        self.root.mkdir(parents=True, exist_ok=True)
        meta = {
            "format": FORMAT_VERSION,
            "key": key,
            "settings": dataclasses.asdict(result.settings),
            "clearance_mm": result.clearance_mm,
            "free_play_mm": result.free_play_mm,
            "timings_s": result.timings_s,
            "slides": list(result.slides),
            "start_disp_mm": result.start_disp_mm,
            "cutbacks": [list(c) for c in result.cutbacks],
        }
        arrays = {
            "meta": np.array(json.dumps(meta)),
            "increments": np.array(
                [[float(getattr(i, f)) for f in _INC_FIELDS] for i in result.increments]
            ).reshape(-1, len(_INC_FIELDS)),
        }
        if result.states:
            arrays["p"] = np.stack([s.p for s in result.states])
            arrays["w"] = np.stack([s.w for s in result.states])
            arrays["status"] = np.stack([s.status for s in result.states])
            arrays["alpha"] = np.stack([s.alpha for s in result.states])
        if result.ball_coordinates is not None:
            arrays["balls"] = np.asarray(result.ball_coordinates)
        if result.preload_state is not None:
            pre = result.preload_state
            arrays |= {"pre_p": pre.p, "pre_w": pre.w, "pre_status": pre.status}
            arrays["pre_alpha"] = pre.alpha
        fd, tmp = tempfile.mkstemp(dir=self.root, prefix=f".{key[:12]}-", suffix=".npz")
        try:
            with os.fdopen(fd, "wb") as fh:
                np.savez(fh, **arrays)  # type: ignore[arg-type]
            os.replace(tmp, self.path(key))
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return self.path(key)

    def get(self, key: str) -> CycleResult | None:
        """Return the stored cycle (without condensed configurations), or None.

        Raises:
            DataError: If the file exists but is not a result of this format.
        """
        path = self.path(key)
        if not path.is_file():
            return None
        try:
            with np.load(path) as z:
                meta = json.loads(str(z["meta"]))
                incs = z["increments"]
                states: tuple[ContactState, ...] = ()
                if "p" in z:
                    states = tuple(
                        ContactState(p, w, st, a)
                        for p, w, st, a in zip(z["p"], z["w"], z["status"], z["alpha"], strict=True)
                    )
                balls = np.asarray(z["balls"]) if "balls" in z else None
                preload = None
                if "pre_p" in z:
                    preload = ContactState(z["pre_p"], z["pre_w"], z["pre_status"], z["pre_alpha"])
        except (OSError, ValueError, KeyError) as err:
            raise DataError(f"{path}: not a readable hingelab result ({err})") from err
        if meta.get("key") != key:
            raise DataError(f"{path}: stored key does not match (delete the file to recompute)")
        if meta.get("format") != FORMAT_VERSION:
            # an older layout (v1 had no tangent stiffness per increment): not an error,
            # the point is recomputed and the file replaced
            logger.info("%s: stored format %s, now %d: recomputing", path, meta.get("format"),
                        FORMAT_VERSION)  # fmt: skip
            return None
        ints = {"stage", "side", "iterations", "n_open", "n_stick", "n_slip"}
        increments = tuple(
            Increment(
                **{  # type: ignore[arg-type]  # int and float fields by name
                    f: (int(v) if f in ints else float(v))
                    for f, v in zip(_INC_FIELDS, row, strict=True)
                }
            )
            for row in incs
        )
        return CycleResult(
            settings=CycleSettings(**meta["settings"]),
            clearance_mm=float(meta["clearance_mm"]),
            increments=increments,
            free_play_mm=float(meta["free_play_mm"]),
            states=states,
            configs={},
            timings_s={k: float(v) for k, v in meta["timings_s"].items()},
            preload_state=preload,
            ball_coordinates=balls,
            slides=tuple(int(k) for k in meta.get("slides", ())),
            start_disp_mm=float(meta.get("start_disp_mm", 0.0)),
            cutbacks=tuple((int(k), int(n)) for k, n in meta.get("cutbacks", ())),
        )
