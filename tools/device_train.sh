#!/usr/bin/env bash
# One training run on a lent GPU machine, from a bare machine to what comes back under $OUT:
#
#   bash tools/device_train.sh NAME SECONDS [TRAIN FLAGS...]
#
# Installs the wheels carried in .whl/ (the machine has JAX with CUDA, but not brax and its
# needs; flax, optax and chex at this project's versions), trains `python -m simjax.train --out
# /tmp/NAME TRAIN FLAGS` (or resumes /tmp/NAME if it holds a checkpoint: a second call on the same
# warm machine), stopping it cleanly (SIGTERM keeps rows and checkpoint) if it would leave less
# than FIGURES_S seconds of the SECONDS this call has; then, with the time left, draws the run's
# trajectories and novelty map there (the checkpoint is too large to bring back) and puts
# config.json, metrics.csv, device_log.txt (commit, GPU, JAX version, precision, wall times, the
# whole output), figures.tar (curve, trajectories, novelty map) and, where it fits the device's
# limits, export/ (every seed's policy and novelty model) in $OUT. Training compiles at the run's own
# --precision (config.json; highest unless given); JAX_DEFAULT_MATMUL_PRECISION, highest unless
# set, is what the figures' scripts run at.
set -u
began=$(date +%s)
name=$1
budget=$2
shift 2
figures_s=${FIGURES_S:-150}
run=/tmp/$name
log=$OUT/device_log.txt
left() { echo $((budget - ($(date +%s) - began))); }
say() { echo "$* (at $(($(date +%s) - began)) s)" >>"$log"; }

{
    date
    echo "commit $(git rev-parse HEAD 2>/dev/null || echo unknown)"
    nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader
    echo "cpus $(nproc)"
} >"$log" 2>&1
if [ -d .whl ]; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl >>"$log" 2>&1 || {
        say "wheel install failed"
        exit 1
    }
fi
export PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1
export JAX_DEFAULT_MATMUL_PRECISION=${JAX_DEFAULT_MATMUL_PRECISION:-highest}
python3 -c "import jax, flax, optax, brax; print('jax', jax.__version__, 'flax', flax.__version__, 'optax', optax.__version__, \
'brax', brax.__version__, jax.devices(), 'precision', jax.config.jax_default_matmul_precision)" >>"$log" 2>&1

if [ -f "$run/checkpoint.msgpack" ]; then
    cmd=(python3 -m simjax.train --resume "$run")
else
    cmd=(python3 -m simjax.train --out "$run" "$@")
fi
say "train: ${cmd[*]}"
timeout -s TERM -k 60 $(($(left) - figures_s)) "${cmd[@]}" >>"$log" 2>&1
rc=$?
say "train rc $rc"
tail -n 12 "$run/metrics.csv" >>"$log" 2>/dev/null

if [ "$rc" = 0 ] && [ "$(left)" -gt 60 ]; then
    # the two figures side by side: each compiles its own programs and leaves the GPU mostly idle
    say "trajectories and novelty map with $(left) s left"
    stamp="($(date +%F), commit $(git rev-parse --short HEAD 2>/dev/null), on the lent GPU)"
    echo "\$ python experiments/trajectories.py $run --envs 32 --random   $stamp" >"$run/trajectories.txt"
    echo "\$ python experiments/novelty_map.py $run   $stamp" >"$run/novelty_map.txt"
    timeout $(($(left) - 15)) python3 experiments/trajectories.py "$run" --envs 32 --random >>"$run/trajectories.txt" 2>>"$log" &
    timeout $(($(left) - 15)) python3 experiments/novelty_map.py "$run" >>"$run/novelty_map.txt" 2>>"$log" &
    wait
    say "figures done"
fi
# What comes back is at most 8 files of 16 MiB, 64 MiB in all: config, metrics and the log as they
# are, the figures in one tar (unpack it into the run folder), and the export's files (every
# seed's policy and novelty model, at most 15 MiB each) where they fit beside those, else not
cp "$run/config.json" "$run/metrics.csv" "$OUT/" 2>/dev/null
figures=$(cd "$run" && ls curve.png trajectories.png trajectories.txt novelty_map.png novelty_map.txt 2>/dev/null)
[ -n "$figures" ] && tar -C "$run" -cf "$OUT/figures.tar" $figures
if [ -d "$run/export" ]; then
    parts=$(ls "$run/export" | wc -l)
    bytes=$(du -cb "$run"/export/* | tail -n 1 | cut -f1)
    if [ "$parts" -le 4 ] && [ "$bytes" -le $((56 * 1024 * 1024)) ]; then
        mkdir -p "$OUT/export" && cp "$run"/export/* "$OUT/export/"
    else
        say "export/ not brought back: $parts files, $bytes bytes"
    fi
fi
say "done"
tail -n 30 "$log"
