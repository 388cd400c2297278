"""The frames a report draws, read back from an output folder written by :func:`fem_grasp.io.output.write_run`:
which three the 3-D views show, each one's mesh and fields from its VTU step, and where the fingertips were; and
the stick and slip colours every picture uses.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["SLIP", "STICK", "finger_centres", "pick_frames", "read_frame"]

#: Stick and slip dots.
STICK, SLIP = "#2ca02c", "#ff7f0e"


def read_frame(out: Path, frame: dict[str, Any], doc: dict[str, Any] | None = None) -> dict[str, Any]:
    """One frame of the time series read back from its VTU step in ``out``: points, tets, displacement, the
    elastic displacement, von Mises stress, strain energy density, contact force, state and body per node
    (``doc``, the run's result.json, gives the material for a series written without the stress fields)."""
    import meshio

    m = meshio.read(out / frame["file"])
    tets = next(c.data for c in m.cells if c.type == "tetra")
    pd = m.point_data
    cd = {k: np.asarray(v[0], float) for k, v in m.cell_data.items()}
    points = np.asarray(m.points, float)
    disp = np.asarray(pd["displacement"], float)
    if "von_mises" not in cd or "elastic_displacement" not in pd:  # a series written before these fields
        from .series import mechanics_fields

        scene = (doc or {}).get("scene") or {}
        extra_pd, extra_cd = mechanics_fields(points - disp, np.asarray(tets, np.int64), disp,
                                              float(scene.get("young") or 1.0), float(scene.get("poisson") or 0.3))
        pd = {**extra_pd, **pd}
        cd = {**extra_cd, **cd}
    return {"points": points, "tets": np.asarray(tets, np.int64), "displacement": disp,
            "elastic_displacement": np.asarray(pd["elastic_displacement"], float),
            "von_mises": cd["von_mises"], "strain_energy_density": cd["strain_energy_density"],
            "force": np.asarray(pd["contact_force"], float),
            "state": np.asarray(pd["contact_state"]).astype(int), "body": np.asarray(pd["contact_body"]).astype(int)}


def pick_frames(doc: dict[str, Any]) -> list[tuple[str, str, dict[str, Any]]]:
    """(picture, title, frame) of the three 3-D views: at rest, when the lift starts (or where the squeeze
    stopped), and the last frame."""
    frames = doc["series"]["frames"]
    rest = frames[0]
    start = next((f for f in frames if f["label"] == "lift start"), None)
    if start is None:  # no lift: the last squeeze frame
        squeeze = [f for f in frames if f["phase"] in ("squeeze", "rest")]
        start = squeeze[-1]
    final = frames[-1]
    return [("rest.png", "at rest", rest), ("lift_start.png", "lift start" if start["label"] == "lift start"
                                            else "end of the squeeze (no lift)", start),
            ("lifted.png", "lifted" if doc["summary"]["success"] else "where the pickup stopped", final)]


def finger_centres(doc: dict[str, Any], frame: dict[str, Any]) -> np.ndarray | None:
    """(2, 3) the fingertip centres at ``frame`` (at rest: where they first touch), or None (no fingers placed)."""
    res = doc["result"]
    k = frame["snapshot"]
    if k is not None:
        return np.asarray(res["snapshots"][k]["finger_centers"], float)
    if frame["label"] == "rest" and res["snapshots"]:
        return np.asarray(res["snapshots"][0]["finger_centers"], float)
    if res.get("final"):
        return np.asarray(res["final"]["finger_centers"], float)
    return None
