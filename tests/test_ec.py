"""Episodic Curiosity (``simjax.novelty.ec``, ``ec_pretrain``): shapes, the episodic memory
against a plain-Python port of the original wrapper's rules, the percentile, the bonus's sign,
pretraining on a small maze, and a run end to end. Networks here are tiny (width 4-8, 16-32
features); the paper's sizes are checked by shape only (``jax.eval_shape``, nothing compiled)."""

import csv
import dataclasses
import json

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import flags as settings_flags
from helpers import flat_draw, random_rollout

from simjax import runs, runtime
from simjax import train as cli
from simjax.agents import TrainConfig, make_trainer
from simjax.envs import make
from simjax.novelty import EC, RND, Novelty, NoveltySettings, make_model
from simjax.novelty.ec import (
    BETA,
    ECState,
    ReachabilityNet,
    episode_bounds,
    percentile,
    sample_pair,
    scan_memory,
)
from simjax.novelty.ec_pretrain import Pretrainer
from simjax.novelty.settings import PretrainPlan
from simjax.plotting import read_members
from simjax.runs import training
from simjax.runs.folder import load_checkpoint, write_checkpoint
from simjax.runs.grid import batch_inputs, check_sweep
from simjax.runs.training import PRETRAIN_STATE, pretrain, read_pretrain_state, write_pretrain_state

A = 4
TINY = dict(width=4, features=16, capacity=8)


@pytest.fixture(scope="module")
def frames():
    """A random-action rollout of maze-tiny: obs (T, N, 42, 42, 3), reset, actions, last obs/reset."""
    return random_rollout(make("maze-tiny"), jax.random.PRNGKey(0), T=6, N=2, num_actions=A)


@pytest.fixture(scope="module")
def tiny_ec(frames):
    """``Novelty(EC(A, **TINY), 0.01)``, its initial params and state, and its jitted
    ``loss_and_bonus``: one compiled init and loss for the tests that read them."""
    novelty = Novelty(model=EC(A, **TINY), bonus_scale=0.01)
    params, state = jax.jit(novelty.init)(jax.random.PRNGKey(0), frames[0][0])
    return novelty, params, state, jax.jit(novelty.loss_and_bonus)


# ----------------------------------------------------------------------------- the network

def test_paper_sized_network_shapes_without_compiling():
    """ResNet-18 with 512 outputs on 42x42 frames, fc 512, fc 2 (A.4); ~11M parameters."""
    net = ReachabilityNet()
    x = jax.ShapeDtypeStruct((3, 42, 42, 3), jnp.float32)
    params = jax.eval_shape(net.init, jax.random.PRNGKey(0), x, x)
    emb = jax.eval_shape(lambda p, x: net.apply(p, x, method=ReachabilityNet.embed), params, x)
    logits = jax.eval_shape(net.apply, params, x, x)
    chex.assert_shape([emb], (3, 512))
    chex.assert_shape([logits], (3, 2))
    p = params["params"]
    assert p["first"]["kernel"].shape == (512, 512) and p["second"]["kernel"].shape == (512, 512)
    assert "bias" not in p["second"] and p["out"]["kernel"].shape == (512, 2)
    convs = [k for k in jax.tree_util.tree_leaves_with_path(p["embedding"]) if k[0][-1].key == "kernel"]
    # conv1 + 8 blocks x 2 convs + 3 shortcut projections + the fc: ResNet-18's 18 layers and 3 1x1s
    assert len(convs) == 1 + 16 + 3 + 1
    widths = sorted({leaf.shape[-1] for _, leaf in convs})
    assert widths == [64, 128, 256, 512]
    assert 10e6 < sum(x.size for x in jax.tree.leaves(params)) < 13e6


def test_split_first_layer_is_the_fc_of_the_concatenation():
    net = ReachabilityNet(width=4, features=16, hidden=8)
    k1, k2, k3 = jax.random.split(jax.random.PRNGKey(0), 3)
    x1, x2 = (flat_draw(jax.random.uniform, k, (5, 42, 42, 3)) for k in (k1, k2))
    params = jax.jit(net.init)(k3, x1[:1], x2[:1])  # one program, not an eager op per initialiser
    p = params["params"]

    @jax.jit
    def both(x1, x2):
        e1 = net.apply(params, x1, method=ReachabilityNet.embed)
        e2 = net.apply(params, x2, method=ReachabilityNet.embed)
        w = jnp.concatenate([p["first"]["kernel"], p["second"]["kernel"]], axis=0)  # W = [W1; W2]
        h = jax.nn.relu(jnp.concatenate([e1, e2], axis=-1) @ w + p["first"]["bias"])
        return net.apply(params, x1, x2), h

    logits, h = both(x1, x2)
    chex.assert_trees_all_close(logits, h @ p["out"]["kernel"] + p["out"]["bias"], atol=1e-5)


@pytest.mark.xdist_group("tiny_ec")  # one worker compiles the fixture once
def test_ec_shapes_and_state_through_novelty(frames, tiny_ec):
    obs, reset, actions, last_obs, last_reset = frames
    T, N = actions.shape
    novelty, params, state, loss_and_bonus = tiny_ec
    chex.assert_shape([state.model.slots], (N, 8, 16))
    np.testing.assert_array_equal(state.model.count, np.ones(N))  # the first frame is remembered
    grads, (bonus, metrics, new_state) = jax.jit(jax.grad(novelty.loss_and_bonus, has_aux=True))(params, state, *frames)
    loss, _ = loss_and_bonus(params, state, *frames)
    chex.assert_shape(bonus, (T, N))
    chex.assert_tree_all_finite((loss, bonus, metrics, new_state))
    chex.assert_trees_all_equal_shapes_and_dtypes(state, new_state)
    assert float(loss) == 0.0  # EC's network is fixed during the run
    assert np.all(np.abs(np.asarray(bonus)) <= 0.01 * BETA + 1e-7)
    assert np.all(np.asarray(new_state.model.count) >= 1)
    assert all(float(jnp.max(jnp.abs(g))) == 0.0 for g in jax.tree.leaves(grads))


def test_eco_trains_the_network_on_pairs_of_recent_frames(frames):
    """ECO: R's pair loss on each env's last ``window`` + T frames, trained by the learner."""
    obs = frames[0]
    model = EC(A, online=True, window=24, **TINY)
    novelty = Novelty(model=model, bonus_scale=0.01)
    params, state = jax.jit(novelty.init)(jax.random.PRNGKey(0), obs[0])
    chex.assert_shape(state.memory.frames, (24,) + obs.shape[1:])
    # a memory of 24 real frames and a rollout of 16, one episode: far pairs exist
    T, N = 16, obs.shape[1]
    noise = flat_draw(jax.random.randint, jax.random.PRNGKey(1), (24 + T + 1, N, 42, 42, 3), 0, 256).astype(jnp.uint8)
    state = state._replace(memory=state.memory._replace(frames=noise[:24], reset=jnp.zeros((24, N), bool),
                                                        valid=jnp.ones((24, N), bool)))
    batch = (noise[24:-1], jnp.zeros((T, N), bool), jnp.zeros((T, N), jnp.int32), noise[-1], jnp.zeros((N,), bool))
    grads, (bonus, metrics, new_state) = jax.jit(jax.grad(novelty.loss_and_bonus, has_aux=True))(params, state, *batch)
    assert float(metrics["forward_loss"]) > 0.0
    assert max(float(jnp.max(jnp.abs(g))) for g in jax.tree.leaves(grads)) > 0.0
    assert not np.array_equal(np.asarray(new_state.model.key), np.asarray(state.model.key))
    chex.assert_trees_all_equal_shapes_and_dtypes(state, new_state)
    chex.assert_shape(bonus, (T, N))


def test_ec_is_made_from_settings():
    settings = NoveltySettings(algo="ec", ec_memory=50, ec_width=8, ec_embed=32, ec_online=True, ec_beta=1.0)
    model = make_model(settings, A)
    assert isinstance(model, EC) and (model.capacity, model.width, model.features, model.online) == (50, 8, 32, True)
    assert model.history == model.window and EC(A).history == 0
    # the learner steps ECO's network, not EC's (fixed after pretraining); every other model trains
    assert Novelty(model).trainable and not Novelty(EC(A)).trainable
    assert Novelty(RND(A)).trainable and not Novelty(None).trainable
    assert model.beta == 1.0 and EC(A).beta == BETA == 0.5
    # the default follows the EC paper's rule: 1 where an episode can end early, else the original 0.5
    assert TrainConfig(algo="ec").ec_beta == TrainConfig(algo="ec", env="melon").ec_beta == 1.0
    assert TrainConfig(algo="ec", env="explore-goals").ec_beta == TrainConfig(algo="ec", env="melon-dmlab").ec_beta == BETA
    assert TrainConfig(algo="ec", ec_beta=1.0).novelty.ec_beta == 1.0
    for bad in (-0.1, 1.5):
        with pytest.raises(ValueError, match="--ec-beta"):
            TrainConfig(algo="ec", ec_beta=bad)


# ------------------------------------------------------------------------- episodic memory

@pytest.mark.parametrize("count", [0, 1, 2, 3, 7, 10, 11, 200])
def test_percentile_is_numpys_over_the_slots_in_use(count):
    values = np.asarray(jax.random.uniform(jax.random.PRNGKey(count), (200,)))
    got = float(percentile(jnp.asarray(values), jnp.asarray(count)))
    want = 0.0 if count == 0 else float(np.percentile(values[:count], 90))
    assert got == pytest.approx(want, abs=1e-6)


def _id_head(a, slots):
    """A comparator over frame ids (hidden size 1): P(reachable) ~ 1 for the same id, ~ 0 else."""
    return jnp.stack([jnp.zeros(slots.shape[0]), 20.0 - 40.0 * jnp.abs(a[..., 0] - slots[..., 0])], axis=-1)


def _reference(ids, starts, capacity):
    """The original CuriosityEnvWrapper / EpisodicMemory rules, in plain Python, for one env whose
    memory starts with frame ``first``: per frame (bonus, memory size after)."""
    memory, out = [ids[0]], []
    for frame, start in zip(ids[1:], starts[1:]):
        sims = [1.0 if m == frame else 0.0 for m in memory]
        s = float(np.percentile(sims, 90)) if memory else 0.0
        if start:
            memory = [frame]
            out.append((0.0, len(memory)))
            continue
        if s < 0.5:
            assert len(memory) < capacity  # these sequences never fill the memory
            memory.append(frame)
        out.append((0.5 - s, len(memory)))
    return out


def test_memory_matches_the_original_rules_under_vmap():
    # two environments, frame ids along 14 steps; env 1 starts a new episode at step 8
    ids = np.array([[0, 1, 1, 2, 1, 1, 1, 1, 1, 1, 3, 3, 1, 0, 0],
                    [5, 5, 6, 7, 5, 6, 7, 5, 9, 9, 9, 5, 6, 9, 9]], np.float32)
    starts = np.zeros_like(ids, bool)
    starts[1, 8] = True
    capacity = 16
    state = ECState(jnp.zeros((2, capacity, 1)).at[:, 0, 0].set(ids[:, 0]), jnp.ones((2,), jnp.int32),
                    jax.random.split(jax.random.PRNGKey(0), 2))
    xs = jnp.asarray(ids[:, 1:].T[..., None])  # (T, N, 1): a = b = the frame id
    state, novelty, sims = jax.jit(lambda s, x, st: scan_memory(s, x, x, st, _id_head))(
        state, xs, jnp.asarray(starts[:, 1:].T))
    for n in range(2):
        ref = _reference(ids[n], starts[n], capacity)
        np.testing.assert_allclose(np.asarray(novelty[:, n]), [b for b, _ in ref], atol=1e-6)
        assert int(state.count[n]) == ref[-1][1]
        kept = sorted(np.asarray(state.slots[n, : ref[-1][1], 0]).tolist())
        assert len(kept) == ref[-1][1] and set(kept) <= set(ids[n].tolist())
    # the new episode forgot env 1's first episode: 9 (seen only after the start) and 5, 6 again
    assert sorted(np.asarray(state.slots[1, : int(state.count[1]), 0]).tolist()) == [5.0, 6.0, 9.0]


def test_a_full_memory_replaces_one_random_slot():
    capacity = 3
    first = ECState(jnp.zeros((1, capacity, 1)), jnp.ones((1,), jnp.int32), jax.random.PRNGKey(3)[None])
    ids = jnp.arange(1.0, 7.0)[:, None, None]  # six new frames: 2 fill the memory, 4 replace
    state, novelty, _ = scan_memory(first, ids, ids, jnp.zeros((6, 1), bool), _id_head)
    # beta is the bonus's offset: with the EC paper's 1 (episodes that can end early) a new frame scores 1
    np.testing.assert_allclose(scan_memory(first, ids, ids, jnp.zeros((6, 1), bool), _id_head, beta=1.0)[1], 1.0,
                               atol=1e-6)
    assert int(state.count[0]) == capacity
    np.testing.assert_allclose(np.asarray(novelty[:, 0]), 0.5, atol=1e-6)  # every frame was new
    slots = sorted(np.asarray(state.slots[0, :, 0]).tolist())
    assert len(set(slots)) == capacity and 6.0 in slots  # the last frame always lands somewhere
    assert len({0.0, 1.0, 2.0} & set(slots)) < 3  # ... on a slot that was full


@pytest.mark.xdist_group("tiny_ec")  # one worker compiles the fixture once
def test_bonus_sign_and_scale_through_novelty(frames, tiny_ec):
    """A comparator that calls every pair reachable gives beta * (0.5 - 1) < 0; one that calls
    none reachable, beta * 0.5 > 0; episode starts get 0."""
    obs, reset, actions, last_obs, last_reset = frames
    reset = reset.at[3, 0].set(True)  # o_3 of env 0 starts an episode: transition 2 scores 0
    batch = (obs, reset, actions, last_obs, last_reset)
    _, params, state, loss_and_bonus = tiny_ec  # one program for both comparators
    for bias, want in (([-30.0, 30.0], 0.01 * (BETA - 1.0)), ([30.0, -30.0], 0.01 * BETA)):
        p = jax.tree.map(lambda x: x, params)
        p["r"]["params"]["out"]["kernel"] = jnp.zeros_like(p["r"]["params"]["out"]["kernel"])
        p["r"]["params"]["out"]["bias"] = jnp.asarray(bias)
        _, (bonus, _, new_state) = loss_and_bonus(p, state, *batch)
        bonus = np.asarray(bonus)
        assert bonus[2, 0] == 0.0
        mask = np.ones_like(bonus, bool)
        mask[2, 0] = False
        np.testing.assert_allclose(bonus[mask], want, atol=1e-6)
        if want > 0:  # nothing was similar: every frame joined its memory
            assert int(new_state.model.count[1]) == 1 + actions.shape[0]


@pytest.mark.xdist_group("tiny_ec")  # one worker compiles the fixture once
def test_alpha_is_the_hyper_bonus_scale(frames, tiny_ec):
    """A sweep's beta (EC's alpha) reaches EC's bonus: ``hyper.bonus_scale`` replaces the
    Novelty's own, as a traced value (one compiled program for every alpha)."""
    novelty, params, state, loss_and_bonus = tiny_ec
    hyper = NoveltySettings(algo="ec", bonus_scale=0.01).hyper()

    @jax.jit
    def bonus(alpha):
        return novelty.loss_and_bonus(params, state, *frames, hyper._replace(bonus_scale=alpha))[1][0]

    own = loss_and_bonus(params, state, *frames)[1][0]
    assert float(jnp.abs(own).max()) > 0.0
    np.testing.assert_allclose(bonus(jnp.float32(0.01)), own, rtol=1e-6)
    np.testing.assert_allclose(bonus(jnp.float32(0.03)), 3.0 * np.asarray(own), rtol=1e-5, atol=1e-9)
    assert bonus._cache_size() == 1


# ------------------------------------------------------------------------------ pretraining

def test_pairs_are_near_or_far_within_one_episode():
    segment = jnp.asarray(np.repeat([0, 1, 2], [40, 100, 20]))  # episodes of 40, 100, 20 frames
    valid = jnp.ones((160,), bool)
    start, end = episode_bounds(segment, valid)
    i, j, label, ok = jax.vmap(lambda k: sample_pair(k, start, end, valid))(
        jax.random.split(jax.random.PRNGKey(0), 4000))
    i, j, label, ok = map(np.asarray, (i, j, label, ok))
    seg = np.asarray(segment)
    assert np.all(seg[i[ok]] == seg[j[ok]])
    d = np.abs(i - j)
    assert np.all((d[ok & (label == 1)] >= 1) & (d[ok & (label == 1)] <= 5))
    assert np.all(d[ok & (label == 0)] > 25)
    assert abs(label.mean() - 0.5) < 0.05
    # far pairs do not exist in the 20-frame episode; near ones always do
    assert not np.any(ok & (label == 0) & (seg[i] == 2)) and np.all(ok[label == 1])
    # a far partner is drawn from the whole episode: both sides of the anchor occur
    far = ok & (label == 0) & (seg[i] == 1)
    assert np.any(j[far] < i[far]) and np.any(j[far] > i[far])


def test_pretraining_separates_near_from_far_pairs_on_a_small_maze():
    env = make("maze-tiny")
    model = EC(A, width=8, features=32, capacity=8)
    plan = PretrainPlan(chunk_len=200, num_chunks=2, calls=5, updates_per_call=40, num_envs=8)
    pre = Pretrainer(env, model, plan, batch=32, learning_rate=1e-3)
    x = jnp.zeros((1, 42, 42, 3))
    params = jax.jit(lambda k: {"r": model.net().init(k, x, x)})(jax.random.PRNGKey(1))
    trained, metrics = jax.jit(pre.run)(jax.random.PRNGKey(2), params)
    print("pretraining accuracy per chunk:", np.asarray(metrics["accuracy"]), "usable:", np.asarray(metrics["usable_pairs"]))

    @jax.jit
    def held_out(both):
        """Accuracy of each of ``both`` on 8 batches of pairs from a fresh random-policy chunk."""
        state = pre.collect(pre.init(jax.random.PRNGKey(7), params))
        start, end = pre.bounds(state.starts)
        batches = jax.vmap(lambda k: pre.sample(k, state.frames, start, end))(jax.random.split(jax.random.PRNGKey(8), 8))
        return [jnp.mean(jax.vmap(lambda b, p=p: pre.loss(p, *b)[1])(batches)) for p in both]

    before, after = (float(a) for a in held_out([params, trained]))
    print(f"held-out accuracy: untrained {before:.3f}, pretrained {after:.3f}")
    # measured: untrained 0.45, pretrained 0.71 (train batches of the last chunk: 0.80)
    assert after > 0.65 and after > before + 0.15


# ---------------------------------------------------------------------------- configuration

def test_config_counts_the_pretraining_in_the_step_axis():
    config = TrainConfig(env="maze-dense", algo="ec", total_steps=2_000_000)
    assert config.bonus_scale == 0.01 and config.step_offset == 600_000
    assert config.num_updates * config.steps_per_update >= 1_400_000 > (config.num_updates - 1) * config.steps_per_update
    plan = config.pretrain_plan
    assert (plan.chunk_len, plan.num_chunks, plan.num_envs) == (500, 75, 16)
    assert plan.updates >= 10 * 600_000 / 4 / 64  # 10 passes at one pair per 4 steps, batch 64
    assert TrainConfig(algo="ec", ec_pretrain_steps=0).step_offset == 0
    assert TrainConfig(algo="sim").step_offset == 0 and TrainConfig(algo="sim").pretrain_plan is None
    with pytest.raises(ValueError, match="pretraining steps"):
        TrainConfig(algo="ec", total_steps=600_000)
    with pytest.raises(ValueError, match="--ec-memory"):
        TrainConfig(algo="ec", ec_memory=0)


def test_cli_accepts_ec_flags(monkeypatch):
    monkeypatch.setattr(cli, "run", lambda *a, **k: pytest.fail("must not start a run"))
    config, _, _ = cli.parse_config(["--algo", "ec", "--env", "maze-tiny", "--ec-memory", "10", "--ec-width", "4",
                                     "--ec-embed", "8", "--ec-pretrain-steps", "1000", "--ec-pretrain-epochs", "2",
                                     "--ec-online", "true", "--total-steps", "2000"])
    assert (config.algo, config.ec_memory, config.ec_width, config.ec_embed, config.ec_online) == ("ec", 10, 4, 8, True)
    assert config.step_offset == 1008  # 16 envs x 63 steps


def test_checkpoints_from_before_the_model_state_still_load(tmp_path):
    """A checkpoint saved before NoveltyState had its ``model`` field reads back with it empty."""
    from flax import serialization

    from simjax.runs.folder import atomic_write

    old = {"runner": {"novelty": {"ret_running": np.zeros(2, np.float32)}}, "env_steps": 5, "seeds": [0]}
    atomic_write(tmp_path / "checkpoint.msgpack", serialization.msgpack_serialize(old))
    assert load_checkpoint(tmp_path)["runner"]["novelty"]["model"] == {}
    write_checkpoint(tmp_path, {"novelty": {"model": ()}}, 5, [0])  # an empty model state round-trips
    assert load_checkpoint(tmp_path)["runner"]["novelty"]["model"] == {}


# ------------------------------------------------------------------------------- end to end

# the tiny EC run of the two tests below (2 seeds, two pretraining chunks): marked
# xdist_group("ec_tiny_run"), they share a worker, and the second loads the pretraining's
# programs from the session's cache (the precision named: the command's default may differ)
EC_TINY = dict(env="maze-tiny", algo="ec", num_envs=2, rollout_len=4, ec_width=4, ec_embed=8, ec_memory=8,
               ec_pretrain_steps=2000, ec_pretrain_epochs=3, total_steps=2016, log_every=8, num_seeds=2,
               precision="highest")


@pytest.mark.xdist_group("ec_tiny_run")
def test_train_ec_end_to_end_and_a_run_stopped_in_its_pretraining_resumes_from_the_last_chunk(
        tmp_path, capsys, monkeypatch):
    """``python -m simjax.train --algo ec`` on maze-tiny: pretraining in two chunks, then rows
    from its end; the same run stopped after the first chunk and resumed with ``--resume`` is
    the whole run, bit for bit (its rows, pretrain.csv and checkpoint)."""
    flags = [*settings_flags(EC_TINY), "--quiet"]
    whole, parts = tmp_path / "whole", tmp_path / "parts"
    assert cli.main([*flags, "--out", str(whole)]) == 0
    with open(whole / "metrics.csv") as f:
        rows = list(csv.DictReader(f))
    assert [(int(r["env_steps"]), int(r["seed"])) for r in rows] == [(2008, 0), (2008, 1), (2016, 0), (2016, 1)]
    # (the curve starts after the 2,000 steps)
    assert all(np.isfinite(float(r["bonus_mean"])) for r in rows)
    with open(whole / "pretrain.csv") as f:
        pre = list(csv.DictReader(f))
    assert [(int(r["env_steps"]), int(r["seed"])) for r in pre] == [(1000, 0), (1000, 1), (2000, 0), (2000, 1)]
    assert all(0 <= float(r["accuracy"]) <= 1 for r in pre)
    ckpt = load_checkpoint(whole)
    assert ckpt["env_steps"] == 2016 and np.asarray(ckpt["runner"]["novelty"]["model"]["count"]).min() >= 1
    assert not (whole / PRETRAIN_STATE).exists()  # removed once the pretraining's checkpoint is written
    # the policy's updates took no optimiser step for the fixed network: its Adam state is as initialised
    adam = ckpt["runner"]["opt_state"]["inner_states"]["novelty"]["inner_state"]["1"]["0"]
    assert int(np.asarray(adam["count"]).max()) == 0
    assert all(not np.any(np.asarray(m)) for m in jax.tree.leaves((adam["mu"], adam["nu"])))

    saved = []

    def record(*args):  # the chunks after which the pretraining's state is written
        write_pretrain_state(*args)
        saved.append(args[2])

    def stop_after_first_chunk(*args):
        record(*args)
        raise KeyboardInterrupt  # as a Ctrl-C during the write: stops_deferred lets it in after it

    monkeypatch.setattr(training, "write_pretrain_state", stop_after_first_chunk)
    assert cli.main([*flags, "--out", str(parts)]) == 130
    assert saved == [1] and not (parts / "metrics.csv").exists()
    first_rows = (parts / "pretrain.csv").read_text().splitlines()
    assert len(first_rows) == 3  # header + the first chunk's row of each seed
    assert load_checkpoint(parts)["env_steps"] == 0
    plan = TrainConfig(**EC_TINY).pretrain_plan
    assert read_pretrain_state(parts, plan, [0, 1])["chunks"] == 1
    with pytest.raises(ValueError, match="another pretraining's"):  # e.g. a stale file of other settings
        read_pretrain_state(parts, dataclasses.replace(plan, calls=plan.calls + 1))
    monkeypatch.setattr(training, "write_pretrain_state", record)
    assert cli.main(["--resume", str(parts), "--quiet"]) == 0
    assert saved == [1, 2]  # the resumed run trained the second chunk only
    assert not (parts / PRETRAIN_STATE).exists()
    assert (parts / "pretrain.csv").read_text().splitlines()[:3] == first_rows  # kept as written, wall_s too
    drop = ("steps_per_s", "wall_s")
    for name in ("pretrain.csv", "metrics.csv"):
        a, b = ([{k: v for k, v in r.items() if k not in drop} for r in csv.DictReader(open(d / name))]
                for d in (whole, parts))
        assert a == b, name
    chex.assert_trees_all_equal(load_checkpoint(parts)["runner"], ckpt["runner"])
    capsys.readouterr()


@pytest.mark.xdist_group("ec_tiny_run")  # EC_TINY's pretraining, as a sweep
def test_an_ec_sweep_pretrains_once_per_seed_and_each_point_scales_its_own_bonus(tmp_path):
    """A sweep of alpha (``--bonus-scale``) over 2 seeds: pretrain.csv has a row per seed and
    chunk, not per member; every point's member of a seed gets the network that pretraining the member on
    its own gives; the first update's bonus of each point is its alpha times the same novelty
    (the members of a seed start alike)."""
    sweep = {"bonus_scale": [0.01, 0.03]}
    config, grid = check_sweep(EC_TINY, sweep)
    out = tmp_path / "sweep"
    runs.run(config, out, quiet=True, sweep=sweep)
    with open(out / "pretrain.csv") as f:
        pre = list(csv.DictReader(f))
    assert [(int(r["env_steps"]), int(r["seed"])) for r in pre] == [(1000, 0), (1000, 1), (2000, 0), (2000, 1)]
    members = read_members(out)
    assert sorted(members) == [((("bonus_scale", a),), s) for a in (0.01, 0.03) for s in (0, 1)]
    for seed in (0, 1):
        low, high = (members[((("bonus_scale", a),), seed)] for a in (0.01, 0.03))
        assert list(low["env_steps"]) == [2008, 2016]  # the rows start after the pretraining
        assert abs(low["bonus_mean"][0]) > 0
        np.testing.assert_allclose(high["bonus_mean"][0], 3.0 * low["bonus_mean"][0], rtol=1e-4)

    # the network each member trains with (EC's stays fixed during the run): point 1's members
    # were given point 0's pretraining; pretrained on their own, they get the same
    trainer = make_trainer(config)
    with runtime.matmul_precision(config.precision):  # as the run traced them: its init's program, loaded
        fresh = jax.jit(jax.vmap(trainer.init))(*batch_inputs(config, grid))
        point1 = jax.tree.map(lambda x: x[2:], fresh)
        own = pretrain(trainer.pretrain, point1, tmp_path, [0, 1], quiet=True)[0].params["novelty"]
    saved = load_checkpoint(out)["runner"]["params"]["novelty"]
    chex.assert_trees_all_close(jax.tree.map(lambda x: x[2:], saved), jax.device_get(own), rtol=1e-6, atol=1e-7)
    first = jax.tree.leaves(saved)[0]
    np.testing.assert_array_equal(first[0], first[2])  # point 0 and point 1 of seed 0
    assert not np.array_equal(first[0], first[1])  # seed 0 and seed 1


def test_a_stored_config_without_ec_beta_loads_with_the_offset_it_trained_with(tmp_path):
    # a config.json without ec_beta trained with 0.5, though this task's default is 1
    runs.write_config(tmp_path, TrainConfig(algo="ec", env="maze-very-sparse"))
    record = json.loads((tmp_path / "config.json").read_text())
    assert record["config"].pop("ec_beta") == 1.0
    (tmp_path / "config.json").write_text(json.dumps(record))
    assert runs.load_config(tmp_path).ec_beta == 0.5
