"""Small unit helpers shared by plots and the progress bar."""

import math


def time_unit(t_max: float) -> tuple[float, str]:
    """Pick a readable time unit for values up to ``t_max`` seconds.

    Returns ``(scale, label)``: multiply seconds by ``scale`` to get ``label``.
    Dynamic fracture runs last microseconds to milliseconds, so those are the
    usual answers; seconds only for quasi-static runs.
    """
    t = abs(float(t_max)) if t_max is not None else 0.0
    if not math.isfinite(t) or t < 1e-3:
        return 1e6, "µs"
    if t < 1.0:
        return 1e3, "ms"
    return 1.0, "s"


def duration_text(seconds: float) -> str:
    """A wall time as a person reads it: '45 s', '12 min', '3.5 h' ('?' for nan: not known yet)."""
    if seconds != seconds:
        return "?"
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"
