"""Fresh-process hang trials, PARALLEL at a time (each the others' load), with XLA's defaults.

usage: python tools/xla_hang/fresh.py OUT.jsonl TRIALS PARALLEL TIMEOUT_S -- ENV=VALUE... ARGS...
Each trial runs ``one.py ARGS`` with the environment variables given before ARGS (e.g.
HANG_ORTHOGONAL=flax) and no XLA_FLAGS. A trial still running at TIMEOUT_S is classed by
its CPU use over the next 10 s (about 0 s: deadlocked; otherwise: slow) and killed. One JSON
line per trial goes to OUT.jsonl.
"""

import json
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))


def cpu_s(pid):
    f = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")


def main():
    out, trials, parallel, timeout = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])
    rest = sys.argv[sys.argv.index("--") + 1:]
    extra = dict(a.split("=", 1) for a in rest if "=" in a)
    args = [a for a in rest if "=" not in a]
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"} | extra
    running, started, n = [], 0, 0
    with open(out, "a") as log:
        while started < trials or running:
            while started < trials and len(running) < parallel:
                proc = subprocess.Popen([sys.executable, os.path.join(HERE, "one.py"), *args], env=env,
                                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
                running.append((proc, time.time(), started))
                started += 1
            time.sleep(0.5)
            for item in list(running):
                proc, t0, i = item
                if proc.poll() is not None:
                    text = proc.stdout.read()
                    line = [x for x in text.splitlines() if x.startswith("RESULT ")]
                    record = json.loads(line[-1][7:]) if line else {"error": text[-400:]}
                    record |= {"trial": i, "outcome": "completed" if line else "failed", "args": args, "env": extra}
                elif time.time() - t0 > timeout:
                    before = cpu_s(proc.pid)
                    time.sleep(10)
                    busy = cpu_s(proc.pid) - before
                    proc.kill()
                    phases = [x for x in proc.stdout.read().splitlines() if x.startswith("PHASE")]
                    record = {"trial": i, "outcome": "deadlock" if busy < 0.5 else "slow", "cpu_s_in_10s": busy,
                              "last_phase": phases[-1] if phases else None, "args": args, "env": extra}
                else:
                    continue
                running.remove(item)
                record["load1"] = os.getloadavg()[0]
                log.write(json.dumps(record) + "\n")
                log.flush()
                n += 1
                print(n, record["outcome"], flush=True)


if __name__ == "__main__":
    main()
