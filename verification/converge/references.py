"""The study's references, kept in the repository: ``verification/converge/references.json``.

The full study takes hours on two cores, and its cache stays on the machine that ran it.  Its references — per
object the verdict, ρ* and Σ f·n̂ of the finest uniform mesh with the increment divided by 2 and 4, each with its
own uncertainty and method, and how far the other fine meshes are from it — are what the benchmarks measure
answers against (``python -m bench.bench --only accuracy``).  ``python -m verification converge --report-only
--write-references`` writes them from the cache into this file (objects without a reference in the cache keep
theirs), so that a machine without the study measures against the same numbers; the file says which machine and
which study wrote each object's entry.

Every mesh of the study grasps at its own nodes, up to half a spacing from the points where the placement rule
grasps on the object's surface, and the answer moves with the grasp: the study's references are 5-13 % in ρ*
and 11-22 % in Σ f·n̂ from the pinned ones on the tomato, the orange and the football.  An object's entry may
therefore also hold a **pinned** reference (:data:`PINNED`): the answer at the rule's own points, on uniform
meshes that have those points as nodes, written by ``python scripts/pinned_reference.py NAME
--write-reference`` (:func:`write_pinned`).  It is the reference of the question a run answers (the rule's
grasp), and the benchmarks measure against it where an object has one.
"""

from __future__ import annotations

import datetime
import json
import math
import os
from pathlib import Path
from typing import Any

from fem_grasp.io.output import json_safe

from .._common.run import cpu_model

__all__ = ["REFERENCES", "FIELDS", "PINNED", "extract", "load", "write", "write_pinned"]

#: The committed references.
REFERENCES = Path(__file__).with_name("references.json")
#: What an entry keeps of the analysis's ``reference`` (not w(ρ) itself, nor the increments' runs).
FIELDS = ("success", "vertices", "step", "h", "weight", "max_liftable", "rho", "force", "rho_bracket", "slope",
          "mesh_band")
#: An entry's key for the reference at the placement rule's own grasp points (module notes).
PINNED = "pinned"


def extract(analysis: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Per object with a reference in the study's ``analysis`` (:func:`verification.converge.study`), the
    :data:`FIELDS` of it."""
    out = {}
    for name, obj in analysis.get("objects", {}).items():
        ref = (obj or {}).get("reference")
        if ref:
            out[name] = json_safe({k: ref[k] for k in FIELDS if k in ref})
    return out


def load(path: Path | None = None) -> dict[str, dict[str, Any]]:
    """The committed references per object (``path``, default :data:`REFERENCES`; an error of None in the file
    is read as inf: unknown); each carries ``source``, the study that wrote it.  Empty when the file is
    missing."""
    path = REFERENCES if path is None else path
    if not path.exists():
        return {}
    data = json.loads(path.read_text())
    out = {}
    for name, ref in data.get("objects", {}).items():
        ref = _errors_read(ref)
        if isinstance(ref.get(PINNED), dict):
            ref[PINNED] = _errors_read(ref[PINNED])
        out[name] = ref
    return out


def _errors_read(ref: dict[str, Any]) -> dict[str, Any]:
    ref = dict(ref)
    for q in ("rho", "force"):
        if isinstance(ref.get(q), dict) and ref[q].get("error") is None:
            ref[q] = dict(ref[q], error=math.inf)
    return ref


def _machine(machine: str | None) -> str:
    return machine or f"{cpu_model()}, {os.cpu_count()} cores"


def _save(path: Path, objects: dict[str, Any]) -> None:
    data = {"about": "The convergence study's references (verification/converge/references.py); written by "
                     "python -m verification converge --report-only --write-references, the pinned ones by "
                     "python scripts/pinned_reference.py NAME --write-reference",
            "units": "metres, newtons; rho and force: value, relative error and how it was estimated",
            "objects": dict(sorted(objects.items()))}
    path.write_text(json.dumps(data, indent=1) + "\n")


def write_pinned(name: str, entry: dict[str, Any], path: Path | None = None, machine: str | None = None) -> None:
    """Keep ``entry`` as object ``name``'s reference at the rule's grasp (:data:`PINNED`) in ``path`` (default
    :data:`REFERENCES`), with the command, the date and the machine; the study's reference and the other objects
    stay as they are."""
    path = REFERENCES if path is None else path
    data = json.loads(path.read_text()) if path.exists() else {}
    objects = data.get("objects", {})
    source = {"command": f"python scripts/pinned_reference.py {name} --write-reference",
              "date": datetime.date.today().isoformat(), "machine": _machine(machine)}
    objects[name] = dict(objects.get(name, {}), **{PINNED: json_safe(dict(entry, source=source))})
    _save(path, objects)


def write(analysis: dict[str, Any], path: Path | None = None, machine: str | None = None) -> list[str]:
    """Merge the references of ``analysis`` into ``path`` (default :data:`REFERENCES`; objects the analysis has
    none for keep their entry, and every object its pinned reference); returns the objects written.  Each entry
    records the study, the date and the machine."""
    path = REFERENCES if path is None else path
    if analysis.get("quick"):
        raise ValueError("the quick study's references are coarse meshes: only the full study's are kept")
    data = json.loads(path.read_text()) if path.exists() else {}
    objects = data.get("objects", {})
    source = {"study": "python -m verification converge", "date": datetime.date.today().isoformat(),
              "machine": _machine(machine)}
    new = extract(analysis)
    for name, ref in new.items():
        pinned = objects.get(name, {}).get(PINNED)
        objects[name] = dict(ref, source=source, **({PINNED: pinned} if pinned else {}))
    _save(path, objects)
    return sorted(new)
