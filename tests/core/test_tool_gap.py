"""Gap of a ball (centre p, radius r) to each rigid tool shape, against closed-form distances:
what lets particles (r = radius) and shell nodes (r = half thickness) meet the same tools as tet
nodes (r = 0)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crackle.loading import History, Tool
from crackle.loading.arrays import tool_arrays
from crackle.loading.tools import tool_gap

STILL = History.constant(0.0)


def _gap(tool, p, r):
    # Contact depth 1: a surface tool's triangles are candidates up to 1 m behind or in front.
    tools = tool_arrays([tool], 1e12, 1.0, 1)
    return tool_gap(0, p[0], p[1], p[2], r, tools)


BOX = Tool("b", "box", (0, 0, -1), STILL, center=(0, 0, 0), size=(2.0, 2.0, 2.0))
CYL = Tool("c", "cylinder", (0, 0, -1), STILL, center=(0, 0, 0), axis=(0, 0, 1), radius=1.0, length=2.0)


@pytest.mark.parametrize(
    "tool, p, r, gap, normal",
    [
        (BOX, (3.0, 0.0, 0.0), 2.5, -0.5, (1, 0, 0)),  # beside a face
        (BOX, (2.0, 2.0, 0.0), 2.0, math.sqrt(2) - 2.0, (1 / math.sqrt(2), 1 / math.sqrt(2), 0)),  # an edge
        (BOX, (2.0, 2.0, 2.0), 2.0, math.sqrt(3) - 2.0, (1 / math.sqrt(3),) * 3),  # a corner
        (BOX, (0.0, 0.0, 0.8), 0.1, -0.3, (0, 0, 1)),  # inside: leave through the nearest face
        (CYL, (1.5, 0.0, 0.0), 0.7, -0.2, (1, 0, 0)),  # the mantle
        (CYL, (0.0, 0.0, -1.4), 0.5, -0.1, (0, 0, -1)),  # an end
        (CYL, (1.3, 0.0, 1.4), 0.6, 0.5 - 0.6, (0.6, 0, 0.8)),  # the rim: distance sqrt(0.3^2 + 0.4^2)
    ],
)
def test_ball_gap_closed_form(tool, p, r, gap, normal):
    g, nx, ny, nz = _gap(tool, p, r)
    assert g == pytest.approx(gap, abs=1e-12)
    assert (nx, ny, nz) == pytest.approx(normal, abs=1e-12)


def test_clear_and_zero_radius():
    """A ball clear of the tool gets a positive gap (a lower bound: no contact, no normal needed);
    r = 0 gives a point's signed distance inside."""
    assert _gap(BOX, (3.0, 0.0, 0.0), 0.5)[0] == pytest.approx(1.5)
    assert _gap(BOX, (3.0, 3.0, 0.0), 0.5)[0] > 0.0
    assert _gap(BOX, (0.0, 0.5, 0.0), 0.0)[0] == pytest.approx(-0.5)


def test_ball_in_front_of_a_surface_tool():
    """A square plate z = 0 (normal +z): a ball 0.3 above it with r = 0.5 overlaps by 0.2; with
    r = 0.2 it is clear (no triangle within reach: inf)."""
    v = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
    t = np.array([[0, 1, 2], [0, 2, 3]])
    plate = Tool("s", "surface", (0, 0, 1), STILL, vertices=v, triangles=t)
    g, nx, ny, nz = _gap(plate, (0.1, 0.2, 0.3), 0.5)
    assert g == pytest.approx(-0.2) and (nx, ny, nz) == pytest.approx((0, 0, 1))
    assert _gap(plate, (0.1, 0.2, 0.3), 0.2)[0] == math.inf
