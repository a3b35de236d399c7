"""Where the quick borehole's wall fails (the borehole example, FDEM): each failed face of the
first 0.1 ms of failures, and of the whole run, coloured by time, around the hole; sigma_H along
x, sigma_h along y. Breakouts start on the sigma_h axis, where Kirsch's hoop stress is highest.

    python docs/figures/borehole_breakout.py [RUN]   # RUN: a finished `crackle run borehole --quick`
                                                      # folder; without it the run is made (~5 min)
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from crackle.api import run_scenario
from crackle.io import read_events_csv

RADIUS = 0.01  # m, the example's hole


def draw(run: Path, path: Path) -> None:
    events = read_events_csv(run / "events.csv")
    t, x, y = (np.asarray(events[k]) for k in ("time", "x", "y"))
    first = t <= t.min() + 1e-4
    fig, axes = plt.subplots(1, 2, figsize=(10, 5), sharey=True)
    circle = np.linspace(0.0, 2.0 * np.pi, 200)
    for ax, chosen, title in ((axes[0], first, f"first 0.1 ms of failures ({first.sum()})"),
                              (axes[1], np.ones_like(first), f"all {len(t)} failures to {t.max() * 1e3:.2f} ms")):
        ax.plot(RADIUS * 1e3 * np.cos(circle), RADIUS * 1e3 * np.sin(circle), "k-", lw=1)
        dots = ax.scatter(x[chosen] * 1e3, y[chosen] * 1e3, c=t[chosen] * 1e3, s=4, cmap="viridis")
        ax.set_aspect("equal")
        ax.set_xlim(-30, 30)
        ax.set_ylim(-30, 30)
        ax.set_xlabel("x [mm] (sigma_H)")
        ax.set_title(title, fontsize=9)
        fig.colorbar(dots, ax=ax, label="time [ms]", shrink=0.8)
    axes[0].set_ylabel("y [mm] (sigma_h)")
    fig.suptitle("borehole --quick: failed faces around the hole", fontsize=10)
    fig.savefig(path, dpi=110)


def main() -> None:
    target = Path(__file__).with_name("borehole-breakout.png")
    if len(sys.argv) > 1:
        draw(Path(sys.argv[1]), target)
        return
    with tempfile.TemporaryDirectory() as tmp:
        run_scenario("borehole", Path(tmp) / "run", quick=True, progress=False, plots=False,
                     overrides=["run.field_frames=0"])
        draw(Path(tmp) / "run", target)


if __name__ == "__main__":
    main()
