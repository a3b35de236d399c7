"""Fragments: connected pieces of a specimen after fracture."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components


@dataclass(frozen=True)
class Fragments:
    labels: np.ndarray  # fragment id of each element, 0..count-1, largest fragment first
    masses: np.ndarray  # kg, descending
    velocities: np.ndarray  # (count, 3) m/s, mass-weighted mean velocity of each fragment

    @property
    def count(self) -> int:
        return len(self.masses)

    @property
    def largest_mass_fraction(self) -> float:
        return float(self.masses[0] / self.masses.sum()) if self.count else 0.0


def find_fragments(n_elements: int, links: np.ndarray, element_mass: np.ndarray, element_velocity: np.ndarray) -> Fragments:
    """Connected components of elements joined by unbroken links ((k, 2) element pairs).

    Fragments are numbered by decreasing mass (ties by lowest element index), so that ids are
    stable and reproducible."""
    links = np.asarray(links, dtype=np.int64).reshape(-1, 2)
    graph = coo_matrix((np.ones(len(links)), (links[:, 0], links[:, 1])), shape=(n_elements, n_elements))
    count, raw = connected_components(graph, directed=False)
    mass = np.bincount(raw, weights=element_mass, minlength=count)
    first = np.full(count, n_elements, dtype=np.int64)
    np.minimum.at(first, raw, np.arange(n_elements))
    order = np.lexsort((first, -mass))
    rank = np.empty(count, dtype=np.int64)
    rank[order] = np.arange(count)
    labels = rank[raw]
    momentum = np.stack([np.bincount(labels, weights=element_mass * element_velocity[:, d], minlength=count) for d in range(3)], axis=1)
    masses = mass[order]
    return Fragments(labels, masses, momentum / masses[:, None])
