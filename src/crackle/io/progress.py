"""Progress bar for long runs, drawn with rich only on an interactive terminal."""

from __future__ import annotations

import contextlib
import errno
import json
import os
import sys
from datetime import datetime, timezone
from pathlib import Path
from time import monotonic

from ._units import duration_text, time_unit


def _stdout_is_terminal() -> bool:
    try:
        return sys.stdout.isatty()
    except (AttributeError, ValueError):  # replaced or closed stdout
        return False


class _GuardedStream:
    """stdout or stderr that survives its reader going away (a pipe closed: `crackle run ... |
    head`; a terminal closed: EIO; a log file on a full disk or past ulimit -f): the first failed
    write sends the stream to the null device from then on (its file descriptor too, so that
    nothing buffered fails at exit) and calls `on_lost` with how it was lost, once."""

    LOST = (errno.EPIPE, errno.EIO, errno.ENOSPC, errno.EFBIG)

    def __init__(self, stream, on_lost):
        if stream is None:  # closed from the start (`crackle run ... >&-`): output nobody asked to see
            stream = open(os.devnull, "w")
        self._stream, self._on_lost, self._lost = stream, on_lost, False

    def _guard(self, call, *args):
        try:
            return call(*args)
        except OSError as err:
            if err.errno not in self.LOST:
                raise
            if not self._lost:
                self._lost = True
                with contextlib.suppress(OSError, ValueError):
                    null = os.open(os.devnull, os.O_WRONLY)
                    os.dup2(null, self._stream.fileno())
                    os.close(null)
                self._on_lost("closed" if err.errno in (errno.EPIPE, errno.EIO) else f"failed: {err.strerror}")
            return None

    def write(self, text):
        return len(text) if self._lost else (self._guard(self._stream.write, text) or len(text))

    def flush(self):
        if not self._lost:
            self._guard(self._stream.flush)

    def __getattr__(self, name):
        return getattr(self._stream, name)


@contextlib.contextmanager
def guarded_standard_streams(on_lost):
    """sys.stdout and sys.stderr as _GuardedStreams for the block; `on_lost(what)` when one is lost
    ("stdout closed", "stderr failed: No space left on device")."""
    saved = sys.stdout, sys.stderr
    sys.stdout = _GuardedStream(saved[0], lambda how: on_lost(f"stdout {how}"))
    sys.stderr = _GuardedStream(saved[1], lambda how: on_lost(f"stderr {how}"))
    try:
        yield
    finally:
        sys.stdout, sys.stderr = saved


def _log_interval(default: float = 30.0) -> float:
    """Wall seconds between the plain progress lines of a run without a terminal: CRACKLE_LOG_INTERVAL
    (a cluster log may want fewer), else `default`; a value that is no positive number says so and
    takes the default (it must not stop crackle from starting)."""
    text = os.environ.get("CRACKLE_LOG_INTERVAL", "").strip()
    if not text:
        return default
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not 0.0 < value < float("inf"):
        print(f"crackle: CRACKLE_LOG_INTERVAL={text!r} is not a positive number of seconds; using {default:g}",
              file=sys.stderr)
        return default
    return value


LOG_INTERVAL = _log_interval()


class Progress:
    """Shows simulated time, steps/s, broken count and ETA.

    ``enabled=None`` means: only when stdout is a terminal, so logs and CI
    output stay clean. Even when enabled, nothing is drawn before the run
    has lasted ``delay`` seconds (default 1 s). ``update`` is cheap: between
    redraws (every ``refresh_interval`` s) it only reads the clock. ``stage``
    shows at once what the run is doing before its first step (e.g. compiling
    kernels); ``note`` prints a line above the bar.

    Without a bar (no terminal: a piped run, a batch job's log), ``log`` (a
    callable taking a line) gets a plain progress line every ``log_interval``
    wall seconds: time, per cent, steps/s, broken, ETA.
    """

    def __init__(
        self,
        end_time: float,
        enabled: bool | None = None,
        delay: float = 1.0,
        refresh_interval: float = 0.1,
        log=None,
        log_interval: float = LOG_INTERVAL,
        status_path=None,
    ):
        self.end_time = float(end_time)
        self.enabled = _stdout_is_terminal() if enabled is None else bool(enabled)
        self.delay = float(delay)
        self.refresh_interval = float(refresh_interval)
        self._scale, self._unit = time_unit(self.end_time)
        self._bar = None
        self._task = None
        self._last = (0.0, 0, 0)  # latest (time, steps, broken)
        self._stage = ""
        self.log = None if self.enabled else log
        self.log_interval = float(log_interval)
        self.status_path = None if status_path is None else Path(status_path)
        self._restart_clock()

    def _restart_clock(self) -> None:
        self._start = monotonic()
        self._next_draw = self._start + self.delay
        self._rate = None
        self._rate_mark = (self._start, 0)  # (wall time, steps) of the last redraw
        self._log_mark = None  # (wall time, simulated time, steps) at the first update, then at each line
        self._log_first = None

    def __enter__(self) -> Progress:
        self._restart_clock()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def update(self, time: float, steps: int, broken: int) -> None:
        if self.log is not None or self.status_path is not None:
            self._log_line(monotonic(), float(time), int(steps), int(broken))
        if not self.enabled:
            return
        self._last = (time, steps, broken)
        now = monotonic()
        if now < self._next_draw:
            return
        self._next_draw = now + self.refresh_interval
        if self._bar is None:
            self._open_bar()
        self._draw(now)

    def stage(self, text: str) -> None:
        """Show `text` beside the bar now (opening it), or clear it with ""."""
        if not self.enabled:
            return
        self._stage = text
        if self._bar is None and text:
            self._open_bar()
        if self._bar is not None:
            self._draw(monotonic())

    def note(self, text: str, fallback=print) -> None:
        """A line of text above the bar (through `fallback` while no bar is drawn)."""
        if self._bar is not None:
            self._bar.console.print(text, highlight=False, markup=False)
        else:
            fallback(text)

    def _open_bar(self) -> None:
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            TaskProgressColumn,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )
        from rich.progress import Progress as RichProgress

        self._bar = RichProgress(
            TextColumn("t = {task.fields[sim_time]}"),
            BarColumn(),
            TaskProgressColumn(),
            TextColumn("{task.fields[rate]} steps/s"),
            TextColumn("broken {task.fields[broken]}"),
            TimeElapsedColumn(),
            TextColumn("ETA"),
            TimeRemainingColumn(),
            TextColumn("{task.fields[stage]}"),
            console=Console(file=sys.stdout),
            auto_refresh=False,  # we redraw from update(): no background thread
        )
        self._task = self._bar.add_task(
            "run", total=self.end_time, sim_time="", rate="", broken=0, stage=""
        )
        self._bar.start()

    def _draw(self, now: float) -> None:
        time, steps, broken = self._last
        mark_time, mark_steps = self._rate_mark
        if now > mark_time:
            rate = (steps - mark_steps) / (now - mark_time)
            # Smooth the rate so the number is readable while it changes.
            self._rate = rate if self._rate is None else 0.7 * self._rate + 0.3 * rate
            self._rate_mark = (now, steps)
        self._bar.update(
            self._task,
            completed=min(float(time), self.end_time),
            sim_time=f"{float(time) * self._scale:.4g} / "
                     f"{self.end_time * self._scale:.4g} {self._unit}",
            rate=f"{self._rate or 0.0:,.0f}",
            broken=int(broken),
            stage=self._stage,
        )
        self._bar.refresh()

    def _log_line(self, now: float, time: float, steps: int, broken: int) -> None:
        """Every log_interval: the progress line (without a terminal) and status.json."""
        if self._log_mark is None:
            self._log_mark = self._log_first = (now, time, steps)
            self._write_status("running", now, time, steps, broken, 0.0, float("nan"))
            return
        if now - self._log_mark[0] < self.log_interval:
            return
        wall0, time0, _ = self._log_first
        rate = (steps - self._log_mark[2]) / (now - self._log_mark[0])
        done = min(time / self.end_time, 1.0) if self.end_time > 0 else 1.0
        eta = (now - wall0) * (self.end_time - time) / (time - time0) if time > time0 else float("nan")
        self._log_mark = (now, time, steps)
        self._write_status("running", now, time, steps, broken, rate, eta)
        if self.log is not None:
            self.log(f"  t = {time * self._scale:.4g} / {self.end_time * self._scale:.4g} {self._unit} ({done:.0%}), "
                     f"{steps:,} steps, {rate:,.0f} steps/s, broken {broken:,}, ETA {duration_text(eta)}")

    def _write_status(self, state: str, now: float, time: float, steps: int, broken: int, rate: float, eta: float):
        """status.json for tools that poll a running job (written, then renamed into place)."""
        if self.status_path is None:
            return
        record = {"state": state, "time": time, "end_time": self.end_time, "fraction": min(time / self.end_time, 1.0),
                  "steps": steps, "steps_per_second": rate, "broken": broken,
                  "eta_seconds": None if eta != eta else eta, "wall_seconds": now - self._start,
                  "updated": datetime.now(timezone.utc).isoformat(timespec="seconds")}
        tmp = self.status_path.with_name(self.status_path.name + ".tmp")
        try:
            tmp.write_text(json.dumps(record, indent=1) + "\n")
            os.replace(tmp, self.status_path)
        except OSError:
            pass  # a progress report is not worth stopping a run for (a full disk stops it at its next row)

    def finish(self, state: str, time: float, steps: int, broken: int) -> None:
        """The run's last status.json: `state` its status (completed, stopped, interrupted ...)."""
        now = monotonic()
        first = self._log_first
        rate = (steps - first[2]) / (now - first[0]) if first is not None and now > first[0] else 0.0
        self._write_status(state, now, time, steps, broken, rate, 0.0)

    def close(self) -> None:
        """Draw the final state (if the bar was shown) and release the terminal."""
        if self._bar is not None:
            self._draw(monotonic())
            self._bar.stop()
            self._bar = None
