"""ISRM curved jaws (arc radius 1.5 R, 20 mm wide, 30 mm deep) for the 40 mm Brazilian disc: open
strips written as ASCII STL beside this script, normals towards the disc (python make_jaws.py)."""

import meshio
import numpy as np

R = 0.02  # disc radius, m
JAW_RADIUS = 1.5 * R  # the ISRM arc
HALF_WIDTH = 0.01
DEPTH = 0.03  # along the disc axis, twice the disc's thickness
SEGMENTS = 40

x = np.linspace(-HALF_WIDTH, HALF_WIDTH, SEGMENTS + 1)
for name, side in (("top", 1.0), ("bottom", -1.0)):
    # The arc's centre on the loading axis, so that its apex lies on the disc's rim (y = side R).
    y = side * (R - JAW_RADIUS) + side * np.sqrt(JAW_RADIUS**2 - x**2)
    points = np.array([[xi, yi, z] for z in (-DEPTH / 2, DEPTH / 2) for xi, yi in zip(x, y)])
    n = SEGMENTS + 1
    triangles = np.array([t for i in range(SEGMENTS) for t in ([i, i + 1, n + i + 1], [i, n + i + 1, n + i])])
    # Normals out of the tool, towards the disc centre.
    corners = points[triangles]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    away = np.einsum("ij,ij->i", normal, -corners.mean(axis=1)) < 0
    triangles[away] = triangles[away][:, [0, 2, 1]]
    meshio.write(f"jaw_{name}.stl", meshio.Mesh(points, [("triangle", triangles)]), binary=False)
