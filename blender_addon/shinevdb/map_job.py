"""One ``shine map`` run in a child process, observed without blocking (no Blender API here).

Two threads read the child's stdout and stderr line by line into a queue; :meth:`MapJob.poll`,
called from Blender's main thread, drains the queue and parses ``shine``'s progress lines. When
stderr is not a terminal (a pipe, here) ``shine`` writes each progress update as its own line::

    train      [############............] 151/300  1.4 s, ETA 1 s  bce 0.3829
    train      [########################] 300/300  2.7 s

and a failure as one ``shine: error: <message>`` line with a non-zero exit code.
"""

from __future__ import annotations

import collections
import queue
import re
import signal
import subprocess
import threading
from dataclasses import dataclass
from typing import List, Optional

_PROGRESS_LINE = re.compile(
    r"^(?P<stage>\S+)\s+\[[#.]*\]\s+(?P<done>\d+)/(?P<total>\d+)\s+(?P<seconds>[\d.]+) s"
    r"(?:, ETA (?P<eta>\d+) s)?(?:\s+(?P<detail>.*))?$"
)
_ERROR_PREFIX = "shine: error:"
_STDERR_LINES_KEPT = 20  # enough context for a failure without an error line


@dataclass(frozen=True)
class Progress:
    """One parsed progress line of a ``shine`` stage (load, train, ...)."""

    stage: str
    done: int
    total: int
    seconds: float
    eta_s: Optional[int]  # None on a stage's final line and until the estimate is stable
    detail: str

    @property
    def fraction(self) -> float:
        """How much of the stage is done, in [0, 1]."""
        return min(1.0, self.done / self.total) if self.total > 0 else 0.0


def parse_progress_line(line: str) -> Optional[Progress]:
    """Parses a ``shine`` progress line; returns None for any other line."""
    match = _PROGRESS_LINE.match(line.strip())
    if match is None:
        return None
    return Progress(
        stage=match["stage"],
        done=int(match["done"]),
        total=int(match["total"]),
        seconds=float(match["seconds"]),
        eta_s=int(match["eta"]) if match["eta"] is not None else None,
        detail=(match["detail"] or "").strip(),
    )


class MapJob:
    """Starts ``command`` (a ``shine map`` invocation) and tracks its progress and outcome."""

    def __init__(self, command: List[str]):
        """Starts the child process.

        Raises:
            OSError: the program cannot be started.
        """
        self.progress: Optional[Progress] = None
        self.stdout_lines: List[str] = []
        self._stderr_tail = collections.deque(maxlen=_STDERR_LINES_KEPT)
        self._error_line: Optional[str] = None
        self._cancelled = False
        self._lines: "queue.Queue[tuple[str, str]]" = queue.Queue()
        self._process = subprocess.Popen(
            command,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,  # universal newlines: a terminal-style "\r" also ends a line
            encoding="utf-8",
            errors="replace",
            bufsize=1,
        )
        self._readers = [
            threading.Thread(target=self._read, args=(stream, name), daemon=True)
            for stream, name in ((self._process.stdout, "stdout"), (self._process.stderr, "stderr"))
        ]
        for reader in self._readers:
            reader.start()

    def _read(self, stream, name: str) -> None:
        """Reader thread: queues each line of one output stream until it closes."""
        for line in stream:
            self._lines.put((name, line.rstrip("\n")))
        stream.close()

    def poll(self) -> bool:
        """Takes in the output so far; returns True while the job is still running."""
        running = self._process.poll() is None or any(r.is_alive() for r in self._readers)
        while True:
            try:
                name, line = self._lines.get_nowait()
            except queue.Empty:
                break
            if name == "stdout":
                self.stdout_lines.append(line)
                continue
            progress = parse_progress_line(line)
            if progress is not None:
                self.progress = progress
            elif line.strip():
                self._stderr_tail.append(line)
                if line.startswith(_ERROR_PREFIX):
                    self._error_line = line[len(_ERROR_PREFIX):].strip()
        return running

    def cancel(self) -> None:
        """Asks ``shine`` to stop (SIGTERM). ``shine`` writes each output under a temporary name
        and renames it when complete, so an output file is either whole or absent."""
        if self._process.poll() is None:
            self._cancelled = True
            self._process.terminate()

    @property
    def cancelled(self) -> bool:
        """True if :meth:`cancel` stopped the job."""
        return self._cancelled

    @property
    def succeeded(self) -> bool:
        """True once the job has ended with exit code 0."""
        return self._process.poll() == 0 and not self._cancelled

    def error_message(self) -> str:
        """Why the finished job failed: ``shine``'s error line, else its exit status and output."""
        if self._cancelled:
            return "cancelled"
        if self._error_line:
            return self._error_line
        code = self._process.poll()
        if code is not None and code < 0:
            status = f"shine was killed by signal {signal.Signals(-code).name}"
        else:
            status = f"shine exited with code {code}"
        tail = " / ".join(list(self._stderr_tail)[-3:])
        return f"{status}: {tail}" if tail else status
