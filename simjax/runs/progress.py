"""The training progress line a person watches (metrics.csv is the record)."""

from __future__ import annotations

import datetime as dt
import math
import sys


class Progress:
    """A one-line progress bar on stderr (plain lines when stderr is not a terminal)."""

    def __init__(self, total: int, quiet: bool, num_seeds: int = 1):
        self.total, self.quiet, self.tty = total, quiet, sys.stderr.isatty()
        self.num_seeds = num_seeds

    def update(self, done: int, steps_per_s: float, success: float, length: float):
        """``done``/``total`` count agent steps per seed; ``steps_per_s`` counts all seeds'."""
        if self.quiet:
            return
        frac = done / self.total
        bar = "#" * int(30 * frac) + "." * (30 - int(30 * frac))
        eta = (self.total - done) * self.num_seeds / max(steps_per_s, 1e-9)
        line = (
            f"[{bar}] {done:,}/{self.total:,} steps per seed | {steps_per_s:,.0f} steps/s | "
            f"success {success:.2f} | ep len {length:.0f} | ETA {dt.timedelta(seconds=int(eta))}"
        )
        print(("\r" + line) if self.tty else line, end="" if self.tty else "\n", file=sys.stderr, flush=True)

    def close(self):
        if self.tty and not self.quiet:
            print(file=sys.stderr)


def mean_over_seeds(values) -> float:
    """Mean over seeds, ignoring seeds in which no episode ended (NaN)."""
    finite = [float(v) for v in values if math.isfinite(float(v))]
    return sum(finite) / len(finite) if finite else float("nan")
