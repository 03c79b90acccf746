"""The guard against XLA:CPU stalls: a watchdog in the training process and a supervisor that
restarts it from its checkpoint.

jaxlib 0.10.2 on XLA:CPU now and then never signals a finished computation (see
``simjax.runtime``); the process then waits forever and ignores Ctrl-C. Everything a run has
written is on disk by then (``simjax.runs.folder``), so the worker exits with ``STALLED`` and
the supervisor starts it again on the same run folder.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

from simjax.runs.folder import checkpoint_steps

STALLED = 75  # exit status of a worker whose XLA computation stopped making progress


class StallWatchdog:
    """Ends the process with ``STALLED`` when one compiled call makes no progress for too long.

    The first call of a process may take ``first_limit`` seconds; later ones max(60 s, 4 x the
    slowest call so far). Wrap each watched call in ``begin()`` and ``end()``.
    """

    def __init__(self, first_limit: float):
        self.first_limit, self.slowest, self.started = first_limit, 0.0, None
        self._lock = threading.Lock()
        threading.Thread(target=self._watch, daemon=True).start()

    def begin(self):
        with self._lock:
            self.started = time.perf_counter()

    def end(self, record: bool = True):
        with self._lock:
            if record:
                self.slowest = max(self.slowest, time.perf_counter() - self.started)
            self.started = None

    def limit(self) -> float:
        return self.first_limit if self.slowest == 0.0 else max(60.0, 4.0 * self.slowest)

    def _watch(self):
        while True:
            time.sleep(1.0)
            with self._lock:
                stuck = self.started is not None and time.perf_counter() - self.started > self.limit()
            if stuck:
                print(f"\nno progress for {self.limit():.0f} s (XLA:CPU stall); exiting to resume "
                      "from the last checkpoint", file=sys.stderr, flush=True)
                os._exit(STALLED)


def supervise(worker: Callable[[float], list[str]], run_dir: Path, max_restarts: int,
              stall_timeout: float = 300.0) -> int:
    """Run ``worker(limit)`` (the command of a training process on ``run_dir`` whose first
    call may take ``limit`` seconds) in a child process; restart it from the last checkpoint
    each time it exits ``STALLED``. A worker that stalls again without having added a row gets
    twice the time for its first call (in case that call is just slow). Ctrl-C reaches both
    processes; the worker saves and stops. Returns the worker's exit status."""
    limit, steps = stall_timeout, checkpoint_steps(run_dir)
    for attempt in range(max_restarts + 1):
        proc = subprocess.Popen(worker(limit))
        try:
            code = proc.wait()
        except KeyboardInterrupt:
            try:  # the worker got the same Ctrl-C and is saving; a stalled one cannot, so end it
                code = proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                code = proc.wait()
            return 130
        if code != STALLED:
            return code
        now = checkpoint_steps(run_dir)
        limit = limit * 2 if now == steps else stall_timeout
        steps = now
        print(f"restarting from the checkpoint in {run_dir} ({attempt + 1} of {max_restarts})", file=sys.stderr,
              flush=True)
    print(f"gave up after {max_restarts} restarts; resume with --resume {run_dir}", file=sys.stderr)
    return STALLED
