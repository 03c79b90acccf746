"""Which tests compile which XLA programs, and for how long: a pytest plugin and its report.

Most of the suite's time is compiling, so this is where to look before making the tests faster:

    .venv/bin/python -m pytest -n auto -p tools.compile_census     # writes .compile_census/*.jsonl
    .venv/bin/python tools/compile_census.py [.compile_census]     # the tables

Each xdist worker writes one JSON line per JAX compile log message (JAX's ``jax_log_compiles``)
with the test that was running; a module fixture's compiles count for the first test that uses it.
Subprocesses a test starts are not seen. ``SIMJAX_COMPILE_CENSUS`` names another folder.
"""

from __future__ import annotations

import collections
import json
import logging
import os
import re
import sys
import time
from pathlib import Path

FOLDER = Path(os.environ.get("SIMJAX_COMPILE_CENSUS", ".compile_census"))
KEEP = ("Finished XLA compilation", "Finished jaxpr to MLIR", "Finished tracing", "cache hit")

_test = {"id": "<collection>"}


class _Handler(logging.Handler):
    def __init__(self, out):
        super().__init__(logging.DEBUG)
        self.out = out

    def emit(self, record):
        message = record.getMessage()
        if any(k in message for k in KEEP):
            self.out.write(json.dumps({"test": _test["id"], "msg": message[:300], "t": time.time()}) + "\n")
            self.out.flush()


def pytest_configure(config):
    import jax

    FOLDER.mkdir(exist_ok=True)
    worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
    out = open(FOLDER / f"{worker}.jsonl", "w")  # open for the whole session
    jax.config.update("jax_log_compiles", True)
    logger = logging.getLogger("jax")
    logger.addHandler(_Handler(out))
    logger.setLevel(logging.DEBUG)


def pytest_runtest_logstart(nodeid, location):
    _test["id"] = nodeid


_SECONDS = {
    "compile": re.compile(r"Finished XLA compilation of (.+?) in ([0-9.e-]+) sec"),
    "lower": re.compile(r"Finished jaxpr to MLIR module conversion (.+?) in ([0-9.e-]+) sec"),
    "trace": re.compile(r"Finished tracing (.+?) for jit in ([0-9.e-]+) sec"),
}


def report(folder: Path, top: int = 30) -> str:
    seconds = {kind: collections.Counter() for kind in _SECONDS}
    programs = collections.defaultdict(list)
    hits = collections.Counter()
    for path in sorted(folder.glob("*.jsonl")):
        for line in path.read_text().splitlines():
            event = json.loads(line)
            test, message = event["test"], event["msg"]
            if "cache hit" in message.lower():
                hits[test] += 1
            for kind, pattern in _SECONDS.items():
                if m := pattern.search(message):
                    seconds[kind][test] += float(m[2])
                    if kind == "compile":
                        programs[m[1]].append((float(m[2]), test))
    total = {kind: sum(c.values()) for kind, c in seconds.items()}
    lines = [f"XLA compile {total['compile']:.0f} s in {sum(map(len, programs.values()))} compiles, "
             f"lowering {total['lower']:.0f} s, tracing {total['trace']:.0f} s, "
             f"persistent-cache hits {sum(hits.values())}", "", "tests by compile seconds:"]
    for test, s in seconds["compile"].most_common(top):
        lines.append(f"{s:8.1f}  lower {seconds['lower'][test]:5.1f}  hits {hits[test]:3d}  {test}")
    lines += ["", "programs by compile seconds (compiles, slowest one, tests):"]
    for name, events in sorted(programs.items(), key=lambda kv: -sum(s for s, _ in kv[1]))[:top]:
        ss = [s for s, _ in events]
        lines.append(f"{sum(ss):8.1f}  n={len(ss):4d}  max {max(ss):6.1f}  tests {len({t for _, t in events}):3d}  {name}")
    return "\n".join(lines)


if __name__ == "__main__":
    print(report(Path(sys.argv[1]) if len(sys.argv) > 1 else FOLDER))
