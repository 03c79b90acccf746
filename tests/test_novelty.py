"""The novelty models: sequence windows, shapes, training signal, ablation switches, normalisation."""

import functools

import chex
import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
from helpers import random_rollout

from simjax.envs import make
from simjax.novelty import ICM, RND, SIM, Novelty, RunningMeanStd, build_timeline, init_memory
from simjax.novelty.base import normalize_frames, spread

A = 4  # the maze tasks' action count


# ---------------------------------------------------------------- windows on a known sequence

def _index_rollouts(history, T, N, starts, rollouts):
    """Rollouts whose frames and actions are their global time index (actions + 100), episode
    starts at the global indices in ``starts``; yields (global index of o_0, Timeline)."""
    memory = init_memory(history, N, (1, 1, 1))
    g = 0
    for _ in range(rollouts):
        idx = np.arange(g, g + T + 1)
        frames = jnp.asarray(np.broadcast_to(idx[:, None, None, None, None], (T + 1, N, 1, 1, 1)), jnp.uint8)
        reset = jnp.asarray(np.broadcast_to(np.isin(idx, starts)[:, None], (T + 1, N)))
        actions = jnp.asarray(np.broadcast_to(idx[:T, None] + 100, (T, N)), jnp.int32)
        tl, memory = build_timeline(memory, frames[:T], reset[:T], actions, frames[T], reset[T])
        yield g, tl
        g += T


def _episode_start(g, starts):
    return max([0] + [s for s in starts if s <= g])


@pytest.mark.parametrize("H,L", [(2, 1), (3, 2), (10, 3)])
def test_windows_carry_across_rollouts_and_stop_at_episode_starts(H, L):
    T, N, starts = 5, 2, [0, 7, 9, 16]
    sim = SIM(A, obs_len=H, act_len=L)
    for g0, tl in _index_rollouts(sim.history, T, N, starts, rollouts=5):
        w = sim.windows(tl)
        frame_mask, action_mask = w.frame_mask, w.action_mask
        chex.assert_shape([frame_mask], (T, H, N))
        chex.assert_shape([action_mask], (T, L, N))
        assert bool(w.frame_start[0]) and not bool(w.frame_start[1:].any())  # no padding at full size
        for t in range(T):
            e = g0 + t + 1  # the target frame o_{t+1}, global index
            first = _episode_start(e, starts)
            for i, k in enumerate(range(L + H - 1, L - 1, -1)):
                want_valid = e - k >= first
                assert bool(frame_mask[t, i, 0]) == want_valid, (e, k)
                if want_valid:  # the right frame, from this rollout or carried in memory
                    assert int(tl.frames[w.frame_index[t, i], 0, 0, 0, 0]) == e - k
                    if i < H - 1:  # the inverse model's label: the action taken at that frame
                        assert int(tl.actions[w.frame_index[t, i], 0]) == e - k + 100
            for i, k in enumerate(range(L, 0, -1)):
                assert bool(action_mask[t, i, 0]) == (e - k >= first)
                if e - k >= first:
                    assert int(tl.actions[w.action_index[t, i], 0]) == e - k + 100
            # a target is scored iff the window's newest frame o_{e-L} is in its episode
            assert bool(frame_mask[t, -1, 0]) == (e - L >= first)


def test_icm_stacks_are_zero_before_the_episode_start():
    T, N, starts = 6, 1, [0, 4]
    icm = ICM(A)
    for g0, tl in _index_rollouts(icm.history, T, N, starts, rollouts=2):
        stacks = np.asarray(icm.stacks(tl))  # (T+1, N, 1, 1, 4), grey = index / 255
        for s in range(T + 1):
            end = g0 + s
            for i, k in enumerate(range(3, -1, -1)):
                want = (end - k) / 255.0 if end - k >= _episode_start(end, starts) else 0.0
                assert stacks[s, 0, 0, 0, i] == pytest.approx(want), (end, k)


# ---------------------------------------------------------------- real frames

@pytest.fixture(scope="module")
def frames():
    """Random-action rollouts: maze-tiny (seen) and maze-dense (unseen), (T+1, N, 42, 42, 3)."""
    return {name: random_rollout(make(task), jax.random.PRNGKey(k), T=10, N=2, num_actions=A)
            for name, task, k in (("seen", "maze-tiny", 0), ("unseen", "maze-dense", 1))}


MODELS = {
    "sim": lambda: SIM(A, obs_len=3, act_len=2),
    "rnd": lambda: RND(A),
    "icm": lambda: ICM(A),
}


def _novelty(model, **kw):
    return Novelty(model=model, bonus_scale=kw.pop("bonus_scale", 0.5), **kw)


def _init(novelty, batch, key=0):
    obs, reset, actions, last_obs, last_reset = batch
    return jax.jit(novelty.init)(jax.random.PRNGKey(key), obs[0])


@pytest.mark.parametrize("name", sorted(MODELS))
def test_bonus_and_loss_shapes_and_finiteness(name, frames):
    batch = frames["seen"]
    novelty = _novelty(MODELS[name]())
    params, state = _init(novelty, batch)
    loss, (bonus, metrics, new_state) = jax.jit(novelty.loss_and_bonus)(params, state, *batch)
    T, N = batch[2].shape
    chex.assert_shape(bonus, (T, N))
    chex.assert_type(bonus, jnp.float32)
    chex.assert_shape(loss, ())
    chex.assert_tree_all_finite((loss, bonus, metrics, new_state))
    assert float(jnp.min(bonus)) >= 0.0 and float(jnp.max(bonus)) > 0.0
    chex.assert_trees_all_equal_shapes_and_dtypes(state, new_state)  # memory keeps its shape


@pytest.mark.parametrize("H,L", [(2, 1), (10, 3)])  # the least and the paper's; test_sweep covers more
def test_sim_output_shapes_for_several_windows(H, L, frames):
    obs, reset, actions, last_obs, last_reset = frames["seen"]
    sim = SIM(A, obs_len=H, act_len=L)
    memory = init_memory(sim.history, obs.shape[1], obs.shape[2:])
    tl, new_memory = build_timeline(memory, obs, reset, actions, last_obs, last_reset)
    chex.assert_trees_all_equal_shapes(memory, new_memory)
    x = normalize_frames(tl.frames, None)

    @jax.jit  # one program: run op by op, the model compiles each of its hundreds of slices alone
    def run(x):  # the timeline's sizes stay Python ints: it is closed over, not traced
        params = sim.init(jax.random.PRNGKey(0), tl, x)
        return sim.net().apply(params["sim"], x, tl.actions, sim.windows(tl)), sim.apply(params, tl, x)

    (emb, prediction, logits), (error, scored, loss, metrics) = run(x)
    T, N = actions.shape
    chex.assert_shape(emb, (sim.history + T + 1, N, 256))
    chex.assert_shape(prediction, (T, N, 64))
    chex.assert_shape(logits, (T, N, H - 1, A))
    chex.assert_shape([error, scored], (T, N))
    chex.assert_tree_all_finite((error, loss, metrics))


def _fit(novelty, params, state, batch, steps=40, lr=1e-3):
    """Adam on the novelty loss for one fixed batch; returns params and first/last metrics."""
    tx = optax.adam(lr)
    opt = tx.init(params)

    @jax.jit
    def step(params, opt):
        grads, (_, metrics, _) = jax.grad(novelty.loss_and_bonus, has_aux=True)(params, state, *batch)
        updates, opt = tx.update(grads, opt)
        return optax.apply_updates(params, updates), opt, metrics

    history = []
    for _ in range(steps):
        params, opt, metrics = step(params, opt)
        history.append(jax.device_get(metrics))
    return params, history


@pytest.mark.parametrize("name", sorted(MODELS))
def test_losses_fall_on_a_fixed_batch_and_repeats_become_less_novel(name, frames):
    seen, unseen = frames["seen"], frames["unseen"]
    novelty = _novelty(MODELS[name]())
    params, state = _init(novelty, seen)
    trained, history = _fit(novelty, params, state, seen)
    first, last = history[0], history[-1]
    assert last["forward_loss"] < 0.5 * first["forward_loss"], (first, last)
    if name != "rnd":
        assert last["inverse_loss"] < first["inverse_loss"] - 0.05, (first, last)
    # the target never moves, whatever the optimiser does with the gradients
    if "target" in params:
        chex.assert_trees_all_equal(params["target"], trained["target"])
        grads = jax.jit(jax.grad(lambda p: novelty.loss_and_bonus(p, state, *seen)[0]))(params)
        assert all(float(jnp.max(jnp.abs(g))) == 0.0 for g in jax.tree.leaves(grads["target"]))
    # the repeated sequence's bonus falls below that of sequences the model never saw
    loss_and_bonus = jax.jit(novelty.loss_and_bonus)
    _, (bonus_seen, _, _) = loss_and_bonus(trained, state, *seen)
    _, (bonus_unseen, _, _) = loss_and_bonus(trained, state, *unseen)
    assert float(jnp.mean(bonus_seen)) < 0.5 * float(jnp.mean(bonus_unseen)), (bonus_seen.mean(), bonus_unseen.mean())


def test_frames_of_an_earlier_episode_never_change_the_new_episodes_scores(frames):
    obs, reset, actions, last_obs, last_reset = frames["seen"]
    T, N = actions.shape
    start = 6  # make o_6 an episode's first frame in every env
    reset = reset.at[:start].set(False).at[start].set(True).at[start + 1 :].set(False)
    last_reset = jnp.zeros_like(last_reset)
    scrambled = obs.at[:start].set(255 - obs[:start])
    novelty = _novelty(SIM(A, obs_len=4, act_len=2), obs_norm=False)
    params, state = _init(novelty, frames["seen"])
    sim = novelty.model

    @jax.jit
    def scores(o):
        tl, _ = build_timeline(state.memory, o, reset, actions, last_obs, last_reset)
        x = normalize_frames(tl.frames, None)
        error, scored, _, _ = sim.apply(params, tl, x)
        emb, prediction, logits = sim.net().apply(params["sim"], x, tl.actions, sim.windows(tl))
        return error, scored, logits

    outs = [scores(o) for o in (obs, scrambled)]
    # targets e = start + 1 ... T are o_{start+1} ... o_T, rows start ... T-1
    new_rows = slice(start, T)
    np.testing.assert_allclose(outs[0][0][new_rows], outs[1][0][new_rows], rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(outs[0][2][new_rows], outs[1][2][new_rows], rtol=1e-5, atol=1e-5)
    np.testing.assert_array_equal(outs[0][1], outs[1][1])
    assert not bool(outs[0][1][start - 1].any())  # the transition into the reset frame: unscored
    # ...and the old episode's targets do see the change
    assert not np.allclose(outs[0][0][: start - 1], outs[1][0][: start - 1])


# ---------------------------------------------------------------- ablation switches

@functools.cache
def _init_and_apply(model):
    """The model's params and its output on a batch, as one compiled program per model (op by
    op, each op would compile a program of its own): batch -> (params, (error, scored, loss,
    metrics))."""

    @jax.jit
    def run(batch):
        obs, reset, actions, last_obs, last_reset = batch
        memory = init_memory(model.history, obs.shape[1], obs.shape[2:])
        tl, _ = build_timeline(memory, obs, reset, actions, last_obs, last_reset)
        x = normalize_frames(tl.frames, None)
        params = model.init(jax.random.PRNGKey(3), tl, x)
        return params, model.apply(params, tl, x)

    return run


def _flat(tree):
    return {jax.tree_util.keystr(p): v for p, v in jax.tree_util.tree_leaves_with_path(tree)}


@pytest.mark.parametrize("switch,changed", [
    (dict(combine="itr"), {"Forward", "Inverse"}),
    (dict(combine="concat"), {"Forward", "Inverse"}),
    (dict(sequence="ff"), {"FrameLSTM", "ActionLSTM", "FrameFF", "ActionFF"}),
    (dict(target="embed"), {"Forward", "target"}),
    (dict(inverse=False), {"Inverse"}),
])
def test_each_ablation_switch_changes_only_its_part(switch, changed, frames):
    base = SIM(A, obs_len=3, act_len=2)
    ablated = SIM(A, obs_len=3, act_len=2, **switch)
    p_base, (error_base, scored, _, m_base) = jax.device_get(_init_and_apply(base)(frames["seen"]))
    p_abl, (error_abl, scored_abl, _, m_abl) = jax.device_get(_init_and_apply(ablated)(frames["seen"]))
    flat_base, flat_abl = _flat(p_base), _flat(p_abl)
    differing = {k for k in flat_base.keys() | flat_abl.keys()
                 if k not in flat_base or k not in flat_abl or flat_base[k].shape != flat_abl[k].shape
                 or not np.array_equal(flat_base[k], flat_abl[k])}
    touched = {part for k in differing for part in changed if f"'{part}'" in k}
    assert touched and all(any(f"'{part}'" in k for part in changed) for k in differing), differing
    np.testing.assert_array_equal(scored, scored_abl)  # masks are not part of any ablation
    if switch == dict(inverse=False):
        # same parameters otherwise: the novelty is the same, only the inverse loss is gone. The
        # two compiled programs may order a sum differently; the longest is the forward layer's
        # 768 inputs, so 768 u = 4.6e-5 relative bounds the difference
        np.testing.assert_allclose(error_base, error_abl, rtol=1e-4)
        assert float(m_abl["inverse_loss"]) == 0.0 and float(m_base["inverse_loss"]) > 0.0
    else:
        assert not np.allclose(error_base, error_abl)
    if switch == dict(combine="itr"):
        assert p_abl["sim"]["params"]["Forward"]["kernel"].shape == (256, 64)
    if switch == dict(combine="concat"):
        assert p_abl["sim"]["params"]["Forward"]["kernel"].shape == (512, 64)
    if switch == dict(target="embed"):
        assert "target" not in p_abl and p_abl["sim"]["params"]["Forward"]["kernel"].shape == (768, 256)


# ---------------------------------------------------------------- normalisation

def test_running_mean_std_matches_numpy():
    rng = np.random.default_rng(0)
    batches = [rng.normal(3.0, 2.0, size=(n, 2, 5)).astype(np.float32) for n in (7, 1, 30)]
    stats = RunningMeanStd.create((5,))
    for b in batches:
        stats = stats.update(jnp.asarray(b))
    allx = np.concatenate([b.reshape(-1, 5) for b in batches])
    np.testing.assert_allclose(stats.mean, allx.mean(0), rtol=1e-5)
    np.testing.assert_allclose(stats.var, allx.var(0), rtol=1e-4)
    assert float(stats.count) == allx.shape[0]
    x = normalize_frames(jnp.array([[0, 255]], jnp.uint8), RunningMeanStd(jnp.array(128.0), jnp.array(1.0), jnp.array(1.0)))
    np.testing.assert_array_equal(x, [[-5.0, 5.0]])


def test_bonus_normalisation_divides_by_the_running_return_std(frames):
    batch = frames["seen"]
    raw = _novelty(RND(A), bonus_scale=2.0)
    normed = _novelty(RND(A), bonus_scale=2.0, bonus_norm=True)
    params, state = _init(raw, batch)
    _, (b_raw, _, _) = raw.loss_and_bonus(params, state, *batch)
    _, (b_norm, _, s_norm) = normed.loss_and_bonus(params, state, *batch)
    np.testing.assert_allclose(b_norm, b_raw / np.sqrt(float(s_norm.ret_stats.var) + 1e-8), rtol=1e-5)
    assert float(s_norm.ret_stats.count) == b_raw.size
    returns = np.zeros(b_raw.shape[1])
    for t in range(b_raw.shape[0]):  # the discounted running sum, per env
        returns = 0.99 * returns + np.asarray(b_raw[t]) / 2.0
    np.testing.assert_allclose(s_norm.ret_running, returns, rtol=1e-5)


def test_obs_normalisation_feeds_the_networks(frames):
    batch = frames["seen"]
    on, off = _novelty(RND(A)), _novelty(RND(A), obs_norm=False)
    params, state = _init(on, batch)
    _, (b_on, _, s_on) = on.loss_and_bonus(params, state, *batch)
    _, (b_off, _, s_off) = off.loss_and_bonus(params, state, *batch)
    assert float(s_on.obs_stats.count) == batch[0].shape[0] * batch[0].shape[1]
    assert float(s_off.obs_stats.count) == 0.0
    assert not np.allclose(b_on, b_off)


def test_no_model_means_no_bonus(frames):
    batch = frames["seen"]
    novelty = Novelty(model=None)
    params, state = novelty.init(jax.random.PRNGKey(0), batch[0][0])
    loss, (bonus, metrics, _) = novelty.loss_and_bonus(params, state, *batch)
    assert params == {} and float(loss) == 0.0 and float(jnp.abs(bonus).max()) == 0.0


# ---------------------------------------------------------------- the maze's looks, as a target sees them

def test_no_wall_look_is_a_louder_tv_for_the_rnd_target():
    """Each of the nine invented looks (raycaster.TEXTURE_LOOKS: MyWayHome without its Freedoom
    textures), drawn on every wall of the map, spreads the RND target
    about as widely as the others (`experiments/look_loudness.py` calibrated them). A look
    that spread it several times wider would pay a prediction-error bonus several times
    higher at the same accuracy: the bright cyan look did (4.2x at these sizes, 6.2x at full)."""
    from simjax.envs import MazeEnv, MazeTask, mywayhome_layout, random_walks
    from simjax.envs.doom import mywayhome_map
    from simjax.novelty.networks import RNDTarget

    base = mywayhome_layout([10])
    spots = jnp.asarray([mywayhome_map.SPAWN_SPOTS[s] for s in (10, 17, 22, 26)], jnp.float32)
    walks, steps = 4, 16

    @jax.jit
    def frames(look, key):
        layout = base._replace(walls=base.walls._replace(texture=jnp.full_like(base.walls.texture, look)))

        def from_spot(spot, k):
            env = MazeEnv(layout._replace(spawns=spot[None]), MazeTask("looks", random_heading=True))
            obs, *_ = random_walks(env, k, walks, steps)
            return obs.reshape((-1,) + obs.shape[2:])

        obs = jax.vmap(from_spot)(spots, jax.random.split(key, spots.shape[0]))
        return obs.reshape((-1,) + obs.shape[2:])

    per_look = [frames(k, jax.random.PRNGKey(50)) for k in range(len(mywayhome_map.TEXTURE_NAMES))]
    chex.assert_shape(per_look[0], (4 * walks * steps, 42, 42, 3))
    everything = jnp.concatenate(per_look)
    stats = RunningMeanStd.create(everything.shape[1:]).update(everything)
    init = jax.jit(RNDTarget().init)  # one program, not op by op
    targets = [init(jax.random.PRNGKey(100 + i), everything[:1].astype(jnp.float32)) for i in range(2)]
    target = jax.jit(lambda p, f: RNDTarget().apply(p, normalize_frames(f, stats)))
    loudness = np.asarray([np.mean([spread(target(p, f)) for p in targets]) for f in per_look])
    assert np.all(np.isfinite(loudness)) and loudness.min() > 0
    assert loudness.max() / loudness.min() < 2.5, dict(zip(mywayhome_map.TEXTURE_NAMES, loudness.round(2)))


def test_rnd_target_leaky_slope_is_its_slope_below_zero():
    """``RNDTarget(leaky_slope=1)`` has no kink: with its zero biases it is linear, so
    f(-x) = -f(x) (negation commutes with every rounding). The runs' 0.01 and RND code's 0.2
    bend below zero, so f(-x) + f(x) is of the size of f(x), and the two slopes give different
    targets from the same parameters (``spot_loudness.py --slopes`` compares them this way)."""
    from simjax.novelty.networks import RNDTarget

    x = jax.random.normal(jax.random.PRNGKey(3), (2, 42, 42, 3))
    params = jax.jit(RNDTarget().init)(jax.random.PRNGKey(4), x)
    out = {v: jax.jit(lambda p, f, v=v: RNDTarget(leaky_slope=v).apply(p, f))(params, jnp.stack([x, -x]))
           for v in (0.01, 0.2, 1.0)}
    chex.assert_shape(out[0.01], (2, 2, 64))
    chex.assert_tree_all_finite(out)
    size = {v: float(jnp.abs(o[0]).max()) for v, o in out.items()}
    odd = {v: float(jnp.abs(o[0] + o[1]).max()) for v, o in out.items()}
    assert odd[1.0] <= 1e-5 * size[1.0], (odd, size)
    assert odd[0.01] > 0.1 * size[0.01] and odd[0.2] > 0.1 * size[0.2], (odd, size)
    assert float(jnp.abs(out[0.2][0] - out[0.01][0]).max()) > 0.1 * size[0.01]
    default = jax.jit(RNDTarget().apply)(params, jnp.stack([x, -x]))  # the same program as slope 0.01's
    np.testing.assert_array_equal(np.asarray(default), np.asarray(out[0.01]))


def test_spearman_ranks_the_spots():
    """The rank statistic that ``spot_loudness.py --slopes``, ``novelty_map.py`` and
    ``precision_check.py`` report: 1 for the same order, -1 for the reverse, and
    1 - 6 * sum(d^2) / (n (n^2 - 1)) for one swap of neighbours."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "experiments" / "precision_check.py"
    spec = importlib.util.spec_from_file_location("precision_check", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    a = np.asarray([5.0, 1.0, 3.0, 2.0, 4.0])
    np.testing.assert_array_equal(module.ranks(a), [1, 5, 3, 4, 2])
    assert module.spearman(a, 10 * a) == 1.0
    assert module.spearman(a, -a) == -1.0
    swapped = np.asarray([5.0, 1.0, 2.0, 3.0, 4.0])  # spots 3 and 4 trade ranks 3 and 4
    assert module.spearman(a, swapped) == pytest.approx(1 - 6 * 2 / (5 * 24))
