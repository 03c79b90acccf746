"""What importing simjax does to a process: nothing global, nothing computed, nothing printed."""

import os
import subprocess
import sys

MODULES = ("simjax", "simjax.envs", "simjax.agents", "simjax.novelty", "simjax.runs", "simjax.train",
           "simjax.fork", "simjax.evaluate", "simjax.plotting")
REPORT = "import os, jax\nprint(os.environ.get('XLA_FLAGS'))\nprint(jax.config.read('jax_cpu_enable_async_dispatch'))\n"


def _python(code: str, **env) -> list[str]:
    """The stdout lines of ``code`` in a fresh interpreter, without this process's XLA flags."""
    clean = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                         env={**clean, **env}, check=True)
    return out.stdout.splitlines()


def test_importing_simjax_leaves_xla_flags_and_jax_config_alone():
    code = f"import importlib\nfor m in {MODULES!r}: importlib.import_module(m)\n" + REPORT
    assert _python(code) == ["None", "True"]
    assert _python(code, XLA_FLAGS="--xla_dump_to=/nowhere") == ["--xla_dump_to=/nowhere", "True"]


def test_importing_simjax_starts_no_computation():
    """XLA reads XLA_FLAGS when its CPU backend starts: a user's flags set after ``import simjax``
    only count if no import has started it."""
    code = (f"import importlib\nfor m in {MODULES!r}: importlib.import_module(m)\n"
            "from jax._src import xla_bridge\nprint(sorted(xla_bridge._backends))")
    assert _python(code) == ["[]"]


def test_a_normal_run_prints_no_import_failures():
    """brax imports mujoco.mjx, which prints 'Failed to import warp' wherever warp is missing."""
    for command in (["-m", "simjax.train", "--help"], ["-c", "import simjax.envs, simjax.runs"]):
        out = subprocess.run([sys.executable, *command], capture_output=True, text=True, timeout=300, check=True)
        assert "Failed to import" not in out.stdout + out.stderr, command
