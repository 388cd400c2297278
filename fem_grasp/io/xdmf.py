"""The XDMF 3 + HDF5 copy of a pickup's time series (``object.xdmf`` with its heavy data in ``object.h5``),
written beside the ParaView series when h5py can be loaded in the process (:func:`has_h5py`).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Sequence
from xml.sax.saxutils import quoteattr

import numpy as np

from .._files import atomic_write, atomic_write_text

__all__ = ["has_h5py", "write_xdmf"]

log = logging.getLogger(__name__)


_H5PY: list[bool] = []


def has_h5py() -> bool:
    """Whether h5py can be used in this process (checked once).  h5py's own HDF5 cannot load into a process
    that has loaded another HDF5 library first (dolfinx's, through PETSc): then no XDMF copy is written."""
    if not _H5PY:
        try:
            import h5py  # noqa: F401
            _H5PY.append(True)
        except ImportError:
            log.info("h5py is not installed: no object.xdmf, the .pvd series holds the same data "
                     "(pip install \"fem_grasp[xdmf]\" adds it)")
            _H5PY.append(False)
        except Exception as exc:  # noqa: BLE001 - installed but cannot load here
            log.warning("h5py cannot be loaded in this process (%s: %s; another HDF5 library was loaded first, "
                        "e.g. by dolfinx): no object.xdmf, the .pvd series holds the same data",
                        type(exc).__name__, exc)
            _H5PY.append(False)
    return _H5PY[0]


def write_xdmf(path: str | Path, tets: np.ndarray,
               steps: Sequence[tuple[float, np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray],
                                     dict[str, float]]]) -> Path:
    """An XDMF 3 temporal collection (``path``) with its heavy data in HDF5 beside it (``path`` with ``.h5``).

    ``steps``: (time, deformed points (n, 3), point data, cell data, field data) per frame.  Each frame is a
    grid of its own deformed geometry sharing one topology; point and cell data are node- and
    cell-centred attributes, field data grid-centred ones (ParaView shows them as field data).
    """
    import h5py

    path = Path(path)
    h5 = path.with_suffix(".h5")
    tets = np.asarray(tets, dtype=np.int64)

    def heavy(tmp: Path) -> None:
        with h5py.File(tmp, "w") as f:
            f.create_dataset("topology", data=tets)
            for k, (_, pts, pd, cd, _) in enumerate(steps):
                g = f.create_group(f"frames/{k:04d}")
                g.create_dataset("geometry", data=np.asarray(pts, float))
                for name, v in {**pd, **cd}.items():
                    g.create_dataset(name, data=np.asarray(v))

    def item(dataset: str, shape: tuple[int, ...], dtype: np.dtype) -> str:
        kind = "Int" if np.issubdtype(dtype, np.integer) else "Float"
        return (f'<DataItem Dimensions="{" ".join(str(d) for d in shape)}" NumberType="{kind}" '
                f'Precision="{np.dtype(dtype).itemsize}" Format="HDF">{h5.name}:/{dataset}</DataItem>')

    def attribute(name: str, value: np.ndarray, center: str, dataset: str) -> str:
        kind = "Vector" if value.ndim == 2 and value.shape[1] == 3 else "Scalar"
        return (f'<Attribute Name={quoteattr(name)} AttributeType="{kind}" Center="{center}">'
                f'{item(dataset, value.shape, value.dtype)}</Attribute>')

    grids = []
    for k, (t, pts, pd, cd, field) in enumerate(steps):
        g = f"frames/{k:04d}"
        parts = [f'<Grid Name="frame_{k:04d}" GridType="Uniform">', f'<Time Value="{t:.17g}"/>',
                 f'<Topology TopologyType="Tetrahedron" NumberOfElements="{len(tets)}">'
                 f'{item("topology", tets.shape, tets.dtype)}</Topology>',
                 f'<Geometry GeometryType="XYZ">{item(g + "/geometry", np.shape(pts), np.dtype(float))}</Geometry>']
        parts += [attribute(name, np.asarray(v), "Node", f"{g}/{name}") for name, v in pd.items()]
        parts += [attribute(name, np.asarray(v), "Cell", f"{g}/{name}") for name, v in cd.items()]
        for name, v in field.items():
            kind, prec = ("Int", 4) if isinstance(v, (int, np.integer)) else ("Float", 8)
            parts.append(f'<Attribute Name={quoteattr(name)} AttributeType="Scalar" Center="Grid">'
                         f'<DataItem Dimensions="1" NumberType="{kind}" Precision="{prec}" Format="XML">'
                         f'{v if kind == "Int" else format(float(v), ".17g")}</DataItem></Attribute>')
        parts.append("</Grid>")
        grids.append("\n      ".join(parts))
    text = ('<?xml version="1.0"?>\n<Xdmf Version="3.0">\n  <Domain>\n'
            '    <Grid Name="object" GridType="Collection" CollectionType="Temporal">\n      '
            + "\n      ".join(grids) + "\n    </Grid>\n  </Domain>\n</Xdmf>\n")
    atomic_write(h5, heavy)
    atomic_write_text(path, text)
    return path
