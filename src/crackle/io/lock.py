"""One writer per output folder: a run holds `.crackle.lock` in its folder while it runs."""

from __future__ import annotations

import json
import os
import socket
import sys
import time
from pathlib import Path

LOCK_FILE = ".crackle.lock"


class FolderBusy(RuntimeError):
    """Another live run writes into the folder."""


def _alive(pid: int) -> bool:
    if pid <= 0:  # no process (a lock left half-written); os.kill(-1, 0) would ask about every process
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process: alive
        return True
    return True


class OutputLock:
    """Held from before the set-up to after the last output. A second run into the same folder
    raises FolderBusy naming the holder (pid, host, start, command). A lock left by a run that was
    killed (its process gone, on this host) is taken over; one from another host cannot be
    checked and is refused with the advice to delete it if that run is over. A lock copied with
    its folder names the folder it was taken in and is not this folder's. A folder the lock made
    and nobody wrote into (a run refused at set-up) is removed with it."""

    def __init__(self, folder: Path):
        self.path = Path(folder) / LOCK_FILE
        self.taken_over: dict | None = None  # the stale holder, when its lock was taken over
        self._held = False

    def __enter__(self) -> OutputLock:
        folder = self.path.parent
        self._made = [p for p in (folder, *folder.parents) if not p.exists()]
        folder.mkdir(parents=True, exist_ok=True)
        me = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.strftime("%Y-%m-%d %H:%M:%S"),
              "command": " ".join(sys.argv), "folder": str(folder.resolve())}
        for _ in range(3):  # a stale lock removed by a racing run: try again
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                holder = self._holder()
                if holder is None:
                    time.sleep(0.2)  # gone in between, or being written now: retry
                    continue
                copied = holder.get("folder", me["folder"]) != me["folder"]
                if copied or (holder.get("host") == me["host"] and not _alive(int(holder.get("pid", -1)))):
                    self.taken_over = holder
                    self.path.unlink(missing_ok=True)
                    continue
                where = f"pid {holder.get('pid')} on {holder.get('host')}, started {holder.get('started')}"
                advice = ("" if holder.get("host") == me["host"] else
                          f"; if that run is over, delete {self.path}")
                raise FolderBusy(f"{self.path.parent} is the output folder of a run still going ({where}: "
                                 f"{holder.get('command', '?')}); give another --out or wait for it{advice}")
            with os.fdopen(fd, "w") as f:
                json.dump(me, f)
            self._held = True
            return self
        raise FolderBusy(f"could not take the lock {self.path}; retry")

    def _holder(self) -> dict | None:
        try:
            text = self.path.read_text()
        except FileNotFoundError:
            return None
        try:
            return json.loads(text)
        except json.JSONDecodeError:
            # Written by a run killed between creating and filling it, or being written now.
            age = time.time() - self.path.stat().st_mtime if self.path.exists() else 0.0
            return {"pid": -1, "host": socket.gethostname()} if age > 5.0 else None

    def __exit__(self, *exc) -> None:
        if self._held:
            self.path.unlink(missing_ok=True)
            self._held = False
            for made in self._made:  # innermost first; stops at the first that holds something
                try:
                    made.rmdir()
                except OSError:
                    break
