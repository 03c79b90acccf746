"""Interleaved hang measurement: rounds of configurations a, b, c, d (order rotated each round),
each trial a fresh `python one.py ALGO ENV NUM_ENVS` with a per-trial timeout; one JSON line per
trial in runs.jsonl (and its log and gdb stacks in logs/, beside this file).
usage: python tools/xla_hang/drive2.py FIRST_ROUND ROUNDS TIMEOUT_S DEADLINE_S [ALGO ENV NUM_ENVS]
A trial still running at TIMEOUT_S is classed by its CPU use over the next 10 s (about 0 s: deadlocked,
threads idle; otherwise: still working, i.e. slow) and its native stacks are saved (gdb)."""

import json
import os
import signal
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
PY = sys.executable
YNN = "--xla_cpu_experimental_ynn_fusion_type="
CONFIGS = {
    "a": {"SIMJAX_KEEP_XLA_DEFAULTS": "1"},  # jax's defaults
    "b": {"SIMJAX_KEEP_XLA_DEFAULTS": "1", "XLA_FLAGS": YNN},  # defaults + YNN off
    "c": {},  # the project's flags (simjax.runtime.configure)
    "d": {"XLA_FLAGS": YNN},  # the project's flags + YNN off
}
first, rounds, timeout, deadline = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
workload = sys.argv[5:8] or ["a2c", "maze-tiny", "8"]
base = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "SIMJAX_KEEP_XLA_DEFAULTS")}
base["PYTHONPATH"] = os.environ.get("HANG_SIMJAX", os.path.dirname(os.path.dirname(HERE)))  # simjax to test
os.makedirs(os.path.join(HERE, "logs"), exist_ok=True)
start = time.time()
gdb_done = set()
out = open(os.path.join(HERE, "runs.jsonl"), "a")


def cpu_s(pid):
    f = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")


for r in range(first, first + rounds):
    if time.time() - start > deadline:
        print(f"deadline reached after {r} rounds", flush=True)
        break
    names = list(CONFIGS)
    names = names[r % 4 :] + names[: r % 4]
    for name in names:
        env = {**base, **CONFIGS[name]}
        load0 = os.getloadavg()[0]
        t = time.perf_counter()
        log = open(os.path.join(HERE, "logs", f"r{r:02d}_{name}.log"), "w")
        proc = subprocess.Popen([PY, os.path.join(HERE, "one.py"), *workload], env=env, cwd=HERE, stdout=log, stderr=subprocess.STDOUT)
        try:
            code = proc.wait(timeout=timeout)
            hung = False
            cpu10 = None
        except subprocess.TimeoutExpired:
            hung = True
            c0 = cpu_s(proc.pid)
            time.sleep(10)
            cpu10 = round(cpu_s(proc.pid) - c0, 2)
            if True:  # native stacks of every timed-out trial
                with open(os.path.join(HERE, "logs", f"r{r:02d}_{name}.gdb"), "w") as g:
                    subprocess.run(
                        ["gdb", "-p", str(proc.pid), "-batch", "-ex", "thread apply all bt 12"],
                        stdout=g,
                        stderr=subprocess.STDOUT,
                        timeout=60,
                    )
            proc.send_signal(signal.SIGUSR1)
            time.sleep(2)
            proc.kill()
            code = proc.wait()
        wall = time.perf_counter() - t
        log.close()
        text = open(log.name).read()
        phases = [line.split()[1] for line in text.splitlines() if line.startswith("PHASE ")]
        result = next((json.loads(line[7:]) for line in text.splitlines() if line.startswith("RESULT ")), None)
        row = dict(
            round=r,
            config=name,
            hung=hung,
            cpu_10s_after_timeout=cpu10,
            verdict=("ok" if not hung else "deadlock" if cpu10 < 0.5 else "slow") if code == 0 or hung else "error",
            rc=code,
            wall=round(wall, 1),
            last_phase=phases[-1] if phases else None,
            load1_start=round(load0, 2),
            load1_end=round(os.getloadavg()[0], 2),
            result=result,
            time=time.strftime("%H:%M:%S"),
        )
        out.write(json.dumps(row) + "\n")
        out.flush()
        print(
            json.dumps(
                {
                    k: row[k]
                    for k in ("round", "config", "hung", "verdict", "cpu_10s_after_timeout", "rc", "wall", "last_phase", "load1_start")
                }
            ),
            flush=True,
        )
