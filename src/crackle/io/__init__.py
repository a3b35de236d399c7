"""Run outputs: history/events CSV, summary JSON, ParaView fields, plots, progress."""

from .fields import FieldWriter, read_pvd
from .outputs import (
    EVENT_COLUMNS,
    FAILURE_MODES,
    EventWriter,
    HistoryWriter,
    RunHistory,
    format_number,
    read_events_csv,
    read_history_csv,
    to_json_compatible,
    write_summary,
)
from .plots import (
    plot_crack_pattern,
    plot_energies,
    plot_crack_growth,
    plot_fragment_sizes,
    plot_load_displacement,
    plot_stress_strain,
    plot_time_steps,
    tool_names,
    write_standard_plots,
)
from .progress import Progress

__all__ = [
    "EVENT_COLUMNS",
    "FAILURE_MODES",
    "EventWriter",
    "FieldWriter",
    "HistoryWriter",
    "RunHistory",
    "Progress",
    "format_number",
    "plot_crack_pattern",
    "plot_energies",
    "plot_crack_growth",
    "plot_fragment_sizes",
    "plot_load_displacement",
    "plot_stress_strain",
    "plot_time_steps",
    "read_events_csv",
    "read_history_csv",
    "read_pvd",
    "to_json_compatible",
    "tool_names",
    "write_standard_plots",
    "write_summary",
]
