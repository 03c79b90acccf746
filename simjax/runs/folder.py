"""A run folder on disk, written and read back.

    config.json         every setting of the run (``TrainConfig``) and, from a training
                        process, the package versions; a sweep's also lists the swept values
                        ("sweep") and the grid of points ("grid", ``simjax.runs.grid``)
    metrics.csv         one row per seed (per sweep point and seed) per log interval, appended
                        and flushed as training goes; a sweep's rows start with a column per
                        swept setting
    checkpoint.msgpack  the runner state of every seed as of a metrics row (rewritten atomically
                        every ``--checkpoint-every`` seconds, at the end and when stopped; a
                        killed run keeps the last, and resuming drops the rows after it)
    export/             the policy, the novelty model and its frame statistics of every seed
                        as of the checkpoint (not Adam's moments, the environments, the novelty
                        memory), in files of at most 15 MiB (``write_export``): what evaluating
                        needs, small enough to copy off a GPU machine without the checkpoint
    pretrain.csv        EC only: its reachability network's pretraining, one row per seed per chunk
    pretrain_state.msgpack  EC only, while it pretrains: the pretraining after its last chunk
                        (``resume`` goes on from it); removed once the checkpoint after the
                        pretraining is written
    curve.png           success ratio and mean episode length against agent steps
    fork.json           where a fork (``simjax.runs.fork``) came from, and what it changed
    tensorboard/seedK/  with ``--tensorboard``: metrics.csv's values as TensorBoard scalars

``restore(folder)`` reads a run back for whatever goes on from it: resuming, forking,
evaluating, the experiments' diagnostics (these last from the export alone where the folder
has no checkpoint).
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import functools
import json
import math
import os
import re
import signal
import threading
from pathlib import Path

from simjax.agents import TrainConfig, make_trainer
from simjax.config_history import TASKS_AS_OF, current_record

METRIC_COLUMNS = (
    "env_steps", "seed", "success_ratio", "mean_episode_length", "mean_extrinsic_return",
    "episodes", "policy_loss", "value_loss", "entropy", "value_mean", "grad_norm",
    "bonus_mean", "forward_loss", "inverse_loss", "steps_per_s", "wall_s",
)
_ONE_DECIMAL = ("steps_per_s", "wall_s")  # measured, not learnt: tenths are plenty


STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def stops_deferred():
    """Ctrl-C or SIGTERM arriving within this block takes effect when the block has finished,
    through whatever handler was installed before it, so the block is never cut short (if the
    block raises, its exception goes on and the stop is dropped: the process is ending anyway).
    In a thread other than the main one (where Python runs no signal handler) it does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending = []
    previous = {s: signal.signal(s, lambda signum, frame: pending.append(signum)) for s in STOP_SIGNALS}
    try:
        yield
    finally:
        for s, handler in previous.items():  # None: a handler not installed from Python
            signal.signal(s, signal.SIG_DFL if handler is None else handler)
    for s in pending:
        signal.raise_signal(s)


def atomic_write(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and a rename, so a run stopped or
    killed mid-write leaves the old file or the new one, never half of one (nor the temporary
    file, when stopped by Ctrl-C or SIGTERM)."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    with stops_deferred():
        tmp.write_bytes(data)
        os.replace(tmp, path)


# -- config.json ----------------------------------------------------------------------------------


def write_config(run_dir: Path, config: TrainConfig, versions: dict | None = None,
                 sweep: dict[str, list] | None = None) -> None:
    """config.json: every setting (and, from a training process, the package versions); for a
    sweep, the swept values and the grid of points (``config`` holds the first point's values,
    with windows for the largest H and L); and the date of the task names it uses
    (``simjax.config_history``)."""
    from simjax.runs.grid import grid_of

    record = {"config": dataclasses.asdict(config), "tasks_as_of": TASKS_AS_OF}
    if sweep:
        record |= {"sweep": sweep, "grid": grid_of(sweep)}
    record |= {"versions": versions} if versions else {}
    atomic_write(Path(run_dir) / "config.json", json.dumps(record, indent=2).encode())


def _read_config(run_dir: Path) -> dict:
    path = Path(run_dir) / "config.json"
    if not path.exists():
        raise FileNotFoundError(f"{run_dir} is not a run folder (no config.json)")
    return current_record(json.loads(path.read_text()))


def load_config(run_dir: Path) -> TrainConfig:
    return TrainConfig(**_read_config(run_dir)["config"])


def load_sweep(run_dir: Path) -> dict[str, list]:
    """The swept values of a sweep's folder ({} for a plain run)."""
    return _read_config(run_dir).get("sweep", {})


def metric_columns(sweep: dict | None = None) -> tuple[str, ...]:
    """metrics.csv's columns: a sweep's swept settings first, then ``METRIC_COLUMNS``."""
    return tuple(sweep or ()) + METRIC_COLUMNS


# -- metrics.csv (and TensorBoard) ------------------------------------------------------------------


def rows_up_to(path: Path, steps: int, columns: tuple[str, ...] = METRIC_COLUMNS) -> list[list[str]]:
    """metrics.csv rows (header first) up to ``steps``: a row written after the last checkpoint
    (the process died between the two writes) is dropped, its update will be rerun."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows or tuple(rows[0]) != tuple(columns):
        raise ValueError(f"{path} does not have the columns this version writes")
    at = columns.index("env_steps")
    return [rows[0]] + [r for r in rows[1:] if int(r[at]) <= steps]


class MetricsLog:
    """The one writer of a run's metrics: ``append`` writes a row to metrics.csv (flushed and
    synced, so a killed run keeps it) and, with ``tensorboard``, the same values, as written
    to the CSV, as TensorBoard scalars in ``tensorboard/seed<K>/`` at step ``env_steps``.

    ``rows`` (header first) are what metrics.csv starts with: a resumed run's earlier rows.
    A sweep's rows start with the point's value of each swept setting (``labels``), and its
    TensorBoard folders are named by them too (``tensorboard/act_len=3/seed0/``).
    TensorBoard gets no point where a value is not finite (e.g. the success ratio of a row
    in which no episode ended): tensorboardX would print a warning for each."""

    def __init__(self, run_dir: Path, rows: list[list[str]] | None = None, tensorboard: bool = False,
                 labels: tuple[str, ...] = ()):
        self.run_dir, self.labels = Path(run_dir), tuple(labels)
        rows = rows or [list(metric_columns(dict.fromkeys(labels)))]
        atomic_write(self.run_dir / "metrics.csv", "".join(",".join(r) + "\r\n" for r in rows).encode())
        self._file = open(self.run_dir / "metrics.csv", "a", newline="")
        self._csv = csv.writer(self._file)
        self._boards = {} if tensorboard else None
        # a resumed run drops its rows after the checkpoint; TensorBoard hides them too
        self._purge_step = int(rows[-1][len(self.labels)]) + 1 if len(rows) > 1 else None

    def append(self, env_steps: int, seed: int, values: dict, point: dict | None = None) -> None:
        """One row: ``values`` holds every column after ``env_steps`` and ``seed``; ``point``
        the sweep point's value of each of ``labels``."""
        point = point or {}
        text = [f"{values[c]:.1f}" if c in _ONE_DECIMAL else f"{values[c]:.6g}" for c in METRIC_COLUMNS[2:]]
        self._csv.writerow([point[k] for k in self.labels] + [env_steps, seed] + text)
        if self._boards is not None:
            board = self._board("".join(f"{k}={point[k]}/" for k in self.labels) + f"seed{seed}")
            for column, value in zip(METRIC_COLUMNS[2:], text):
                if math.isfinite(float(value)):
                    board.add_scalar(column, float(value), env_steps)

    def flush(self) -> None:
        """Everything appended so far is on disk."""
        self._file.flush()
        os.fsync(self._file.fileno())
        for board in (self._boards or {}).values():
            board.flush()

    def close(self) -> None:
        self._file.close()
        for board in (self._boards or {}).values():
            board.close()

    def _board(self, name: str):
        if name not in self._boards:
            from tensorboardX import SummaryWriter

            self._boards[name] = SummaryWriter(str(self.run_dir / "tensorboard" / name), purge_step=self._purge_step)
        return self._boards[name]


def tensorboard_available() -> str | None:
    """None if ``--tensorboard`` can work here, else why not."""
    try:
        import tensorboardX  # noqa: F401
    except ImportError:
        return "--tensorboard needs tensorboardX: pip install -e '.[tensorboard]'"
    return None


# -- checkpoint.msgpack -----------------------------------------------------------------------------


def seed_keys(config: TrainConfig):
    """(num_seeds, 2) the PRNG keys a run's seeds start from: seed, seed + 1, ..."""
    import jax

    return jax.numpy.stack([jax.random.PRNGKey(config.seed + i) for i in range(config.num_seeds)])


def runner_template(trainer, config: TrainConfig, sweep: dict | None = None):
    """The shapes and types of a run's runner state (every member: sweep point x seed), without
    computing it."""
    import jax

    from simjax.runs.grid import batch_inputs, grid_of

    return jax.eval_shape(jax.vmap(trainer.init), *batch_inputs(config, grid_of(sweep or {})))


def write_checkpoint(run_dir: Path, runner, env_steps: int, seeds: list[int]) -> None:
    """checkpoint.msgpack: ``runner`` (a RunnerState of every seed, or its state dict) at
    ``env_steps`` agent steps per seed."""
    import jax
    from flax import serialization

    state = {"runner": serialization.to_state_dict(jax.device_get(runner)), "env_steps": env_steps,
             "seeds": list(seeds)}
    atomic_write(Path(run_dir) / "checkpoint.msgpack", serialization.msgpack_serialize(state))


_POSE_WITH_HEADING = {"pos", "heading", "vel", "angle", "turn_tics"}


def _drop_stored_headings(tree) -> None:
    """A pose entry that also holds "heading" beside the angle it is derived from (``motion.Pose``
    computes it) loses it, so that such a checkpoint restores into today's ``Pose``."""
    if isinstance(tree, dict):
        if tree.keys() == _POSE_WITH_HEADING:
            del tree["heading"]
        for value in tree.values():
            _drop_stored_headings(value)


def load_checkpoint(run_dir: Path, template=None) -> dict:
    """The checkpoint as saved: {"runner": RunnerState of every seed (leading axis: seed),
    "env_steps", "seeds"}; with a ``template`` RunnerState the runner is rebuilt into its types.
    A file that does not read as one is a ValueError naming it."""
    from flax import serialization

    path = Path(run_dir) / "checkpoint.msgpack"
    damaged = lambda why: ValueError(f"{path} is damaged ({why}); restore it from a copy or start the run again")
    try:
        ckpt = serialization.msgpack_restore(path.read_bytes())
    except (ValueError, TypeError) as err:  # msgpack's and flax's errors for a truncated or overwritten file
        raise damaged(err) from None
    if not (isinstance(ckpt, dict) and {"runner", "env_steps", "seeds"} <= ckpt.keys()):
        raise damaged("not a simjax checkpoint")
    _drop_stored_headings(ckpt["runner"])
    novelty = ckpt["runner"].get("novelty") if isinstance(ckpt.get("runner"), dict) else None
    if isinstance(novelty, dict) and "model" not in novelty:
        novelty["model"] = {}  # saved before NoveltyState had a model state (EC's); the others' is empty
    if template is not None:
        ckpt["runner"] = serialization.from_state_dict(template, ckpt["runner"])
    return ckpt


def checkpoint_steps(run_dir: Path) -> int:
    """Agent steps per seed at the folder's checkpoint; -1 if it has none that reads."""
    try:
        return int(load_checkpoint(run_dir)["env_steps"])
    except (FileNotFoundError, KeyError, ValueError):
        return -1


# -- export/ ----------------------------------------------------------------------------------------

EXPORT = "export"
# what of a runner's state dict the export keeps: what evaluating a policy and reading its novelty
# model need (the policy, the novelty model, the frame statistics it normalises with), not Adam's
# moments, the environments or the novelty memory, which only training on needs
EXPORTED = (("params", "policy"), ("params", "novelty"), ("novelty", "obs_stats"))
# each file's arrays stay under this, so that each can be copied off a machine that brings back
# files of at most 16 MiB
EXPORT_PART_BYTES = 15 * 2**20
_PART_NAME = re.compile(r"(\d+)-(\d+)-of-(\d+)\.msgpack")


def _exported(runner) -> dict:
    """The ``EXPORTED`` subtrees of ``runner`` (a RunnerState or its state dict) on the host,
    flat: {"params/policy/params/Dense_0/kernel": array (members, ...), ...}."""
    import jax
    from flax import serialization, traverse_util

    state = serialization.to_state_dict(runner)
    picked = {}
    for outer, inner in EXPORTED:
        if isinstance(state.get(outer), dict) and inner in state[outer]:
            picked.setdefault(outer, {})[inner] = state[outer][inner]
    return traverse_util.flatten_dict(jax.device_get(picked), sep="/")


def write_export(run_dir: Path, runner, env_steps: int, seeds: list[int]) -> None:
    """export/: the ``EXPORTED`` parts of ``runner`` (every member's) at ``env_steps``, in files
    ``STEPS-K-of-N.msgpack`` of at most ``EXPORT_PART_BYTES`` of arrays each (an array larger
    than that is cut along its first axis). Each file is written atomically and the older
    export's files are removed only once the new one is whole, so a run killed mid-export
    keeps one it can read."""
    import numpy as np
    from flax import serialization

    pieces = []  # (name, array): member m's slice of a leaf, cut j of it
    flat = _exported(runner)
    members = len(seeds)
    for m in range(members):
        for path, leaf in flat.items():
            piece = np.asarray(leaf[m])
            cuts = max(1, -(-piece.nbytes // EXPORT_PART_BYTES)) if piece.ndim else 1
            for j, cut in enumerate(np.array_split(piece, cuts) if cuts > 1 else [piece]):
                pieces.append((f"{m}/{j}/{path}", cut))
    parts, size = [{}], 0
    for name, array in pieces:
        if size and size + array.nbytes > EXPORT_PART_BYTES:
            parts.append({})
            size = 0
        parts[-1][name] = array
        size += array.nbytes
    folder = Path(run_dir) / EXPORT
    folder.mkdir(exist_ok=True)
    names = [f"{env_steps}-{k + 1}-of-{len(parts)}.msgpack" for k in range(len(parts))]
    for k, (name, arrays) in enumerate(zip(names, parts)):
        record = {"env_steps": env_steps, "seeds": list(seeds), "part": k + 1, "parts": len(parts), "arrays": arrays}
        atomic_write(folder / name, serialization.msgpack_serialize(record))
    for old in folder.iterdir():
        if old.name not in names:
            old.unlink()


def has_export(run_dir: Path) -> bool:
    return any(_PART_NAME.fullmatch(f.name) for f in (Path(run_dir) / EXPORT).glob("*.msgpack"))


def load_export(run_dir: Path) -> dict:
    """The newest whole export, as ``load_checkpoint`` gives a checkpoint: {"runner": the state
    dict of ``EXPORTED`` only (leading axis: member), "env_steps", "seeds"}. A ValueError names
    a file that does not read as one, or a folder without a whole export."""
    import numpy as np
    from flax import serialization, traverse_util

    folder = Path(run_dir) / EXPORT
    found = {}  # (steps, parts) -> {part: path}
    for f in folder.glob("*.msgpack"):
        match = _PART_NAME.fullmatch(f.name)
        if match:
            steps, k, n = map(int, match.groups())
            found.setdefault((steps, n), {})[k] = f
    whole = [key for key, files in found.items() if set(files) == set(range(1, key[1] + 1))]
    if not whole:
        raise ValueError(f"{folder} holds no whole export (files STEPS-K-of-N.msgpack for every K)")
    (steps, n) = max(whole)
    pieces, seeds = {}, None
    for k in range(1, n + 1):
        path = found[(steps, n)][k]
        try:
            record = serialization.msgpack_restore(path.read_bytes())
            ok = (int(record["env_steps"]), int(record["part"]), int(record["parts"])) == (steps, k, n)
            arrays, seeds = record["arrays"], [int(s) for s in record["seeds"]]
        except (ValueError, TypeError, KeyError) as err:
            raise ValueError(f"{path} is damaged ({err!r})") from None
        if not ok:
            raise ValueError(f"{path} is damaged (its record is not part {k} of {n} at {steps} steps)")
        for name, array in arrays.items():
            m, j, leaf = name.split("/", 2)
            pieces.setdefault(leaf, {}).setdefault(int(m), {})[int(j)] = np.asarray(array)
    flat = {}
    for leaf, by_member in pieces.items():
        cuts = [by_member[m] for m in sorted(by_member)]
        flat[leaf] = np.stack([np.concatenate([c[j] for j in sorted(c)]) if len(c) > 1 else c[0] for c in cuts])
    return {"runner": traverse_util.unflatten_dict(flat, sep="/"), "env_steps": steps, "seeds": seeds}


def check_resumable(run_dir: Path) -> None:
    """A FileNotFoundError for a folder that has an export but no checkpoint: resumed, it would
    train again from step 0 and replace the export."""
    run_dir = Path(run_dir)
    if not (run_dir / "checkpoint.msgpack").exists() and has_export(run_dir):
        raise FileNotFoundError(
            f"{run_dir} has its export but no checkpoint.msgpack, so --resume would train it again from step 0 "
            f"and replace the export; copy the checkpoint from the machine that trained it (or move {EXPORT}/ away)")


# -- a run read back ----------------------------------------------------------------------------------


class Restored:
    """A run folder read back: its ``config``, the checkpoint's ``env_steps`` and ``seeds``, and,
    built when first asked for, its task's ``env`` and the learner (``trainer``, ``network``).

    ``policy()`` rebuilds only the policy's parameters, so checkpoints whose env or novelty
    state has since changed shape still give their policy; ``novelty()`` the novelty model's
    and its frame statistics; ``runner()`` rebuilds everything (the novelty model's memory,
    Adam's moments too). ``state`` is the runner as saved (a state dict). Read from the export
    (``exported``: the folder has no checkpoint), ``state`` holds only what the export keeps,
    and ``runner()`` refuses."""

    def __init__(self, folder: Path, config: TrainConfig, checkpoint: dict, env=None, sweep: dict | None = None,
                 exported: bool = False):
        self.folder, self.config, self.sweep, self.exported = Path(folder), config, sweep or {}, exported
        self.state = checkpoint["runner"]
        self.env_steps, self.seeds = int(checkpoint["env_steps"]), [int(s) for s in checkpoint["seeds"]]
        if env is not None:
            self.env = env

    @functools.cached_property
    def env(self):
        from simjax.envs import make

        return make(self.config.env)

    @functools.cached_property
    def trainer(self):
        return make_trainer(self.config, self.env)

    @property
    def network(self):
        return self.trainer.network

    @functools.cached_property
    def _template(self):
        return runner_template(self.trainer, self.config, self.sweep)

    def policy(self, seed_index: int | None = None):
        """The policy's parameters: every seed's (leading axis: seed), or seed ``seed_index``'s."""
        from flax import serialization

        params = serialization.from_state_dict(self._template.params["policy"], self.state["params"]["policy"])
        return params if seed_index is None else _pick(params, seed_index)

    def novelty(self, seed_index: int | None = None):
        """(the novelty model's parameters, its frames' running statistics): every seed's
        (leading axis: seed), or seed ``seed_index``'s."""
        from flax import serialization

        template = self._template
        both = (serialization.from_state_dict(template.params["novelty"], self.state["params"].get("novelty", {})),
                serialization.from_state_dict(template.novelty.obs_stats, self.state["novelty"]["obs_stats"]))
        return both if seed_index is None else _pick(both, seed_index)

    def runner(self, seed_index: int | None = None):
        """The whole RunnerState: every seed's (leading axis: seed), or seed ``seed_index``'s."""
        from flax import serialization

        if self.exported:
            raise FileNotFoundError(f"{self.folder} has no checkpoint.msgpack, and its {EXPORT}/ holds only the "
                                    "policy, the novelty model and its frame statistics, not the whole runner state")
        runner = serialization.from_state_dict(self._template, self.state)
        return runner if seed_index is None else _pick(runner, seed_index)


def _pick(tree, index: int):
    import jax

    return jax.tree.map(lambda x: x[index], tree)


def restore(folder: Path, env=None) -> Restored:
    """Read the run in ``folder`` (config.json and checkpoint.msgpack, or without the
    checkpoint its export); ``env`` replaces the env its task would build. A
    FileNotFoundError says which file is missing."""
    folder = Path(folder)
    config = load_config(folder)
    if (folder / "checkpoint.msgpack").exists():
        return Restored(folder, config, load_checkpoint(folder), env, load_sweep(folder))
    if has_export(folder):
        return Restored(folder, config, load_export(folder), env, load_sweep(folder), exported=True)
    raise FileNotFoundError(f"{folder} has no checkpoint.msgpack and no {EXPORT}/")
