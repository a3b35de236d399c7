"""Mesh fields as a ParaView time series: ``fields.pvd`` + ``fields/step_*.vtu``."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np


def _as_table(name: str, values, length: int) -> np.ndarray:
    """(length,) or (length, k) array; 3x3 tensors are flattened to 9 components."""
    a = np.asarray(values)
    if a.dtype == bool:
        a = a.astype(np.uint8)  # VTK has no boolean array type
    if a.ndim == 0 or a.shape[0] != length:
        raise ValueError(f"field {name!r} has shape {a.shape}, expected ({length}, ...)")
    if a.ndim > 2:
        a = a.reshape(length, -1)
    return np.ascontiguousarray(a)


def _merge_cell_data(tet_data: dict, tri_data: dict, n_tets: int, n_tris: int) -> dict:
    """One list of two arrays per name; a name missing from a block gets zeros.

    VTK requires every cell array to cover all cells of the file, so an array
    given only for tets is padded with zeros over the triangles and vice versa.
    """
    merged = {}
    for name in list(tet_data) + [n for n in tri_data if n not in tet_data]:
        tet, tri = tet_data.get(name), tri_data.get(name)
        template = tet if tet is not None else tri
        if tet is None:
            tet = np.zeros((n_tets,) + template.shape[1:], dtype=template.dtype)
        if tri is None:
            tri = np.zeros((n_tris,) + template.shape[1:], dtype=template.dtype)
        if tet.shape[1:] != tri.shape[1:]:
            raise ValueError(
                f"cell field {name!r} has {tet.shape[1:]} components on tets "
                f"but {tri.shape[1:]} on triangles"
            )
        dtype = np.result_type(tet.dtype, tri.dtype)
        merged[name] = [tet.astype(dtype, copy=False), tri.astype(dtype, copy=False)]
    return merged


class FieldWriter:
    """Writes one ``fields/step_NNNNNN.vtu`` per call and keeps ``fields.pvd`` current.

    The pvd is rewritten after every step, so the series opens in ParaView
    even while the run is going or after it crashed.
    """

    def __init__(self, out_dir: str | os.PathLike):
        self.out_dir = Path(out_dir)
        self.fields_dir = self.out_dir / "fields"
        self.fields_dir.mkdir(parents=True, exist_ok=True)
        self.pvd_path = self.out_dir / "fields.pvd"
        self.steps: list[tuple[float, str]] = []  # (time, path relative to out_dir)

    def write(
        self,
        time: float,
        points,
        tets,
        point_data: Mapping | None = None,
        cell_data: Mapping | None = None,
        triangles=None,
        triangle_data: Mapping | None = None,
    ) -> Path:
        """Write one step and return the path of the vtu file.

        ``cell_data`` is per tet, ``triangle_data`` per triangle (e.g. interface
        elements). With triangles, both blocks go into the same file, every
        cell array is padded with zeros on the block it was not given for,
        and ``cell_kind`` tells tets (0) from triangles (1).
        """
        points = np.asarray(points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"points must be (n, 3), got {points.shape}")
        tets = np.asarray(tets, dtype=np.int64).reshape(-1, 4)
        n_points, n_tets = len(points), len(tets)

        point_fields = {
            name: _as_table(name, v, n_points) for name, v in (point_data or {}).items()
        }
        tet_fields = {
            name: _as_table(name, v, n_tets) for name, v in (cell_data or {}).items()
        }

        if triangles is None:
            if triangle_data:
                raise ValueError("triangle_data given without triangles")
            cells = [("tetra", tets)]
            tet_fields.setdefault("cell_kind", np.zeros(n_tets, dtype=np.int32))
            cell_fields = {name: [a] for name, a in tet_fields.items()}
        else:
            triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
            n_tris = len(triangles)
            tri_fields = {
                name: _as_table(name, v, n_tris)
                for name, v in (triangle_data or {}).items()
            }
            cells = [("tetra", tets), ("triangle", triangles)]
            cell_fields = _merge_cell_data(tet_fields, tri_fields, n_tets, n_tris)
            cell_fields.setdefault(
                "cell_kind",
                [np.zeros(n_tets, dtype=np.int32), np.ones(n_tris, dtype=np.int32)],
            )

        relative = f"fields/step_{len(self.steps):06d}.vtu"
        mesh = meshio.Mesh(points, cells, point_data=point_fields, cell_data=cell_fields)
        meshio.write(
            self.out_dir / relative, mesh, file_format="vtu", binary=True, compression=None
        )
        self.steps.append((float(time), relative))
        self._write_pvd()
        return self.out_dir / relative

    def _write_pvd(self) -> None:
        lines = [
            '<?xml version="1.0"?>',
            '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
            "  <Collection>",
        ]
        for time, relative in self.steps:
            lines.append(
                f'    <DataSet timestep="{time!r}" group="" part="0" '
                f"file={quoteattr(relative)}/>"
            )
        lines += ["  </Collection>", "</VTKFile>", ""]
        # Write then rename: the pvd on disk is always a complete document.
        tmp = self.pvd_path.with_name(self.pvd_path.name + ".tmp")
        tmp.write_text("\n".join(lines), encoding="utf-8")
        os.replace(tmp, self.pvd_path)


def read_pvd(path: str | os.PathLike) -> list[tuple[float, Path]]:
    """(time, vtu path) for each dataset listed in a pvd file."""
    import xml.etree.ElementTree as ET

    path = Path(path)
    root = ET.parse(path).getroot()
    return [
        (float(ds.get("timestep")), path.parent / ds.get("file"))
        for ds in root.iter("DataSet")
    ]
