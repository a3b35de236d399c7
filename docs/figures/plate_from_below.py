"""A perforated meshfree plate seen from below, as an impact experiment photographs it: the last
field frame's particles within HALF of the impact axis, at their current positions projected on
the plate's plane and mirrored (looking up from below), coloured intact / failed / detached.

    python docs/figures/plate_from_below.py OUT [OUT ...] --half 0.025 --png docs/figures/NAME.png

OUT: run output folders (their fields/*.vtu, written with run.field_frames > 0), one panel each.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import meshio
import numpy as np


def last_frame(out: Path):
    frames = sorted((out / "fields").glob("*.vtu"))
    if not frames:
        raise SystemExit(f"{out}: no field frames (run with run.field_frames > 0)")
    return meshio.read(frames[-1])


def panel(ax, out: Path, half: float, title: str) -> None:
    m = last_frame(out)
    x, data = m.points, m.point_data
    failed = np.asarray(data["failed"]).astype(bool).ravel()
    detached = np.asarray(data["detached"]).astype(bool).ravel()
    near = (np.abs(x[:, 0]) < half) & (np.abs(x[:, 1]) < half)
    for mask, colour, label in ((near & ~failed & ~detached, "0.65", "intact"),
                                (near & failed & ~detached, "tab:red", "failed, attached"),
                                (near & detached, "k", "detached")):
        ax.scatter(1e3 * x[mask, 0], -1e3 * x[mask, 1], s=2, c=colour, label=f"{label} ({int(mask.sum())})")
    ax.set_aspect("equal")
    ax.set_xlim(-1e3 * half, 1e3 * half)
    ax.set_ylim(-1e3 * half, 1e3 * half)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("-y [mm] (from below)")
    ax.set_title(title, fontsize=9)
    ax.legend(loc="upper right", fontsize=7, markerscale=3)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("outs", nargs="+", type=Path)
    parser.add_argument("--half", type=float, default=0.025, help="m, half the window about the axis")
    parser.add_argument("--titles", nargs="*", default=None)
    parser.add_argument("--png", type=Path, required=True)
    args = parser.parse_args()
    titles = args.titles or [out.name for out in args.outs]
    fig, axes = plt.subplots(1, len(args.outs), figsize=(4.2 * len(args.outs), 4.4), squeeze=False)
    for ax, out, title in zip(axes[0], args.outs, titles):
        panel(ax, out, args.half, title)
    fig.tight_layout()
    fig.savefig(args.png, dpi=110)
    print(args.png)


if __name__ == "__main__":
    main()
