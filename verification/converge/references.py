"""The study's references, kept in the repository: ``verification/converge/references.json``.

The full study takes hours on two cores, and its cache stays on the machine that ran it.  Its references — per
object the verdict, ρ* and Σ f·n̂ of the finest uniform mesh with the increment divided by 2 and 4, each with its
own uncertainty and method, and how far the other fine meshes are from it — are what the benchmarks measure
answers against (``python -m bench.bench --only accuracy``).  ``python -m verification converge --report-only
--write-references`` writes them from the cache into this file (objects without a reference in the cache keep
theirs), so that a machine without the study measures against the same numbers; the file says which machine and
which study wrote each object's entry.
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

__all__ = ["REFERENCES", "FIELDS", "extract", "load", "write"]

#: The committed references.
REFERENCES = Path(__file__).with_name("references.json")
#: What an entry keeps of the analysis's ``reference`` (not w(ρ) itself, nor the increments' runs).
FIELDS = ("success", "vertices", "step", "h", "weight", "max_liftable", "rho", "force", "rho_bracket", "slope",
          "mesh_band")


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
        ref = dict(ref)
        for q in ("rho", "force"):
            if isinstance(ref.get(q), dict) and ref[q].get("error") is None:
                ref[q] = dict(ref[q], error=math.inf)
        out[name] = ref
    return out


def write(analysis: dict[str, Any], path: Path | None = None, machine: str | None = None) -> list[str]:
    """Merge the references of ``analysis`` into ``path`` (default :data:`REFERENCES`; objects the analysis has
    none for keep their entry); returns the objects written.  Each entry records the study, the date and the
    machine."""
    path = REFERENCES if path is None else path
    if analysis.get("quick"):
        raise ValueError("the quick study's references are coarse meshes: only the full study's are kept")
    data = json.loads(path.read_text()) if path.exists() else {}
    objects = data.get("objects", {})
    source = {"study": "python -m verification converge", "date": datetime.date.today().isoformat(),
              "machine": machine or f"{cpu_model()}, {os.cpu_count()} cores"}
    new = extract(analysis)
    for name, ref in new.items():
        objects[name] = dict(ref, source=source)
    data = {"about": "The convergence study's references (verification/converge/references.py); written by "
                     "python -m verification converge --report-only --write-references",
            "units": "metres, newtons; rho and force: value, relative error and how it was estimated",
            "objects": dict(sorted(objects.items()))}
    path.write_text(json.dumps(data, indent=1) + "\n")
    return sorted(new)
