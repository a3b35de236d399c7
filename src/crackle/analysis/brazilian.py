"""Brazilian disc test: orientation of the splitting fracture, and the load-strain curve.

Paper 001, section 4: F = (F1 + F2) / 2 from the two platen forces (eq. 15), axial strain
e = change of the diameter between the platens / D (eq. 16), and one tensile splitting fracture
along the loading axis. The elastic relation ft = 2 F / (pi D t) links the peak load to the
tensile strength.
"""

from __future__ import annotations

import math

import numpy as np

from .columns import tool_magnitude


def loading_direction(angle_deg: float) -> np.ndarray:
    """Unit loading axis in the disc plane (x, y) for a loading angle measured from y about z
    (the convention of the `[loading] angle` of the brazilian-disc example)."""
    a = math.radians(angle_deg)
    return np.array([-math.sin(a), math.cos(a), 0.0])


def splitting_angle(
    events: dict,
    load_axis,
    radius: float,
    center=(0.0, 0.0, 0.0),
    disc_axis=(0.0, 0.0, 1.0),
    central: float = 0.6,
    modes=("tension", "mixed"),
) -> tuple[float, int]:
    """Angle in degrees (0-90) between the splitting fracture and the loading axis, and the
    number of failures it used.

    The failures (events.csv rows, positions = failed-interface centroids) of the given modes
    are projected on the disc plane; those within `central` x radius of the centre along the
    loading axis are kept (away from the crushing zones at the platens), and the principal
    direction of their in-plane positions (largest eigenvector of their covariance) is the
    fracture's trace. NaN when fewer than 3 failures qualify.
    """
    n = np.asarray(disc_axis, dtype=float)
    n /= np.linalg.norm(n)
    d = np.asarray(load_axis, dtype=float)
    d = d - (d @ n) * n
    d /= np.linalg.norm(d)
    e2 = np.cross(n, d)  # in-plane, normal to the loading axis
    p = np.column_stack([events["x"], events["y"], events["z"]]) - np.asarray(center, dtype=float)
    keep = np.isin(events["mode"], list(modes)) & (np.abs(p @ d) <= central * radius)
    q = np.column_stack([p[keep] @ d, p[keep] @ e2])  # (along the load axis, across it)
    if len(q) < 3:
        return float("nan"), int(len(q))
    w, v = np.linalg.eigh(np.cov(q.T))
    main = v[:, np.argmax(w)]
    return float(math.degrees(math.atan2(abs(main[1]), abs(main[0])))), int(len(q))


def load_strain(history: dict, platens=("top", "bottom"), diameter: float = 0.04) -> tuple[np.ndarray, np.ndarray]:
    """(axial strain, load) columns from history.csv arrays: F = (|F1| + |F2|) / 2 (paper 001
    eq. 15) and e = (|u1| + |u2|) / D (eq. 16), for two platens moving towards each other
    along the loading axis (their displacement magnitudes add up to the change of diameter)."""

    a, b = platens
    force = 0.5 * (tool_magnitude(history, a, "f") + tool_magnitude(history, b, "f"))
    strain = (tool_magnitude(history, a, "u") + tool_magnitude(history, b, "u")) / diameter
    return strain, force


def brazilian_strength(force: float, diameter: float, thickness: float) -> float:
    """Elastic Brazilian relation: ft = 2 F / (pi D t)."""
    return 2.0 * force / (math.pi * diameter * thickness)
