"""Suite-wide settings, applied before any test imports crackle."""

import os

if os.environ.get("PYTEST_XDIST_WORKER"):
    # The suite runs in two worker processes (pyproject's addopts: -n 2), one per core: each steps
    # with one numba thread and lets it sleep between parallel loops, so the two never fight for a
    # core (the thread-count comparisons start their own processes with 1 and 2 threads).
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    import numba

    numba.set_num_threads(1)
else:
    # crackle makes numba's OpenMP threads sleep between parallel loops (OMP_WAIT_POLICY=PASSIVE,
    # src/crackle/__init__.py): robust on a shared machine, but a single process's small models
    # step ~1.5x slower that way on a machine of their own (tests/test_brazilian_disc.py +
    # test_sphere_impact.py: 169 s against 118 s spinning), so it lets the threads spin; results
    # do not depend on the wait policy. test_cli.py checks crackle's own default.
    os.environ.setdefault("OMP_WAIT_POLICY", "ACTIVE")

import fcntl  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import pytest  # noqa: E402

# The compiled kernels, made once for the whole suite before its tests run: each worker takes the
# next group no one holds (a lock file shared by the workers), compiles it with a three-step run
# of an example (numba writes its cache under src/), then waits for the groups the other worker
# took. Without this, both workers and the thread tests' subprocesses compiled the same kernels
# side by side (the FDEM ones take ~4 minutes on one core). Longest first, so the two balance.
WARM_UPS = (
    ("fdem", "three-point-bending", []),
    ("fdem-bilinear", "walnut-crush", []),
    ("dem", "dem-tension", []),
    ("fdem-extrinsic", "direct-tension", ["material.interface.insertion=extrinsic"]),
    ("meshfree", "plate-impact", []),
    ("shell", "shell-centre-crack", []),
    ("fdem-surface-contact", "sphere-impact-fast", []),
)


def _warm_up(example: str, extra: list[str], out: Path) -> None:
    from crackle.api import run_scenario

    try:
        run_scenario(example, out, quick=True, progress=False, plots=False, overrides=[
            "run.dt=1e-10", "run.end_time=3e-10", "run.history_samples=3", "run.field_frames=0", *extra])
    except Exception as err:  # the tests of that example say what is wrong; the others go on
        warnings.warn(f"warming up the kernels with {example} failed: {err}")


@pytest.fixture(scope="session", autouse=True)
def compiled_kernels(tmp_path_factory):
    shared = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        shared = shared.parent  # the workers' folders sit side by side in one per session
    waiting = []
    for group, example, extra in WARM_UPS:
        handle = open(shared / f"warm-up-{group}.lock", "a+")
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            waiting.append(handle)  # the other worker compiles it
            continue
        done = shared / f"warm-up-{group}.done"
        if not done.exists():
            _warm_up(example, extra, shared / f"warm-up-{group}")
            done.touch()
        fcntl.flock(handle, fcntl.LOCK_UN)
        handle.close()
    for handle in waiting:
        fcntl.flock(handle, fcntl.LOCK_EX)
        fcntl.flock(handle, fcntl.LOCK_UN)
        handle.close()
