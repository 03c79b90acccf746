"""What importing simjax does to a process: nothing global, nothing computed, nothing printed."""

import os
import subprocess
import sys

import pytest

MODULES = ("simjax", "simjax.envs", "simjax.agents", "simjax.novelty", "simjax.runs", "simjax.train",
           "simjax.fork", "simjax.evaluate", "simjax.plotting")
REPORT = ("import os, jax\nprint(os.environ.get('XLA_FLAGS'))\nprint(jax.config.read('jax_cpu_enable_async_dispatch'))\n"
          "print(jax.config.jax_default_matmul_precision)\n")


def _python(code: str, **env) -> list[str]:
    """The stdout lines of ``code`` in a fresh interpreter, without this process's XLA flags and
    matmul precision."""
    clean = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "JAX_DEFAULT_MATMUL_PRECISION")}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                         env={**clean, **env}, check=True)
    return out.stdout.splitlines()


def test_importing_simjax_leaves_xla_flags_and_jax_config_alone():
    """Nor the matmul precision: a run applies its own while it traces (``runtime.matmul_precision``)."""
    code = f"import importlib\nfor m in {MODULES!r}: importlib.import_module(m)\n" + REPORT
    assert _python(code) == ["None", "True", "None"]
    assert _python(code, XLA_FLAGS="--xla_dump_to=/nowhere", JAX_DEFAULT_MATMUL_PRECISION="tensorfloat32") == [
        "--xla_dump_to=/nowhere", "True", "tensorfloat32"]


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


def _import_graph(package: str = "simjax.envs", root=None) -> dict[str, set[str]]:
    """{module: the ``package`` modules it imports} for every module under it, read from the
    source under ``root`` (default: the repository), imports inside functions included (``from
    simjax.envs import raycaster`` is an import of simjax.envs.raycaster) and relative ones
    (``from .a3c import x`` in simjax.agents.trainer is one of simjax.agents.a3c)."""
    import ast
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] if root is None else Path(root)
    files = sorted((root / Path(*package.split("."))).rglob("*.py"))

    def name_of(path: Path) -> str:
        parts = path.relative_to(root).with_suffix("").parts
        return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)

    modules = {name_of(f): f for f in files}
    graph = {}
    for name, path in modules.items():
        targets = set()
        # the package a relative import counts from: the module's own for an __init__, else its parent's
        here = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = here[: len(here) - (node.level - 1)]
                    base = ".".join(anchor + ([base] if base else []))
                if base == package or base.startswith(package + "."):
                    for alias in node.names:
                        full = f"{base}.{alias.name}"
                        targets.add(full if full in modules else base)
            elif isinstance(node, ast.Import):
                targets |= {a.name for a in node.names if a.name == package or a.name.startswith(package + ".")}
        graph[name] = targets - {name}
    return graph


def _assert_no_cycle(graph: dict[str, set[str]]) -> None:
    """A topological order exists: repeatedly take the modules whose imports are all taken."""
    done: set[str] = set()
    while len(done) < len(graph):
        ready = [m for m in graph if m not in done and graph[m] <= done]
        assert ready, f"import cycle among {sorted(set(graph) - done)}"
        done |= set(ready)


def test_the_envs_import_only_down_their_layers():
    """The shared floor (raycaster, brax base, episodes) < the Doom engine and MyWayHome
    (envs.doom) < the maze env and its adapters < the DMLab worlds (envs.dmlab) < the registry."""
    graph = _import_graph("simjax.envs")

    def layer(module: str) -> int:
        if module.startswith("simjax.envs.doom"):
            return 1
        if module.startswith("simjax.envs.dmlab"):
            return 3
        return {"simjax.envs.base": 0, "simjax.envs.episodes": 0, "simjax.envs.raycaster": 0,
                "simjax.envs.gymnax_adapter": 2, "simjax.envs.maze": 2, "simjax.envs.topdown": 2,
                "simjax.envs": 4}[module]

    assert {"simjax.envs.doom.motion", "simjax.envs.dmlab.melon", "simjax.envs.maze"} <= graph.keys()
    upward = [(m, t) for m, targets in graph.items() for t in targets if layer(t) > layer(m)]
    assert upward == []
    _assert_no_cycle(graph)  # and no cycle within a layer


def test_the_agents_import_only_down_their_layers():
    """The config < A2C (the rollout, the loss, its rule, the loop) < A3C's rule (built on A2C's
    loss) < the trainer, which picks the rule (a2c.py once imported a3c.py inside
    make_trainer, and a3c.py imports a2c.py) < the package."""
    graph = _import_graph("simjax.agents")
    layer = {"simjax.agents.config": 0, "simjax.agents.a2c": 1, "simjax.agents.a3c": 2, "simjax.agents.trainer": 3,
             "simjax.agents": 4}
    assert graph.keys() == layer.keys()  # a new module takes its place here
    upward = [(m, t) for m, targets in graph.items() for t in targets if layer[t] >= layer[m]]
    assert upward == []
    _assert_no_cycle(graph)


def test_the_import_graph_finds_the_edges_absolute_and_relative(tmp_path):
    """The parser's edges: the known ones in simjax.agents, and in a package written here every
    form of import, relative ones included (a parser that found none would pass every layer test)."""
    agents = _import_graph("simjax.agents")
    assert {"simjax.agents.a2c", "simjax.agents.config"} <= agents["simjax.agents.a3c"]
    assert "simjax.agents.config" in agents["simjax.agents.a2c"]
    assert {"simjax.agents.a2c", "simjax.agents.a3c"} <= agents["simjax.agents.trainer"]
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("from .a import x\nfrom . import b\n")
    (pkg / "a.py").write_text("import pkg.b\n\ndef f():\n    from pkg.sub import c\n")
    (pkg / "b.py").write_text("import os\nfrom pkg import sub\n")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "sub" / "c.py").write_text("from ..a import f\nfrom .. import b\nfrom . import d\n")
    (pkg / "sub" / "d.py").write_text("from ...outside import z\n")
    assert _import_graph("pkg", root=tmp_path) == {
        "pkg": {"pkg.a", "pkg.b"}, "pkg.a": {"pkg.b", "pkg.sub.c"}, "pkg.b": {"pkg.sub"},
        "pkg.sub": set(), "pkg.sub.c": {"pkg.a", "pkg.b", "pkg.sub.d"}, "pkg.sub.d": set()}


def test_the_import_cycle_check_finds_one():
    with pytest.raises(AssertionError, match="import cycle"):
        _assert_no_cycle({"a": {"b"}, "b": {"a"}, "c": set()})
