"""The set-up recipe every method shares (solver.setup): the pieces a method calls with its own."""

from __future__ import annotations

import numpy as np
import pytest

from crackle.loading import History, Selection, Support, Tool
from crackle.scenario import ScenarioError
from crackle.solver.body import Body, body_arrays, pair_incidence
from crackle.solver.setup import supports_on, tool_stiffness, tools_on_body


def test_pair_incidence_lists_each_point_s_pairs_in_order_with_their_sign():
    # Pairs 0-1, 1-2, 0-2: point 0 is a of pairs 0 and 2, point 2 is b of pairs 1 and 2.
    start, pair, sign = pair_incidence(3, np.array([0, 1, 0]), np.array([1, 2, 2]))
    assert start.tolist() == [0, 2, 4, 6]
    assert pair.tolist() == [0, 2, 0, 1, 1, 2]
    assert sign.tolist() == [-1, -1, 1, -1, 1, 1]


def test_a_support_that_holds_nothing_is_the_scenario_s_error():
    points = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    off_the_body = Support("fixed", Selection(plane_point=(0.0, 0.0, 5.0), plane_normal=(0.0, 0.0, 1.0)))
    with pytest.raises(ScenarioError, match=r"supports: supports\.0: the fixed support selects no node"):
        supports_on([off_the_body], points, 1.0)


def test_tools_on_body_seats_the_points_and_gives_the_stiffest_spring():
    """Two planes, penalties 1e12 and 3e12 Pa/m: each point's tool spring for the stable step is
    3e12 x its area; without tools, 0. A plane asked to seat the point inside it does so and
    says how many."""
    x = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    body = Body(**body_arrays(x, np.ones(2), np.array([2e-4, 1e-4]), 0.0))
    still = History.constant(0.0)
    floor = Tool("floor", "plane", (0.0, 0.0, 1.0), still, center=(0.0, 0.0, 0.1), normal=(0.0, 0.0, 1.0),
                 penalty=1e12, seat=True)
    wall = Tool("wall", "plane", (1.0, 0.0, 0.0), still, center=(-5.0, 0.0, 0.0), normal=(1.0, 0.0, 0.0),
                penalty=3e12)
    table, notes = tools_on_body([floor, wall], body, 1e11, 0.01, 1, "nodes")
    assert tool_stiffness(table, body.area).tolist() == [6e8, 3e8]
    assert notes == ["tool floor: 1 nodes inside it at set-up start unloaded there (seat = true)"]
    assert body.tool[0] == 0 and body.tool[1] != 0  # the point inside the floor is seated on it
    empty, none = tools_on_body([], body, 1e11, 0.01, 1)
    assert tool_stiffness(empty, body.area).tolist() == [0.0, 0.0] and none == []
