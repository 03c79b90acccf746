"""Helpers shared by the test files (pytest puts this folder on sys.path)."""

import math

import jax

# One small RND run's settings, for the tests that train through the run folder (restore, TensorBoard,
# SIGTERM, fork): marked xdist_group("rnd_tiny_run"), they share a worker, so the first compiles the
# programs and the others load them from the session's cache (a fork's new program aside). The
# precision is named: the command's default is bfloat16 on a CPU with bfloat16 products and
# TrainConfig's is highest, so the tests that go through the command would otherwise compile
# programs of their own on such a CPU
RND_TINY = dict(env="maze-tiny", algo="rnd", num_envs=4, rollout_len=5, log_every=20, num_seeds=2, precision="highest")


def flags(settings: dict) -> list[str]:
    """The ``simjax.train`` flags that give the TrainConfig ``settings``."""
    return [text for name, value in settings.items() for text in (f"--{name.replace('_', '-')}", str(value))]


def flat_draw(sample, key, shape, *args, **kwargs):
    """``sample(key, shape, ...)`` (a jax.random sampler) drawn as one rank-1 array and reshaped:
    the same values, and XLA:CPU compiles a rank-1 draw several times faster than a rank-4 or -5
    one (about 0.2 s against 1-2 s for a 2x3x42x42x5 normal)."""
    return sample(key, (math.prod(shape),), *args, **kwargs).reshape(shape)


def walk(env, start, actions):
    """Step one env from ``start`` (a State, or a PRNG key to reset with) through ``actions``;
    return the stacked states after each step."""
    def body(s, a):
        s = env.step(s, a)
        return s, s

    state = env.reset(start) if not hasattr(start, "pipeline_state") else start
    return jax.lax.scan(body, state, actions)[1]


def random_rollout(env, key, T, N, num_actions=4):
    """T random-action steps of N envs: obs (T, N, ...), reset (T, N), actions (T, N), and the
    frame after the rollout and whether it starts an episode (the novelty models' batch).
    One compiled program: run op by op, the renderer's reset alone takes seconds."""
    return jax.jit(lambda k: _random_rollout(env, k, T, N, num_actions))(key)


def _random_rollout(env, key, T, N, num_actions):
    k_reset, k_act = jax.random.split(key)
    state = jax.vmap(env.reset)(jax.random.split(k_reset, N))
    actions = jax.random.randint(k_act, (T, N), 0, num_actions)

    def step(s, a):
        return jax.vmap(env.step)(s, a), (s.obs, s.done > 0)

    state, (obs, reset) = jax.lax.scan(step, state, actions)
    return obs, reset, actions, state.obs, state.done > 0


def one_chunk(config, sweep=None):
    """``config``'s trainer, its members' first runner, and the runner and row after one chunk,
    by a run's own programs (``runs.training.member_programs`` at the config's precision): a test
    shares them with any run of the same settings through the session's compilation cache."""
    from simjax import runtime
    from simjax.agents import make_trainer
    from simjax.runs.grid import batch_inputs, grid_of
    from simjax.runs.training import member_programs

    trainer = make_trainer(config)
    init, chunk = member_programs(trainer)
    with runtime.matmul_precision(config.precision):
        runner = init(*batch_inputs(config, grid_of(sweep or {})))
        after, row = chunk(runner)
    return trainer, runner, after, row
