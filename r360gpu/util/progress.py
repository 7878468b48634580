"""Progress reporting: a bar on a terminal, plain periodic lines anywhere else.

A redrawn bar written to a log file or a pipe is a wall of carriage returns,
so when the stream is not a terminal :func:`progress` prints one line every
``every_s`` seconds or every 10% of the items, whichever comes first, and a
last line when done; each line before the last says how long the rest should
take at the rate so far (the bar shows the same).
"""
from __future__ import annotations

import sys
import time


def progress(items, *, desc: str, unit: str = "view", enabled: bool = True, stream=None,
             every_s: float = 10.0, clock=time.monotonic):
    """Iterate over ``items`` reporting progress on ``stream`` (default stderr)."""
    if not enabled:
        return items
    stream = stream if stream is not None else sys.stderr
    isatty = getattr(stream, "isatty", None)
    if isatty is not None and isatty():
        from tqdm import tqdm

        return tqdm(items, desc=desc, unit=unit, dynamic_ncols=True, leave=True, file=stream)
    return _lines(items, desc, unit, stream, every_s, clock)


def _lines(items, desc, unit, stream, every_s, clock):
    items = list(items)
    n = len(items)
    t0 = last_t = clock()
    step = max(1, -(-n // 10))  # ceil(n / 10): at most ~10 lines from the count
    last_i = 0
    for i, item in enumerate(items, start=1):
        yield item
        now = clock()
        if i == n or i - last_i >= step or now - last_t >= every_s:
            rate = i / (now - t0) if now > t0 else 0.0
            print(f"{desc}: {i}/{n} {unit}s ({100 * i // max(n, 1)}%), {now - t0:.1f} s"
                  + (f", {rate:.2f} {unit}s/s" if rate else "")
                  + (f", about {duration((n - i) / rate)} left" if rate and i < n else ""), file=stream, flush=True)
            last_i, last_t = i, now


def duration(seconds: float) -> str:
    """A time span for a person: "40 s", "12 min", "3.5 h"."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 90 * 60:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"
