"""Runs on disk: the run folder (``folder``: config, metrics, checkpoint, export, ``restore``),
training into one (``training``), forking one (``fork``) and the progress line (``progress``).
The command lines (``simjax.train``, ``simjax.fork``, ``simjax.evaluate``) and the experiments
sit on top of this package; it sits on top of the learner (``simjax.agents``)."""

from simjax.runs.folder import (
    METRIC_COLUMNS,
    MetricsLog,
    Restored,
    atomic_write,
    load_checkpoint,
    load_config,
    load_export,
    restore,
    seed_keys,
    write_checkpoint,
    write_config,
    write_export,
)
from simjax.runs.fork import FORKABLE, fork
from simjax.runs.training import Diverged, run

__all__ = [
    "FORKABLE", "METRIC_COLUMNS", "Diverged", "MetricsLog", "Restored", "atomic_write", "fork", "load_checkpoint",
    "load_config", "load_export", "restore", "run", "seed_keys", "write_checkpoint", "write_config", "write_export",
]
