"""The failures before the peak around an open flaw at theta = 0, 30 and 60 deg (quick dem-flaw),
coloured by time: where the wing cracks start and how they grow (paper 003 section 4.2).

    python docs/figures/dem_flaw_wings.py      # about 40 s on 2 cores; writes dem-flaw-wings.png here
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from crackle.api import run_scenario
from crackle.io import read_events_csv
from crackle.scenario import load_scenario

ANGLES = (0, 30, 60)


def main() -> None:
    fig, axes = plt.subplots(1, len(ANGLES), figsize=(10, 6), sharey=True)
    with tempfile.TemporaryDirectory() as tmp:
        for ax, angle in zip(axes, ANGLES):
            overrides = [f"flaw.angle={angle}", "run.field_frames=0"]
            result = run_scenario("dem-flaw", Path(tmp) / str(angle), quick=True, progress=False, overrides=overrides)
            flaw = load_scenario("dem-flaw", quick=True, overrides=overrides)[0].flaw
            events = read_events_csv(result.out_dir / "events.csv")
            before = events["time"] <= result.summary["peak_force_time"]
            dots = ax.scatter(events["x"][before] * 1e3, events["z"][before] * 1e3, c=events["time"][before] * 1e3,
                              s=3, cmap="viridis")
            theta, half = math.radians(angle), 0.5 * flaw.length * 1e3
            cx, cz = flaw.center[0] * 1e3, flaw.center[2] * 1e3
            ax.plot([cx - half * math.cos(theta), cx + half * math.cos(theta)],
                    [cz - half * math.sin(theta), cz + half * math.sin(theta)], "r-", lw=3)
            ax.set_aspect("equal")
            ax.set_title(f"theta = {angle} deg\ninitiation {result.summary['flaw_initiation']:.2f}")
            ax.set_xlabel("x (mm)")
    axes[0].set_ylabel("z (mm), loading axis")
    fig.colorbar(dots, ax=axes, label="time of the bond failure (ms)")
    fig.savefig(Path(__file__).with_name("dem-flaw-wings.png"), dpi=80)


if __name__ == "__main__":
    main()
