"""Mesh fields as a ParaView time series: ``fields.pvd`` + ``fields/step_*.vtu``."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np

# The column order of every symmetric tensor crackle writes (Voigt order, as in Abaqus' output
# except for the shear order), named in ParaView through `component_names`.
STRESS_COMPONENTS = ("xx", "yy", "zz", "xy", "yz", "xz")


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


def _name_components(path: Path, component_names: Mapping) -> None:
    """Add VTK's ComponentName attributes (which meshio does not write) to the named arrays."""
    text = path.read_text(encoding="utf-8")
    for name, comps in component_names.items():
        tag = f'Name="{name}" NumberOfComponents="{len(comps)}"'
        labels = " ".join(f'ComponentName{i}="{c}"' for i, c in enumerate(comps))
        text = text.replace(tag, f"{tag} {labels}")
    path.write_text(text, encoding="utf-8")


def _merge_cell_data(blocks) -> dict:
    """One list of arrays (one per block) per name; a name missing from a block gets zeros.

    VTK requires every cell array to cover all cells of the file, so an array given only for
    some blocks is padded with zeros over the others.
    """
    names = []
    for _, _, data in blocks:
        names += [n for n in data if n not in names]
    merged = {}
    for name in names:
        arrays = [data.get(name) for _, _, data in blocks]
        template = next(a for a in arrays if a is not None)
        shapes = {a.shape[1:] for a in arrays if a is not None}
        if len(shapes) > 1:
            raise ValueError(f"cell field {name!r} has different components on different cell blocks: {sorted(shapes)}")
        dtype = np.result_type(*[a.dtype for a in arrays if a is not None])
        merged[name] = [
            (a if a is not None else np.zeros((len(conn),) + template.shape[1:], dtype=dtype)).astype(dtype, copy=False)
            for a, (_, conn, _) in zip(arrays, blocks)
        ]
    return merged


class FieldWriter:
    """Writes one ``fields/step_NNNNNN.vtu`` per call and keeps ``fields.pvd`` current.

    The pvd is rewritten after every step, so the series opens in ParaView
    even while the run is going or after it crashed.
    """

    def __init__(self, out_dir: str | os.PathLike, keep_until: float | None = None):
        """`keep_until`: continue an existing series (a resumed run), keeping its snapshots up
        to that time and deleting later ones."""
        self.out_dir = Path(out_dir)
        self.fields_dir = self.out_dir / "fields"
        self.fields_dir.mkdir(parents=True, exist_ok=True)
        self.pvd_path = self.out_dir / "fields.pvd"
        self.steps: list[tuple[float, str]] = []  # (time, path relative to out_dir)
        self.last_frame_bytes = 0  # size of the latest snapshot written
        if keep_until is not None and self.pvd_path.exists():
            for time, path in read_pvd(self.pvd_path):
                if time <= keep_until:
                    self.steps.append((time, path.relative_to(self.out_dir).as_posix()))
                else:
                    path.unlink(missing_ok=True)
            self._write_pvd()

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
        and ``cell_kind`` tells tets (0) from triangles (1). See write_blocks.
        """
        tets = np.asarray(tets, dtype=np.int64).reshape(-1, 4)
        if triangles is None:
            if triangle_data:
                raise ValueError("triangle_data given without triangles")
            return self.write_blocks(time, points, [("tetra", tets, cell_data or {})], point_data)
        triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        return self.write_blocks(
            time, points, [("tetra", tets, cell_data or {}), ("triangle", triangles, triangle_data or {})], point_data
        )

    def write_blocks(self, time: float, points, blocks, point_data: Mapping | None = None,
                     component_names: Mapping | None = None) -> Path:
        """Write one step of any cells: `blocks` is a list of (meshio cell type, connectivity,
        {name: per-cell array}); `cell_kind` tells the blocks apart (their index).
        `component_names` ({array name: names of its columns}) labels the columns of an array in
        ParaView (e.g. stress: xx, yy, zz, xy, yz, xz)."""
        points = np.asarray(points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"points must be (n, 3), got {points.shape}")
        n_points = len(points)
        point_fields = {name: _as_table(name, v, n_points) for name, v in (point_data or {}).items()}
        tables = []
        for kind, conn, data in blocks:
            conn = np.asarray(conn, dtype=np.int64)
            conn = conn.reshape(len(conn), -1)
            tables.append((kind, conn, {name: _as_table(name, v, len(conn)) for name, v in data.items()}))
        cells = [(kind, conn) for kind, conn, _ in tables]
        cell_fields = _merge_cell_data(tables)
        cell_fields.setdefault("cell_kind", [np.full(len(conn), k, dtype=np.int32) for k, (_, conn) in enumerate(cells)])

        relative = f"fields/step_{len(self.steps):06d}.vtu"
        mesh = meshio.Mesh(points, cells, point_data=point_fields, cell_data=cell_fields)
        meshio.write(
            self.out_dir / relative, mesh, file_format="vtu", binary=True, compression=None
        )
        if component_names:
            _name_components(self.out_dir / relative, component_names)
        self.steps.append((float(time), relative))
        self.last_frame_bytes = (self.out_dir / relative).stat().st_size
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
