"""How long things take, said plainly: durations for progress lines and tables."""

from __future__ import annotations

import contextlib
import sys
import time


def duration(seconds: float) -> str:
    """``12.3 s``, ``4 min 05 s``, ``1 h 02 min``."""
    if seconds < 60:
        return f"{seconds:.1f} s"
    minutes, sec = divmod(round(seconds), 60)
    if minutes < 60:
        return f"{minutes} min {sec:02d} s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min"


HEARTBEAT_S = 20.0
"""s: the longest a stage of ``reproduce`` stays silent."""


class PrefixedLines:
    """``log`` a line at once, after ``prefix`` (the run's name: two flights print at once),
    and remember when (for the heartbeat)."""

    def __init__(self, log, prefix: str = ""):
        self.log, self.prefix, self.last = log, prefix, time.perf_counter()

    def __call__(self, line: str) -> None:
        self.last = time.perf_counter()
        text = f"{self.prefix}{line.strip()}"
        self.log(text)


def print_now(line: str) -> None:
    print(line, flush=True)


@contextlib.contextmanager
def heartbeat(lines: PrefixedLines, what: str, interval: float = HEARTBEAT_S):
    """While the block runs, a line through ``lines`` whenever it has been silent for
    ``interval`` s (:data:`HEARTBEAT_S`)."""
    import threading

    t0, done = time.perf_counter(), threading.Event()

    def beat():
        while not done.wait(interval / 4):
            if time.perf_counter() - lines.last >= interval:
                lines(f"  {duration(time.perf_counter() - t0)} elapsed ({what})")

    thread = threading.Thread(target=beat, daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()


def step_progress(total: int, progress):
    """A tqdm bar (``True``, or ``None`` on a terminal), plain lines handed to ``progress``
    every 15 s (a callable: for logs), or nothing."""
    if callable(progress):
        return StepLines(total, progress)
    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="step", desc="closed loop", smoothing=0.05)


class StepLines:
    """The part of tqdm's interface :func:`simulate` uses, as a line every ``interval`` s."""

    def __init__(self, total: int, log, interval: float = 15.0):
        self.total, self.log, self.interval = total, log, interval
        self.n, self.postfix = 0, {}
        self.start = self.last = time.perf_counter()

    def update(self, n: int) -> None:
        self.n += n
        now = time.perf_counter()
        if now - self.last >= self.interval:
            self.last = now
            rate = self.n / (now - self.start)
            extra = ", ".join(f"{k} {v}" for k, v in self.postfix.items())
            self.log(f"  closed loop: {self.n} steps ({rate:.0f} steps/s; at most "
                     f"{self.total}){', ' + extra if extra else ''}")

    def set_postfix(self, **values) -> None:
        self.postfix = values

    def close(self) -> None:
        pass
