"""Scenario sections (tools, plates, loading angle, supports, pressures) turned into the
method-agnostic loading descriptions of crackle.loading; every method builds from these."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from ..analysis.strength import ahead_of
from ..geometry.projectile import projectile_surface
from ..schema import ScenarioError, resolve_path
from . import History, Precrack, Pressure, Selection, Support, Tool, load_surface


def _history_of(spec) -> History:
    """A tool's or a moving support's speed history: its table, or a ramp to its speed."""
    if spec.speed_table is not None:
        return History(tuple(spec.speed_table.time), tuple(spec.speed_table.speed))
    return History.ramp(spec.speed, spec.ramp_time)


def selection(where) -> Selection:
    return Selection(where.plane_point, where.plane_normal, where.box_min, where.box_max, where.tol, where.radius,
                     where.axis_point, where.axis_direction, where.group)


def with_named_surfaces(supports: list, pressures: list, points: np.ndarray, surfaces: dict | None):
    """The supports and pressures with each selection naming a group (where.group) given that
    named surface's triangles ((k, 3, 3) corner positions, from the mesh's `surfaces`: name ->
    (k, 3) indices into `points`); ValueError naming the file's surfaces for a name it lacks."""
    surfaces = surfaces or {}

    def resolved(sel):
        if not isinstance(sel, Selection) or sel.group is None:
            return sel
        if sel.group not in surfaces:
            known = ", ".join(sorted(surfaces)) or "none"
            raise ValueError(f"where.group = {sel.group!r}: the mesh file has no surface of that name (its named "
                             f"surfaces: {known}; gmsh: a physical surface group)")
        return dataclasses.replace(sel, surface=points[surfaces[sel.group]])

    return ([dataclasses.replace(s, where=resolved(s.where)) for s in supports],
            [dataclasses.replace(p, faces=resolved(p.faces)) for p in pressures])


def rotation_matrix(angle_deg: float, axis) -> np.ndarray:
    """Right-handed rotation by `angle_deg` degrees about `axis` (Rodrigues)."""
    k = np.asarray(axis, dtype=float)
    k = k / np.linalg.norm(k)
    a = math.radians(angle_deg)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(a) * K + (1.0 - math.cos(a)) * (K @ K)


def build_tools(specs, base: Path | None = None, loading=None) -> list[Tool]:
    """Tools of a scenario; `loading` (a LoadingSpec) rotates all of them rigidly about its
    axis through its center: positions, directions, normals, axes and surface vertices."""
    R = None
    if loading is not None and loading.angle % 360.0 != 0.0:
        R = rotation_matrix(loading.angle, loading.axis)
        c0 = np.asarray(loading.center, dtype=float)

    def vec(v):
        return v if R is None else tuple(float(x) for x in R @ np.asarray(v, dtype=float))

    def point(p):
        return p if R is None else tuple(float(x) for x in c0 + R @ (np.asarray(p, dtype=float) - c0))

    tools = []
    for i, t in enumerate(specs):
        surface = {}
        if t.shape == "surface":
            path = resolve_path(t.file, base)
            try:
                vertices, triangles = load_surface(path, scale=t.scale, offset=t.offset)
            except ValueError as err:  # MeshError included
                raise ScenarioError(f"tools.{i}.file: {err}") from None
            if R is not None:
                vertices = c0 + (np.asarray(vertices, dtype=float) - c0) @ R.T
            surface = {"surface": str(path), "vertices": vertices, "triangles": triangles}
        elif t.shape == "projectile":
            vertices, triangles = projectile_surface(point(t.center), vec(t.direction), t.radius, t.length, t.nose,
                                                     t.nose_length)
            surface = {"vertices": vertices, "triangles": triangles}  # no file
        tools.append(
            Tool(
                name=t.name,
                shape="surface" if surface else t.shape,
                direction=vec(t.direction),
                speed=_history_of(t),
                friction=t.friction,
                center=point(t.center),
                normal=vec(t.normal),
                size=t.size,
                axes=(vec(t.axes[0]), vec(t.axes[1])),
                axis=vec(t.axis),
                radius=t.radius,
                length=t.length,
                penalty=t.penalty,
                mass=t.mass,
                glued=t.glued,
                glue_depth=t.glue_depth,
                seat=t.seat,
                **surface,
            )
        )
    return tools


def touch_specimen(tool: Tool, points: np.ndarray) -> Tool:
    """The tool shifted along its direction so that it just reaches the specimen: a platen placed
    on the mesh as meshed, whatever the facets of a curved surface and the loading angle. A tool
    behind the specimen along its direction (a push) puts its leading extreme on the specimen's
    first point along it; one ahead of it (a glued grip that pulls) its trailing extreme on the
    specimen's last point."""
    d = np.asarray(tool.direction, dtype=float)
    d /= np.linalg.norm(d)
    c = np.asarray(tool.center, dtype=float)
    along = points @ d
    if tool.glued and ahead_of(tool, points):
        shift = float(np.max(along)) - (float(c @ d) - _half_extent(tool, d))
    else:
        shift = float(np.min(along)) - (float(c @ d) + _half_extent(tool, d))
    return dataclasses.replace(tool, center=tuple(float(x) for x in c + shift * d))


def _half_extent(tool: Tool, d: np.ndarray) -> float:
    """How far a sphere or box tool reaches from its centre along the unit direction d."""
    if tool.shape == "sphere":
        return tool.radius
    # Box: its corner furthest along d.
    a1 = np.asarray(tool.axes[0], dtype=float)
    a1 /= np.linalg.norm(a1)
    a2 = np.asarray(tool.axes[1], dtype=float)
    a2 = a2 - (a2 @ a1) * a1
    a2 /= np.linalg.norm(a2)
    a3 = np.cross(a1, a2)
    half = 0.5 * np.asarray(tool.size, dtype=float)
    return sum(h * abs(float(a @ d)) for h, a in zip(half, (a1, a2, a3)))


def build_pressures(specs, end_time: float) -> list[Pressure]:
    out = []
    for p in specs:
        if p.profile == "taylor":
            history = History.taylor_wave(p.value, p.plateau, p.decay_time)
        elif p.rate is not None:
            history = History.rate(p.rate, end_time)
        elif p.table is not None:
            history = History(tuple(p.table.time), tuple(p.table.speed))
        else:
            history = History.ramp(p.value, p.ramp_time)
        out.append(Pressure(history, "precrack" if p.faces == "precrack" else selection(p.where), p.wall,
                            p.front_speed, p.front_origin, p.front_direction))
    return out


def build_supports(specs, grips: dict[int, int] | None = None) -> list[Support]:
    """[[supports]] as loading.Support; `grips` maps a moving support's index to its tool's."""
    grips = grips or {}
    return [Support(s.kind, selection(s.where), s.normal, grips.get(i, -1)) for i, s in enumerate(specs)]


def support_grip(spec, name: str) -> Tool:
    """The tool of shape "support" that drives a moving support and reads its reaction: its
    direction (a roller's normal by default) and speed history; it touches nothing."""
    direction = spec.direction if spec.direction is not None else spec.normal
    return Tool(name=name, shape="support", direction=tuple(float(c) for c in direction), speed=_history_of(spec))


def build_loading(scenario, base: Path | None):
    """The tools (before meshing: a bad surface file fails fast), supports and pressures of a
    scenario. The tools are [[tools]] and [plates] (scenario.all_tools()), then the grips of the
    moving supports (scenario.support_grips())."""
    tools = build_tools(scenario.all_tools(), base, scenario.loading)
    grips = {}
    for i, name in scenario.support_grips():
        grips[i] = len(tools)
        tools.append(support_grip(scenario.supports[i], name))
    return (tools, build_supports(scenario.supports, grips),
            build_pressures(scenario.pressures, scenario.run.end_time))


def touch_tools(tools: list[Tool], specs, points_for) -> list[Tool]:
    """The tools with those whose spec asks `touch` placed on the specimen by touch_specimen on
    `points_for(tool)` (the specimen's points as that tool meets them); the support grips after
    the specs are kept as they are."""
    return [touch_specimen(t, points_for(t)) if j < len(specs) and specs[j].touch else t for j, t in enumerate(tools)]


def build_precracks(specs) -> list[Precrack]:
    """[[precracks]] as loading.Precrack (an unset box corner: unbounded)."""
    return [Precrack(c.point, c.normal, c.box_min or Precrack.box_min, c.box_max or Precrack.box_max, c.tol)
            for c in specs]
