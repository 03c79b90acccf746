"""Helpers shared by the test files (pytest puts this folder on sys.path)."""

import jax


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
