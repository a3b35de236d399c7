"""The multi-point study (paper 004, section 3; issue 38 item 2) from a `crackle sweep walnut-layouts`
folder: a markdown table of each layout (plates CN, loading index I, peak force, crack networks,
cracks by the ring rule at 0.75 / 1 / 1.5 x its scale, energy jumps, main-crack speed) and the
figure of the paper's Fig. 8A and Fig. 11: speed against CN and I, crack count against CN.

    python docs/figures/walnut_layouts.py docs/runs/walnut-layouts-1mm-160mms   # writes walnut-layouts.png here
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

HERE = Path(__file__).parent
# The paper's reported trends (its Fig. 8A, Fig. 11 and section 3): the speed rises with CN and I,
# up to about 450 m/s with four points; the count of cracks rises linearly with CN.
PAPER_FOUR_POINT_SPEED = 450.0


def layouts(folder: Path) -> list[dict]:
    """One row per finished run of the sweep folder, in the sweep's order."""
    rows = []
    for run in sorted(p for p in folder.iterdir() if (p / "summary.json").is_file()):
        s = json.loads((run / "summary.json").read_text())
        peaks = s["peak_forces"]
        rows.append({
            "run": run.name, "plates": len(peaks), "I": s["loading_index"], "peak": s["peak_force"],
            "peak_time": s["peak_force_time"], "broken": s["broken"], "networks": len(s["crack_networks"]),
            "cracks": s["cracks"], "at_scales": [n for _, n in s["cracks_at_scales"]], "jumps": s["energy_jumps"],
            "speed": s["crack_speed"] or 0.0, "burst": max((v for _, v in s["crack_speed_history"]), default=0.0),
            "top": s["main_crack"]["reaches_top"], "energy_error": s["energy_error"],
            "wall": s["wall_time"], "status": s["status"],
        })
    return rows


def table(rows: list[dict]) -> str:
    lines = ["| run | CN | I | peak plate force | failed interfaces | networks | cracks at 0.75 / 1 / 1.5 x scale "
             "| energy jumps | main-crack speed (10-90 % of its length) | fastest growth between rows | reaches the apex | energy error | wall time |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['run']} | {r['plates']} | {r['I']:.3f} | {r['peak']:.1f} N at {1e3 * r['peak_time']:.1f} ms "
                     f"| {r['broken']} | {r['networks']} | {' / '.join(map(str, r['at_scales']))} | {r['jumps']} "
                     f"| {r['speed']:.0f} m/s | {r['burst']:.0f} m/s | {'yes' if r['top'] else 'no'} | {100 * r['energy_error']:.1f} % "
                     f"| {r['wall'] / 60:.0f} min |")
    return "\n".join(lines)


def figure(rows: list[dict], path: Path) -> None:
    cn = np.array([r["plates"] for r in rows])
    index = np.array([r["I"] for r in rows])
    speed = np.array([r["speed"] for r in rows])
    burst = np.array([r["burst"] for r in rows])
    jumps = np.array([r["jumps"] for r in rows])
    cracks = np.array([r["cracks"] for r in rows])
    fig, (a, b, c) = plt.subplots(1, 3, figsize=(13, 4))
    sc = a.scatter(cn, speed, c=index, cmap="viridis", label="10-90 % of the main crack's length")
    a.scatter(cn, burst, c=index, cmap="viridis", marker="^", label="fastest growth between rows")
    fig.colorbar(sc, ax=a, label="loading index I")
    a.axhline(PAPER_FOUR_POINT_SPEED, color="0.5", ls="--", label="paper: ~450 m/s, 4 points (its fastest)")
    a.set_xlabel("loading points CN")
    a.set_ylabel("main-crack speed [m/s]")
    a.legend(fontsize=7)
    b.scatter(index, speed, c=cn, cmap="plasma")
    b.scatter(index, burst, c=cn, cmap="plasma", marker="^")
    b.set_xlabel("loading index I")
    b.set_ylabel("main-crack speed [m/s]")
    c.plot(cn, cracks, "o", label="cracks (ring rule)")
    c.plot(cn, jumps, "s", mfc="none", label="energy jumps (paper's Fig. 12 measure)")
    grid = np.arange(cn.min(), cn.max() + 1)
    c.plot(grid, grid, color="0.5", ls="--", label="paper: linear in CN (cracks = CN drawn)")
    c.set_xlabel("loading points CN")
    c.set_ylabel("count")
    c.legend(fontsize=7)
    for ax in (a, b, c):
        ax.grid(True, alpha=0.3)
    fig.suptitle("Walnut multi-point crushing at ~1 mm (29,850 tets), plates at 0.16 m/s")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main(argv=None) -> int:
    folder = Path((argv or sys.argv[1:])[0])
    rows = layouts(folder)
    print(table(rows))
    figure(rows, HERE / "walnut-layouts.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
