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
