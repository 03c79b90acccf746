"""Table of a runs.jsonl (default: the one beside this file; the 2026-11-27 series is
runs-2026-11-27.jsonl). Trials of the first driver (rounds 0-8) have no CPU-based verdict; their
two timeouts were classed by their gdb stacks: see OVERRIDES."""

import json
import os
import statistics as st
import sys

path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "runs.jsonl")
rows = [json.loads(line) for line in open(path)]
OVERRIDES = {
    # every thread waiting; 2 tf_XLAEigen threads in lapack_sgeqrf_ffi -> ParallelBatchMap -> BlockingCounter::Wait
    # (deadlock-2026-11-27.gdb.txt)
    (4, "b"): "deadlock",
    (7, "d"): "slow",  # a thread inside XLA's WhileLoopSimplifier: still compiling run_chunk at 120 s
}
names = {
    "a": "jax defaults (`SIMJAX_KEEP_XLA_DEFAULTS=1`)",
    "b": "defaults + YNN off",
    "c": "project flags (current)",
    "d": "project flags + YNN off",
}


def verdict(r):
    if (r["round"], r["config"]) in OVERRIDES:
        return OVERRIDES[r["round"], r["config"]]
    if r.get("verdict"):
        return r["verdict"]
    return "ok" if r["rc"] == 0 else "error"  # rc 0 after the timeout fired = finished late (slow)


print(
    "| configuration | trials | deadlocks | timed out still working | completed | median s to done (min-max) "
    "| median init s | median chunk s |"
)
print("|---|---|---|---|---|---|---|---|")
for c in "abcd":
    rs = [r for r in rows if r["config"] == c]
    v = [verdict(r) for r in rs]
    ok = [r["result"] for r in rs if r["rc"] == 0 and r["result"]]
    tot = [x["t_total"] for x in ok]
    med = lambda k, ok=ok: f"{st.median(x[k] for x in ok):.1f}"
    print(
        f"| ({c}) {names[c]} | {len(rs)} | {v.count('deadlock')} | {v.count('slow')} | {len(ok)} | "
        f"{st.median(tot):.1f} ({min(tot):.1f}-{max(tot):.1f}) | {med('t_init')} | {med('t_chunk')} |"
    )
loads = [r["load1_start"] for r in rows]
print(
    f"\n{len(rows)} trials, {rows[0]['time']}-{rows[-1]['time']} UTC; 1-min load average at trial start: "
    f"median {st.median(loads):.1f}, range {min(loads)}-{max(loads)}; errors: {sum(verdict(r) == 'error' for r in rows)}"
)
