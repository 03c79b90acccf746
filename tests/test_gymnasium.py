"""The Gymnasium wrappers (``simjax.gymnasium_env``): Gymnasium's own checker on every MyWayHome
task, the vector env against simjax's envs (same keys, same actions) and against Gymnasium's
``SyncVectorEnv`` of the single env, next-step autoreset, and bad input."""

import subprocess
import sys
import warnings

import chex
import gymnasium
import jax
import numpy as np
import pytest
from gymnasium.error import ResetNeeded
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode, SyncVectorEnv

from simjax.envs import make
from simjax.envs.maze import MazeEnv
from simjax.gymnasium_env import ENV_IDS, SimjaxEnv, SimjaxVectorEnv, seed_key

OBS = (42, 42, 3)
# maze-tiny: 50-step episodes, the goal 160 units ahead of the start; actions leaning forward
# reach it often enough that a short run ends episodes both ways
TINY_ENVS, TINY_CALLS, TINY_P = 8, 130, (0.2, 0.2, 0.5, 0.1)


def tiny_actions(seed, calls=TINY_CALLS, n=TINY_ENVS):
    return np.random.default_rng(seed).choice(4, size=(calls, n), p=TINY_P)


@pytest.mark.parametrize("task", ["maze-dense", "maze-sparse", "maze-very-sparse"])
def test_check_env_passes_on_every_mywayhome_task(task):
    env = gymnasium.make(ENV_IDS[task], render_mode="rgb_array")
    assert env.spec.max_episode_steps is None  # the task truncates itself: no TimeLimit on top
    assert "TimeLimit" not in str(env)
    assert env.unwrapped.task == task
    assert env.observation_space == gymnasium.spaces.Box(0, 255, OBS, np.uint8)
    assert env.action_space == gymnasium.spaces.Discrete(4)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)  # also remakes it for each render mode, renders and closes
    assert [str(w.message) for w in caught if "WARN" in str(w.message)] == []


def test_the_ids_whose_start_changed_have_a_new_version_and_the_old_one_keeps_its_start():
    # the paper's sparse and very sparse starts are v1; v0 is what those ids built before
    assert {task: ENV_IDS[task] for task in ("maze-sparse", "maze-very-sparse", "maze-spot16-east", "maze-spot10-east")} == {
        "maze-sparse": "simjax/MyWayHome-sparse-v1", "maze-very-sparse": "simjax/MyWayHome-very-sparse-v1",
        "maze-spot16-east": "simjax/MyWayHome-sparse-v0", "maze-spot10-east": "simjax/MyWayHome-very-sparse-v0"}
    for task, env_id in ENV_IDS.items():
        if task in ("maze-spot16-east", "maze-spot10-east"):  # Gymnasium points the user at v1
            with pytest.warns(DeprecationWarning, match="out of date.*v1"):
                assert gymnasium.make(env_id).unwrapped.task == task
        else:
            assert gymnasium.make(env_id).unwrapped.task == task


def reference_next_step(task, keys, actions):
    """``simjax.envs.make(task)`` under ``jax.vmap`` with Gymnasium's next-step autoreset written
    out: an env whose episode ended on the previous call does not step (the auto-resetting env's
    state already holds the next episode's first frame) and returns that frame, reward 0, no
    flags; the call that ends an episode returns the frame before the auto-reset (stepped by
    the same env without auto-reset). Returns the reset frames and each call's outputs."""
    env = make(task)
    step = jax.jit(jax.vmap(env.step))
    no_reset = MazeEnv(env.layout, env.task, env.camera, env.motion_params, False, env.look, env.light)
    last_frame = jax.jit(jax.vmap(lambda s, a: no_reset.step(s, a).obs))
    state = jax.jit(jax.vmap(env.reset))(keys)
    first = np.asarray(state.obs)
    pending = np.zeros(keys.shape[0], bool)
    out = []
    for a in actions:
        nxt = step(state, a)
        done = np.asarray(nxt.done) > 0
        trunc = np.asarray(nxt.info["truncation"]) > 0
        frame = np.asarray(nxt.obs)
        if done.any():
            frame = np.where(done[:, None, None, None], np.asarray(last_frame(state, a)), frame)
        frame = np.where(pending[:, None, None, None], np.asarray(state.obs), frame)
        reward = np.where(pending, 0.0, np.asarray(nxt.reward))
        out.append((frame, reward, ~pending & done & ~trunc, ~pending & trunc))
        keep = lambda old, new, p=pending: np.where(p.reshape((-1,) + (1,) * (new.ndim - 1)), old, new)
        state = jax.tree.map(keep, state, nxt)
        pending = ~pending & done
    return first, out


def assert_same_run(venv, seed, keys, task, actions):
    first, expected = reference_next_step(task, keys, actions)
    obs, info = venv.reset(seed=seed)
    chex.assert_shape(obs, (venv.num_envs, *OBS))
    chex.assert_type(obs, np.uint8)
    np.testing.assert_array_equal(obs, first)
    assert info == {}
    for t, (a, want) in enumerate(zip(actions, expected)):
        got = venv.step(a)
        chex.assert_shape(got[:4], [(venv.num_envs, *OBS), (venv.num_envs,), (venv.num_envs,), (venv.num_envs,)])
        assert got[2].dtype == got[3].dtype == np.bool_
        for name, g, w in zip(("obs", "reward", "terminated", "truncated"), got, want):
            np.testing.assert_array_equal(g, w, err_msg=f"{name} at call {t}")
        assert got[4] == {}
    return np.array([e[2] for e in expected]), np.array([e[3] for e in expected])


def test_vector_env_equals_simjax_envs_on_mywayhome():
    """maze-dense (random spots and headings): the same keys give the same starts, the same
    actions the same frames and rewards."""
    # one env, sharing its compiled step with the single env of check_env (maze-tiny runs 8)
    venv = SimjaxVectorEnv(1, "maze-dense")
    actions = np.random.default_rng(0).integers(0, 4, size=(24, 1))
    assert_same_run(venv, 7, jax.random.split(jax.random.PRNGKey(7), 1), "maze-dense", actions)
    # the single env: reset(seed=s) is env.reset(PRNGKey(s)), a start of the 17 and a heading
    reset = jax.jit(make("maze-dense").reset)
    frames = [SimjaxEnv("maze-dense").reset(seed=s)[0] for s in (0, 1, 123)]
    for s, frame in zip((0, 1, 123), frames):
        np.testing.assert_array_equal(frame, np.asarray(reset(jax.random.PRNGKey(s)).obs))
    assert not np.array_equal(frames[0], frames[1])


def test_vector_env_equals_simjax_envs_across_episodes():
    """maze-tiny's 50-step episodes: episode ends (both kinds), autoresets and the episodes
    after them, as the auto-resetting env starts them from its own keys."""
    venv = SimjaxVectorEnv(TINY_ENVS, "maze-tiny")
    keys = jax.random.split(jax.random.PRNGKey(3), TINY_ENVS)
    term, trunc = assert_same_run(venv, 3, keys, "maze-tiny", tiny_actions(0))
    assert term.sum() >= 2 and trunc.sum() >= 2  # the run covers both ends and what follows them
    assert (term | trunc).sum(0).min() >= 2  # every env went on past its first episode


def test_vector_env_equals_gymnasiums_sync_vector_env_of_the_single_env():
    """Gymnasium's own next-step autoreset (SyncVectorEnv over SimjaxEnv, reset with a list of
    seeds) and the one-call vector env give the same numbers, episode after episode."""
    seeds = list(range(100, 100 + TINY_ENVS))
    ours = SimjaxVectorEnv(TINY_ENVS, "maze-tiny")
    sync = SyncVectorEnv([lambda: SimjaxEnv("maze-tiny") for _ in seeds])
    assert ours.metadata["autoreset_mode"] == sync.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert ours.observation_space == sync.observation_space and ours.action_space == sync.action_space
    np.testing.assert_array_equal(ours.reset(seed=seeds)[0], sync.reset(seed=seeds)[0])
    ends = 0
    for t, a in enumerate(tiny_actions(1)):
        got, want = ours.step(a), sync.step(a)
        for name, g, w in zip(("obs", "reward", "terminated", "truncated"), got, want):
            np.testing.assert_array_equal(g, w, err_msg=f"{name} at call {t}")
        ends += int(np.sum(got[2] | got[3]))
    assert ends >= TINY_ENVS * 2


def test_the_step_after_an_episode_ends_resets_and_ignores_the_action():
    """Two vector envs, the same seed and actions, except that b gets other actions wherever an
    env's episode ended on the previous call: both give the same numbers throughout."""
    n = TINY_ENVS
    a, b = SimjaxVectorEnv(n, "maze-tiny", render_mode="rgb_array"), SimjaxVectorEnv(n, "maze-tiny")
    control = SimjaxVectorEnv(n, "maze-tiny")
    last, _ = a.reset(seed=13)
    b.reset(seed=13)
    control.reset(seed=13)
    frames = a.render()
    assert isinstance(frames, tuple) and len(frames) == n
    np.testing.assert_array_equal(np.stack(frames), last)
    actions = tiny_actions(2)
    differ = lambda act: (act + 1 + np.arange(n) % 3) % 4  # another action in every env
    # elsewhere actions count: other actions on the first call give other frames
    assert not np.array_equal(control.step(differ(actions[0]))[0], a.step(actions[0])[0])
    b.step(actions[0])
    resetting, length = np.zeros(n, bool), np.ones(n, int)
    resets, ends = 0, {"terminated": 0, "truncated": 0}
    for t, act in enumerate(actions[1:], 1):
        got_a, got_b = a.step(act), b.step(np.where(resetting, differ(act), act))
        for name, g_a, g_b in zip(("obs", "reward", "terminated", "truncated"), got_a, got_b):
            np.testing.assert_array_equal(g_a, g_b, err_msg=f"{name} at call {t}")
        obs, reward, term, trunc, _ = got_a
        np.testing.assert_array_equal(np.stack(a.render()), obs)
        # the call after an episode's end: the next episode's first frame, reward 0, no flags
        assert np.all(reward[resetting] == 0) and not term[resetting].any() and not trunc[resetting].any()
        assert all(np.any(obs[i] != last[i]) for i in np.flatnonzero(resetting))
        length = np.where(resetting, 0, length + 1)
        assert np.all(length[trunc] == 50) and np.all(length[term] <= 50)  # the task's own limit, no other
        resets += int(resetting.sum())
        ends["terminated"] += int(term.sum())
        ends["truncated"] += int(trunc.sum())
        resetting, last = term | trunc, obs
    assert resets >= 2 * n and min(ends.values()) >= 1, (resets, ends)


def test_single_env_does_not_reset_itself_and_reset_goes_on_from_its_key():
    env = SimjaxEnv("maze-tiny", render_mode="rgb_array")
    obs, _ = env.reset(seed=5)
    np.testing.assert_array_equal(env.render(), obs)
    steps, over = 0, False
    while not over:
        obs, reward, term, trunc, info = env.step(2)
        assert isinstance(reward, float) and isinstance(term, bool) and isinstance(trunc, bool) and info == {}
        steps += 1
        over = term or trunc
    np.testing.assert_array_equal(env.render(), obs)
    # the episode's own last frame, not the next episode's first
    ref = make("maze-tiny")
    state = jax.jit(lambda k: jax.lax.fori_loop(0, steps - 1, lambda i, s: ref.step(s, 2), ref.reset(k)))(seed_key(5))
    no_reset = MazeEnv(ref.layout, ref.task, ref.camera, ref.motion_params, False)
    np.testing.assert_array_equal(obs, np.asarray(jax.jit(no_reset.step)(state, 2).obs))
    # reset() without a seed starts the episode the auto-resetting env starts next
    np.testing.assert_array_equal(env.reset()[0], np.asarray(jax.jit(ref.step)(state, 2).obs))


def test_seeds_beyond_32_bits_stay_distinct():
    np.testing.assert_array_equal(seed_key(7), jax.random.PRNGKey(7))
    np.testing.assert_array_equal(seed_key(2**40 + 7), jax.random.fold_in(jax.random.PRNGKey(7), 2**8))
    assert not np.array_equal(seed_key(2**40 + 7), seed_key(7))
    for bad in (-1, 2**64, 1.5, "1"):
        with pytest.raises(ValueError, match="seed"):
            seed_key(bad)


def test_bad_input_is_a_clear_error():
    with pytest.raises(ValueError, match="maze-dense"):
        SimjaxEnv("melon")
    with pytest.raises(ValueError, match="render_mode"):
        SimjaxEnv("maze-tiny", render_mode="human")
    with pytest.raises(ValueError, match="num_envs"):
        SimjaxVectorEnv(0, "maze-tiny")

    env = SimjaxEnv("maze-tiny")
    with pytest.raises(ResetNeeded):
        env.step(0)
    env.reset(seed=0)
    for action in (4, -1, 1.5, "2", np.array([1])):
        with pytest.raises(ValueError, match=r"Discrete\(4\)"):
            env.step(action)
    with pytest.raises(ValueError, match="options"):
        env.reset(options={"xy": (0, 0)})

    venv = SimjaxVectorEnv(3, "maze-tiny")
    with pytest.raises(ResetNeeded):
        venv.step(np.zeros(3, int))
    venv.reset(seed=0)
    for actions, match in ((np.zeros(4, int), r"shape \(3,\)"), (np.zeros((3, 1), int), r"shape \(3,\)"), (2, r"shape \(3,\)"),
                           (np.zeros(3), "integers"), (np.array([0, 4, 1]), r"\[0, 4\).*\[4\]"),
                           (np.array([-1, 0, 0]), r"\[0, 4\)")):
        with pytest.raises(ValueError, match=match):
            venv.step(actions)
    with pytest.raises(ValueError, match="one per env"):
        venv.reset(seed=[1, 2])
    with pytest.raises(ValueError, match="reset_mask"):
        venv.reset(options={"reset_mask": np.ones(3, bool)})
    venv.step(np.array([0, 1, 2]))  # still usable after the refusals


def test_registered_ids_load_by_module_name_in_a_fresh_process():
    """``gymnasium.make("simjax.gymnasium_env:ID")`` imports the module that registers the ids;
    importing it computes nothing (no XLA backend starts)."""
    code = (
        "import gymnasium, simjax.gymnasium_env\n"
        "from jax._src import xla_bridge\n"
        "print(sorted(xla_bridge._backends))\n"
        "import sys\n"
        "del sys.modules['simjax.gymnasium_env']\n"
        "for i in list(gymnasium.registry):\n"
        "    if i.startswith('simjax/'): del gymnasium.registry[i]\n"
        "env = gymnasium.make('simjax.gymnasium_env:simjax/MyWayHome-very-sparse-v1')\n"
        "print(type(env.unwrapped).__name__, env.unwrapped.task, env.spec.max_episode_steps)\n"
        "venv = gymnasium.make_vec('simjax/MyWayHome-sparse-v0', num_envs=2)\n"
        "print(type(venv).__name__, venv.num_envs, venv.task)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines() == ["[]", "SimjaxEnv maze-very-sparse None", "SimjaxVectorEnv 2 maze-spot16-east"]
