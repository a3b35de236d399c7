"""Paper 004 eqs 6-7: the loading index I of multi-point plate loads, against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crackle.analysis import loading_directions, loading_index


@pytest.mark.parametrize("theta,phi", [(0.0, 0.0), (90.0, 0.0), (90.0, 150.0), (37.0, 211.0)])
def test_two_opposite_plates_give_two_over_sqrt_three(theta, phi):
    """Opposite plates: A = [u, -u], singular values (sqrt 2, 0, 0): I = 2/sqrt(3) to 1e-12."""
    assert loading_index([theta, 180.0 - theta], [phi, phi + 180.0]) == pytest.approx(2.0 / math.sqrt(3.0), abs=1e-12)


def test_regular_tetrahedron_of_plates_gives_zero():
    """Four plates along a regular tetrahedron's vertex directions: A A^T = (4/3) Id, three equal
    singular values 2/sqrt(3): I = 0 to 1e-12."""
    top = math.degrees(math.acos(-1.0 / 3.0))
    theta = [0.0, top, top, top]
    phi = [0.0, 0.0, 120.0, 240.0]
    a = loading_directions(theta, phi)
    assert np.allclose(a @ a.T, 4.0 / 3.0 * np.eye(3), atol=1e-12)
    assert loading_index(theta, phi) == pytest.approx(0.0, abs=1e-12)


def test_paper_four_point_layout_in_one_plane():
    """The paper's fastest 4-point layout (azimuths 0, 150, 180, 330 at top angle 90): all in one
    plane, so p3 = 0 and (p1, p2) are the singular values of the 2 x 4 in-plane matrix of
    (cos phi, sin phi), computed independently: I matches to 1e-12 (here p = 1.9319, 0.5176, 0
    and I = 1.4142)."""
    phi = [0.0, 150.0, 180.0, 330.0]
    i = loading_index([90.0] * 4, phi)
    r = np.radians(phi)
    s = np.linalg.svd(np.array([np.cos(r), np.sin(r)]), compute_uv=False)
    p = np.array([s[0], s[1], 0.0])
    assert i == pytest.approx(float(np.sqrt(np.sum((p - p.mean()) ** 2))), abs=1e-12)
    assert s == pytest.approx([1.93185165, 0.51763809], abs=1e-8)


def test_mismatched_angles_are_refused():
    with pytest.raises(ValueError, match="one top angle and one azimuth per plate"):
        loading_index([90.0, 90.0], [0.0])
