"""The memory guard: a model's size, estimated from its scenario before anything is allocated,
against what the machine can give. A length in the wrong unit (a radius of 1e-5 m meant as
1e-5 of something else) asks for billions of spheres or tets; the set-up says so and exits 2
instead of being killed by the kernel (and taking a neighbour's job with it)."""

from __future__ import annotations

import os

# Bytes per item at the set-up's peak (measured on this project's examples, rounded up: the
# step holds less, docs/validation.md throughput sections): a DEM sphere with its 12 bonds and the
# packer's grids, an FDEM tet (the mesher's and the exploded mesh's share), a meshfree particle
# with its ~60 support links, a shell triangle, a lattice node with its springs.
BYTES_PER = {"spheres": 5_000, "tets": 5_000, "particles": 6_000, "triangles": 3_000, "lattice nodes": 2_000}


class ModelTooLarge(ValueError):
    """The estimated model does not fit in the memory allowed."""


def available_memory() -> int | None:
    """Bytes the kernel says a new allocation can have (MemAvailable), or None where unknown."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def check_model_size(count: float, what: str, key: str, max_memory: float | None, note: str = "") -> None:
    """Raise ModelTooLarge (naming `key`, the scenario value that sets the count, and ending with
    `note`) when `count` items of kind `what` (a BYTES_PER key) would need more than `max_memory`
    bytes (run.max_memory; None: the machine's available memory). A method's set-up calls it
    before allocating; the scenario loader (api.build_simulation) turns it into a ScenarioError."""
    limit, source = max_memory, "run.max_memory"
    if limit is None:
        limit, source = available_memory(), "memory this machine has available"
    if limit is None:
        return
    need = float(count) * BYTES_PER[what]
    if need > limit:
        raise ModelTooLarge(
            f"{key}: the model would have about {count:.3g} {what}, about {_gigabytes(need)} at set-up, more than the "
            f"{_gigabytes(limit)} of {source}; check {key} (lengths are in metres) or, if the size is meant, "
            "set run.max_memory (bytes) on a machine that has it" + note
        )


def _gigabytes(n: float) -> str:
    return f"{n / 1e9:.3g} GB"
