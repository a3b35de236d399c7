"""The hole and petal count of a perforated plate (analysis.perforation) on constructed plates:
unit spacing, a hole of radius 5 about the z axis."""

import numpy as np
import pytest

from crackle.analysis.perforation import measure_perforation

HOLE = 5.0


def _plate():
    g = np.arange(-20.0, 21.0)
    gx, gy = np.meshgrid(g, g, indexing="ij")
    X = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1)
    R = np.hypot(X[:, 0], X[:, 1])
    theta = np.arctan2(X[:, 1], X[:, 0])
    return X, R, theta


def _radial_cracks(X, R, theta, count, length):
    """Failed particles along `count` rays from the axis out to `length`, normals along the hoop."""
    failed = np.zeros(len(X), dtype=bool)
    normal = np.zeros((len(X), 3))
    for k in range(count):
        a = 2.0 * np.pi * k / count
        ray = np.array([np.cos(a), np.sin(a), 0.0])
        along = X @ ray
        off = np.linalg.norm(X - along[:, None] * ray, axis=1)
        on = (along >= 0.0) & (along <= length) & (off < 0.5)
        failed |= on
        normal[on] = [-np.sin(a), np.cos(a), 0.0]
    return failed, normal


def _petalled(X, R, theta):
    """Particles inside the hole folded down out of the plane: projected onto its rim."""
    x = X.copy()
    inside = R < HOLE
    x[inside, 0] = (HOLE + 0.2) * np.cos(theta[inside])
    x[inside, 1] = (HOLE + 0.2) * np.sin(theta[inside])
    x[inside, 2] = -(HOLE - R[inside])
    return x


@pytest.mark.parametrize("count", [3, 4, 6])
def test_radial_cracks_past_the_rim_count_as_petals(count):
    X, R, theta = _plate()
    failed, normal = _radial_cracks(X, R, theta, count, length=12.0)  # past the petal circle, 4.7 + 4.7
    found = measure_perforation(X, _petalled(X, R, theta), np.zeros(len(X), dtype=np.int64), failed, normal,
                                [0.0, 0.0, 1.0], [0.0, 0.0, -1.0], spacing=1.0)
    assert found.petals == count
    # The opening: the folded petals' projection at the rim, less half a spacing: 2 x (5.2 - 0.5).
    assert found.hole_diameter == pytest.approx(2.0 * (HOLE + 0.2 - 0.5), abs=1.0)
    assert found.plug_particles == 0


def test_cracks_shorter_than_the_hole_radius_past_the_rim_open_no_petals():
    X, R, theta = _plate()
    failed, normal = _radial_cracks(X, R, theta, 4, length=8.0)  # short of the petal circle, 4.7 + 4.7
    found = measure_perforation(X, _petalled(X, R, theta), np.zeros(len(X), dtype=np.int64), failed, normal,
                                [0.0, 0.0, 1.0], [0.0, 0.0, 1.0], spacing=1.0)
    assert found.petals == 0
    assert dict(found.petals_by_reach)[2] == 4  # they do cross the circle two spacings out


def test_a_plug_is_a_hole_without_petals():
    X, R, theta = _plate()
    plug = R < HOLE
    x = X.copy()
    x[plug, 2] -= 30.0  # pushed out below the plate
    rim = (R >= HOLE - 0.5) & (R < HOLE + 0.5)
    normal = np.zeros((len(X), 3))
    normal[rim] = X[rim] / R[rim, None]  # a circumferential crack: radial normals
    found = measure_perforation(X, x, plug.astype(np.int64), rim, normal, [0.0, 0.0, 0.0], [0.0, 0.0, 1.0],
                                spacing=1.0)
    assert found.petals == 0
    assert found.plug_particles == int(plug.sum())
    assert found.largest_loose_piece == int(plug.sum())  # one piece
    assert found.hole_diameter == pytest.approx(2.0 * (HOLE - 0.5), abs=1.0)


def test_a_hole_whose_material_went_as_single_particles_has_no_large_loose_piece():
    """The same hole, its material detached particle by particle (each its own piece): as many
    particles out of the plate, the largest loose piece one particle."""
    X, R, theta = _plate()
    plug = R < HOLE
    x = X.copy()
    x[plug, 2] -= 30.0
    piece = np.zeros(len(X), dtype=np.int64)
    piece[plug] = 1 + np.arange(int(plug.sum()))
    found = measure_perforation(X, x, piece, plug, np.zeros((len(X), 3)), [0.0, 0.0, 0.0], [0.0, 0.0, 1.0],
                                spacing=1.0)
    assert found.plug_particles == int(plug.sum()) and found.largest_loose_piece == 1


def test_an_intact_plate_has_no_hole():
    X, R, theta = _plate()
    x = X.copy()
    x[:, 2] -= 3.0 * np.exp(-(R / 6.0) ** 2)  # dished, not perforated
    found = measure_perforation(X, x, np.zeros(len(X), dtype=np.int64), np.zeros(len(X), dtype=bool),
                                np.zeros((len(X), 3)), [0.3, -0.2, 5.0], [0.0, 0.0, 1.0], spacing=1.0)
    assert found.hole_diameter < 1.0 and found.petals == 0
