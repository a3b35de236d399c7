"""Fields on the meshfree method's links, shared by its patch tests: the MLS approximation and
the (smoothed) gradient of nodal values, and the errors of a linear field through both."""

from __future__ import annotations

import numpy as np

from crackle.meshfree.kernels import LINK_FLOAT
from crackle.meshfree.shape import neighbour_links, shape_functions, smoothed_gradients

# The step stores the links' gradients and values in single precision (kernels.LINK_FLOAT): what
# rests on their rounding holds to that precision, here with a margin of 10.
ROUNDING = 10.0 * float(np.finfo(LINK_FLOAT).eps)

# u = A X + b, the linear field of the patch tests.
LINEAR_A = np.array([[0.3, -0.1, 0.2], [0.05, 0.1, -0.4], [0.7, 0.2, 0.1]])
LINEAR_B = np.array([1e-3, -2e-3, 3e-3])


def approximated(start, neighbour, value, u):
    """Per particle I, sum_J N_J(X_I) u_J over its links (CSR start, neighbour; `value` per link)."""
    row = np.repeat(np.arange(len(start) - 1), np.diff(start))
    out = np.zeros((len(start) - 1,) + u.shape[1:])
    np.add.at(out, row, (value.reshape((-1,) + (1,) * (u.ndim - 1))) * u[neighbour])
    return out


def gradient(start, neighbour, grad, u):
    """Per particle I, sum_J u_J (x) grad N_J(I) (n, 3, 3) over its links."""
    row = np.repeat(np.arange(len(start) - 1), np.diff(start))
    out = np.zeros((len(start) - 1, 3, 3))
    np.add.at(out, row, u[neighbour][:, :, None] * grad[:, None, :])
    return out


def linear_field_errors(X, volume, cells, radius, terms):
    """For u = LINEAR_A X + LINEAR_B: the largest error of the MLS values at the particles
    relative to max |u|, and of the gradients smoothed over the cells relative to max |A|
    (asserting that no moment matrix was singular)."""
    u = X @ LINEAR_A.T + LINEAR_B
    start, neighbour, _ = neighbour_links(X, radius)
    value, _, _ = shape_functions(X, volume, start, neighbour, radius, terms)
    value_error = np.max(np.abs(approximated(start, neighbour, value, u) - u)) / np.max(np.abs(u))
    start, neighbour, grad, _, bad = smoothed_gradients(X, volume, cells, radius, terms)
    assert bad is None
    gradient_error = np.max(np.abs(gradient(start, neighbour, grad, u) - LINEAR_A)) / np.max(np.abs(LINEAR_A))
    return value_error, gradient_error
