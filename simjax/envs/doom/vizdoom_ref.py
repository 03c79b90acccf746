"""The real ViZDoom MyWayHome scenario, as a test oracle and an evaluation backend.

simjax's core never imports this module (it needs the ``vizdoom`` package and a Doom engine
process); tests, tools and the evaluation command do. It answers two questions: "what does
ViZDoom do for this action sequence?" (poses, frames, depth; :func:`random_walk`) and "how
often does a policy reach the armour in the real game?" (:class:`MyWayHome`, whose ``step``
returns the goal reward the way our env does).

The scenario (``my_way_home.cfg`` / ``my_way_home.wad`` shipped with vizdoom 1.3.2)
----------------------------------------------------------------------------------
- Buttons TURN_LEFT TURN_RIGHT MOVE_FORWARD MOVE_LEFT MOVE_RIGHT; our 4 actions press
  TURN_LEFT, TURN_RIGHT, MOVE_FORWARD or nothing (the two strafe buttons are never used).
  The vectors are built from ``get_available_buttons()`` names, not positions.
- One agent step repeats its action for 4 tics (``make_action(vec, 4)``), as the paper did.
- ``episode_start_time = 10``: ``new_episode`` runs 10 tics with no input before handing over,
  so an episode's first state is at episode time 10. ``episode_timeout = 2100`` tics counted
  from there: 525 agent steps, after which the episode ends (``get_episode_time()`` 2110).
- Rewards in ViZDoom: a living reward of -0.0001 per tic (-0.0004 per agent step) plus +1.0
  when the player touches the green armour (thing tid 22 at (1040, -352), whose special runs
  ACS script 3: ``reward = 1.0; Exit_Normal``), which also ends the episode.
  Our tasks differ: no living reward, 0 every step, +1 at the goal. :meth:`MyWayHome.step`
  therefore returns 1.0 on the step whose tics touch the armour and 0.0 otherwise, so that an
  evaluation counts successes exactly as with simjax's env (ViZDoom's own running total stays
  available as ``game.get_total_reward()``).
- The map's ENTER script (ACS script 2) teleports the player to a uniform random map spot of
  tids 10..26 (``random(10, 26)``, 17 spots) and sets a uniform random angle
  (``random(0.0, 1.0)`` of a turn, so a multiple of 1/65536 turn). The first frame of an
  episode is rendered after this teleport (verified: it equals the frame rendered after
  placing the player at the same pose; see :meth:`MyWayHome.new_episode`).

Choosing the start pose (what we found, vizdoom 1.3.2)
------------------------------------------------------
- ``send_game_command("warp X Y")`` is refused unless the game runs with ``+sv_cheats 1``,
  and then truncates to integer coordinates ("warp 575.372 -171.77" lands on (575, -171);
  spot 16 is at (575.372, -171.77)) and keeps the angle. We found no console command that
  sets the player's angle (the engine has ``turn180``; ``setangle``/``angle`` do not exist).
- ``puke N [a b c]`` (run ACS script N with up to 3 integer arguments) works without cheats;
  ``puke 2`` re-runs the ENTER script, i.e. draws another random spot and angle.
- ``set_doom_map`` only picks a map; the scenario has one.
- Re-drawing episodes until the ENTER script's spot is the wanted one works for the spot
  (1 in 17) but the angle is a uniform 16-bit draw: facing exactly east is a 1 in 65536 event.
- What we do: at construction we write a copy of ``my_way_home.wad`` whose BEHAVIOR lump has
  one more ACS script, number 4, taking (x, y, angle) as ACS fixed-point numbers and running
  ``SetActorPosition(0, x, y, 0.0, 0); SetActorAngle(0, angle)``, the very calls the ENTER
  script makes, assembled by hand into the lump's compressed ACSe bytecode
  (:func:`patched_behavior`). Every other lump and scripts 1-3 are byte-for-byte the shipped
  ones, and the tests check that a seed gives the same episode (pose and frames) in the
  patched and the shipped wad. ``new_episode(start=(x, y, angle_deg))`` runs the ENTER script
  as usual, then ``puke 4 ...`` during one no-input tic, so the pose is exact to ViZDoom's own
  resolution: 1/65536 map unit and 1/65536 turn (0.0055 deg). To keep the episode clock
  identical to a natural start, that tic is taken from the start period: the episode is
  started with ``episode_start_time`` 9 and ``episode_timeout`` 2101, so play begins at
  episode time 10 and times out at 2110 after 525 steps, exactly as the scenario's own
  episodes. (The one difference: ViZDoom charges the living reward for that tic, so
  ``get_total_reward()`` starts at -0.0001 instead of 0; our reward ignores it.)

The paper's tasks: the ICM code's own wads
------------------------------------------
The paper's three settings are the ICM code's three scenario files (``icm_scenarios``; vendored
in ``assets/icm/``): the same map, each with its own ENTER script (dense: ViZDoom's rule;
sparse: spot 10 at an angle of 0-3.6 degrees; very sparse: spot 15 at 176.4-183.6 degrees).
``MyWayHome(scenario="sparse")`` loads one of them unchanged, so ``new_episode()`` starts where
that file starts the player, drawn by ZDoom's own random numbers; ``open_task`` opens the game
for any MyWayHome task (``TASK_SCENARIOS``). The starts that are no scenario's (spot 10 or 16
facing exactly east) are placed with script 4 in the patched shipped wad, as above.

Reading the pose back
---------------------
- POSITION_X / POSITION_Y read back as exact Doom fixed-point values (``x * 65536`` is an
  integer), e.g. spot 16 reads (575.3719940185547, -171.77000427246094).
- ANGLE reads back in degrees in [0, 360) as ``BAM * 360 / (2**32 - 1)`` (ViZDoom divides by
  ANGLE_MAX, not 2**32), so it is 2.3e-10 relative too large: 270 deg reads
  270.0000000628643. :meth:`MyWayHome.pose` undoes that and returns the exact angle
  ``BAM * 360 / 2**32``.
- After the step that ends an episode ViZDoom renders no frame (``get_state()`` is None) but
  the game variables keep their last values.

Speed (2026-11-27, the project's 2-core Xeon VM, one Python process driving one engine
process, 160x120 RGB + depth): about 7,900 agent steps a second (4 tics each, with ``step``
and a copy of the frame and depth every step; 8,600 for bare ``make_action``), 4,000-7,500
while other work shared the machine; ``new_episode`` about 1 ms; constructing a
:class:`MyWayHome` (engine start, patched wad written) 0.15-0.25 s.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import struct
import tempfile
from functools import cache

import numpy as np
import vizdoom as vzd

from simjax.envs.doom import icm_scenarios
from simjax.envs.doom.doom_render import area_matrix
from simjax.envs.doom.motion import FORWARD, NOOP, TURN_LEFT, TURN_RIGHT
from simjax.envs.doom.mywayhome_map import SPAWN_SPOTS
from simjax.envs.doom.wad import Wad

TICS_PER_STEP = 4
LIVING_REWARD_PER_TIC = -0.0001  # the scenario's; our tasks have none
GOAL_REWARD = 1.0
SCREEN_H, SCREEN_W = 120, 160

# How ViZDoom plays each MyWayHome task: (the ICM scenario whose wad it loads, its ENTER script
# placing the player; or None: the patched shipped wad, with the player placed at ``start``, an
# (x, y, angle_deg) for MyWayHome.new_episode)
TASK_SCENARIOS = {
    "maze-dense": ("dense", None),
    "maze-sparse": ("sparse", None),
    "maze-very-sparse": ("very-sparse", None),
    "maze-spot10-east": (None, (float(SPAWN_SPOTS[10][0]), float(SPAWN_SPOTS[10][1]), 0.0)),
    "maze-spot16-east": (None, (float(SPAWN_SPOTS[16][0]), float(SPAWN_SPOTS[16][1]), 0.0)),
}

_BUTTON_OF_ACTION = {TURN_LEFT: "TURN_LEFT", TURN_RIGHT: "TURN_RIGHT", FORWARD: "MOVE_FORWARD"}
_PLACE_SCRIPT = 4  # the ACS script number we add to the wad
# sha256 of the shipped wad's BEHAVIOR lump (vizdoom 1.3.2); patched_behavior relies on its layout
_BEHAVIOR_SHA256 = "2b53583618c44a47ed923b9af232769b172bd76b0185f1ade46686ccf1023476"


# ---------------------------------------------------------------------------------------------
# The patched wad: one more ACS script that places the player.


def patched_behavior(behavior: bytes) -> bytes:
    """The scenario's BEHAVIOR lump with ACS script 4 ``(x, y, angle)`` added.

    Script 4 runs ``SetActorPosition(0, x, y, 0.0, 0); SetActorAngle(0, angle);`` on its
    activator (the player who typed ``puke``): x, y in ACS fixed point (units * 65536), angle
    in fixed-point turns (65536 = 360 deg). These are the two calls the ENTER script makes.

    The lump is ACC's "ACSe" format: a header ``ACS\\0`` + offset, the compressed bytecode
    (one-byte p-codes; two bytes from 240 on), then SPTR (script table, 8-byte entries:
    number, type, argument count, address) and MINI (map variable values) chunks, then
    the chunk offset and the ``ACSe`` tag just before the old-style directory that the header
    points to. We keep the code of scripts 1-3 and the MINI chunk byte for byte, append
    script 4's code, and rebuild the tables around them. P-codes (ZDoom's p_acs.h):
    PUSHBYTE 167, PUSHSCRIPTVAR 28, PUSH2BYTES 176, SETACTORPOSITION 283, DROP 54,
    SETACTORANGLE 276, TERMINATE 1.
    """
    if hashlib.sha256(behavior).hexdigest() != _BEHAVIOR_SHA256:
        raise RuntimeError(
            "my_way_home.wad's BEHAVIOR lump is not the one vizdoom 1.3.2 ships; "
            "patched_behavior() was written for that exact lump and must be re-checked"
        )
    old_code = behavior[8:0x4C]  # scripts 1 (0x08), 2 (0x14) and 3 (0x40)
    place = bytes(
        [
            0xA7, 0x00,  # PUSHBYTE 0            tid 0: the activator
            0x1C, 0x00,  # PUSHSCRIPTVAR 0       x
            0x1C, 0x01,  # PUSHSCRIPTVAR 1       y
            0xB0, 0x00, 0x00,  # PUSH2BYTES 0 0  z = 0.0, no teleport fog
            0xF0, 0x2B,  # SETACTORPOSITION (283)
            0x36,  # DROP                        its success flag
            0xA7, 0x00,  # PUSHBYTE 0            tid 0
            0x1C, 0x02,  # PUSHSCRIPTVAR 2       angle
            0xF0, 0x24,  # SETACTORANGLE (276)
            0x01,  # TERMINATE
        ]
    )
    out = bytearray(b"ACS\0\0\0\0\0") + old_code
    place_at = len(out)
    out += place
    out += b"\0" * (-len(out) % 4)
    # old-format loaders' directory points at one TERMINATE per script (ZDoom ignores it)
    compat = []
    for _ in range(4):
        compat.append(len(out))
        out += struct.pack("<i", 1)
    chunks_at = len(out)
    sptr = b"".join(
        struct.pack("<HBBi", number, kind, argc, address)
        for number, kind, argc, address in (
            (1, 1, 0, 0x08),  # OPEN
            (2, 4, 0, 0x14),  # ENTER
            (3, 0, 0, 0x40),  # closed: armour touched
            (_PLACE_SCRIPT, 0, 3, place_at),  # closed, 3 arguments
        )
    )
    out += b"SPTR" + struct.pack("<i", len(sptr)) + sptr
    mini = behavior.index(b"MINI")
    out += behavior[mini : mini + 8 + struct.unpack_from("<i", behavior, mini + 4)[0]]
    out += struct.pack("<i", chunks_at) + b"ACSe"
    dir_at = len(out)
    out += struct.pack("<i", 4)
    for i, (number, argc) in enumerate(((1, 0), (2, 0), (3, 0), (_PLACE_SCRIPT, 3))):
        out += struct.pack("<iii", number, compat[i], argc)
    out += struct.pack("<i", 0)  # no strings
    out[4:8] = struct.pack("<i", dir_at)
    return bytes(out)


def write_patched_wad(path: str) -> str:
    """Write ``my_way_home.wad`` with :func:`patched_behavior` applied to ``path``; return it."""
    shipped = Wad.load(os.path.join(vzd.scenarios_path, "my_way_home.wad"))
    patched = Wad([(n, patched_behavior(d) if n == "BEHAVIOR" else d) for n, d in shipped.lumps])
    with open(path, "wb") as f:
        f.write(patched.to_bytes())
    return path


# ---------------------------------------------------------------------------------------------


def _exact_angle_deg(read: float) -> float:
    """ViZDoom's ANGLE reading (BAM * 360 / (2**32 - 1)) as the exact angle BAM * 360 / 2**32."""
    bam = round(read * (2**32 - 1) / 360.0) % 2**32
    return bam * 360.0 / 2**32


class MyWayHome:
    """ViZDoom's MyWayHome at 160x120 RGB with depth, driven with simjax's 4 actions.

    ``seed`` seeds ViZDoom (``set_seed``) before the first episode; ``new_episode(seed=s)``
    reseeds, so the same seed and actions give the same episode, pose for pose and pixel for
    pixel. ``patched=False`` loads the shipped wad unchanged (then ``start`` is unavailable);
    it exists for the test that the patch changes nothing else. ``scenario`` (dense, sparse or
    very-sparse) loads that ICM wad unchanged instead: its ENTER script places the player, and
    ``start`` is unavailable.
    """

    def __init__(self, seed: int = 0, *, depth: bool = True, patched: bool = True, scenario: str | None = None):
        self._tmpdir = None
        game = vzd.DoomGame()
        game.load_config(os.path.join(vzd.scenarios_path, "my_way_home.cfg"))
        if scenario is not None:
            game.set_doom_scenario_path(str(icm_scenarios.wad_path(scenario)))
            patched = False
        elif patched:
            self._tmpdir = tempfile.mkdtemp(prefix="simjax_vizdoom_")
            game.set_doom_scenario_path(
                write_patched_wad(os.path.join(self._tmpdir, "my_way_home_place.wad"))
            )
        self.patched, self.scenario = patched, scenario
        game.set_window_visible(False)
        game.set_screen_format(vzd.ScreenFormat.RGB24)
        game.set_screen_resolution(vzd.ScreenResolution.RES_160X120)
        game.set_depth_buffer_enabled(depth)
        game.set_available_game_variables(
            [vzd.GameVariable.POSITION_X, vzd.GameVariable.POSITION_Y, vzd.GameVariable.ANGLE]
        )
        game.set_sound_enabled(False)
        game.set_mode(vzd.Mode.PLAYER)
        game.set_seed(int(seed))
        self.game = game
        self.start_time = game.get_episode_start_time()  # 10 in the cfg
        self.timeout = game.get_episode_timeout()  # 2100 in the cfg
        try:
            game.init()
        except Exception:
            self._cleanup()
            raise

        names = [b.name for b in game.get_available_buttons()]
        missing = set(_BUTTON_OF_ACTION.values()) - set(names)
        if missing:
            self.close()
            raise RuntimeError(f"my_way_home.cfg lacks buttons {sorted(missing)}; it has {names}")
        self.button_names = tuple(names)
        self._vectors = {NOOP: [0] * len(names)}
        for action, button in _BUTTON_OF_ACTION.items():
            vec = [0] * len(names)
            vec[names.index(button)] = 1
            self._vectors[action] = vec
        self._state = None
        self.steps = 0
        self.succeeded = False

    # -- episodes ------------------------------------------------------------------------------

    def new_episode(self, start: tuple[float, float, float] | None = None, seed: int | None = None):
        """Start an episode; ``seed`` (optional) reseeds ViZDoom first.

        ``start=None`` keeps the scenario's rule (the ENTER script's random spot and angle).
        ``start=(x, y, angle_deg)`` then places the player there (see the module docstring:
        ACS script 4 through ``puke`` in the last start tic), to ViZDoom's resolution of
        1/65536 unit and 1/65536 turn. Raises ValueError if ViZDoom refuses the spot (a
        position where the player's box would overlap a wall) and RuntimeError if the pose
        read back is not the one asked for.
        """
        game = self.game
        if seed is not None:
            game.set_seed(int(seed))
        if start is None:
            game.set_episode_start_time(self.start_time)
            game.set_episode_timeout(self.timeout)
            game.new_episode()
        else:
            if not self.patched:
                raise ValueError("start needs the patched shipped wad (MyWayHome(patched=True), no scenario)")
            x, y, angle_deg = (float(v) for v in start)
            fx, fy = round(x * 65536), round(y * 65536)
            fa = round((angle_deg % 360.0) / 360.0 * 65536) % 65536
            game.set_episode_start_time(self.start_time - 1)
            game.set_episode_timeout(self.timeout + 1)
            game.new_episode()
            game.send_game_command(f"puke {_PLACE_SCRIPT} {fx} {fy} {fa}")
            game.make_action(self._vectors[NOOP], 1)
            got = self.pose()
            if (round(got[0] * 65536), round(got[1] * 65536)) != (fx, fy):
                raise ValueError(f"ViZDoom did not place the player at {(x, y)} (blocked?): {got}")
            if round(got[2] / 360.0 * 65536) % 65536 != fa or game.get_episode_time() != self.start_time:
                raise RuntimeError(f"placement at {start} read back {got} at tic {game.get_episode_time()}")
        self._state = game.get_state()
        self.steps = 0
        self.succeeded = False

    def step(self, action: int) -> tuple[float, bool]:
        """Play ``action`` (TURN_LEFT 0, TURN_RIGHT 1, FORWARD 2, NOOP 3) for 4 tics.

        Returns (reward, done) with our tasks' reward: 1.0 on the step that touches the armour
        (the episode then ends), 0.0 otherwise; done is also true at the 2100-tic timeout.
        Success is read from ViZDoom's running total: touching the armour adds +1.0 and the
        living reward can take off at most 0.21, so the total is above 0.5 exactly when the
        goal was reached.
        """
        if self.game.is_episode_finished():
            raise RuntimeError("the episode is over; call new_episode()")
        self.game.make_action(self._vectors[int(action)], TICS_PER_STEP)
        self.steps += 1
        done = self.game.is_episode_finished()
        self._state = None if done else self.game.get_state()
        if done and self.game.get_total_reward() > 0.5:
            self.succeeded = True
            return GOAL_REWARD, True
        return 0.0, done

    def is_finished(self) -> bool:
        return self.game.is_episode_finished()

    # -- observations --------------------------------------------------------------------------

    def pose(self) -> tuple[float, float, float]:
        """(x, y, angle_deg): position in map units (exact fixed-point values), angle in
        degrees in [0, 360), counter-clockwise from east (+x), made exact (see module doc).
        After the final step of an episode this is ViZDoom's last reported pose."""
        g = self.game
        return (
            g.get_game_variable(vzd.GameVariable.POSITION_X),
            g.get_game_variable(vzd.GameVariable.POSITION_Y),
            _exact_angle_deg(g.get_game_variable(vzd.GameVariable.ANGLE)),
        )

    def _live_state(self):
        if self._state is None:
            raise RuntimeError("no frame: the episode is over (ViZDoom renders none after the last step)")
        return self._state

    def frame(self) -> np.ndarray:
        """The current (120, 160, 3) uint8 RGB frame (a copy)."""
        return np.array(self._live_state().screen_buffer, dtype=np.uint8, copy=True)

    def depth(self) -> np.ndarray:
        """The current (120, 160) uint8 depth buffer (a copy; about 7.35 map units a level)."""
        buf = self._live_state().depth_buffer
        if buf is None:
            raise RuntimeError("depth is off (MyWayHome(depth=False))")
        return np.array(buf, dtype=np.uint8, copy=True)

    # -- lifetime ------------------------------------------------------------------------------

    def _cleanup(self):
        if self._tmpdir is not None:
            shutil.rmtree(self._tmpdir, ignore_errors=True)
            self._tmpdir = None

    def close(self):
        """Stop the engine process and delete the patched wad."""
        if getattr(self, "game", None) is not None:
            self.game.close()
            self.game = None
        self._cleanup()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def open_task(task: str, seed: int = 0, *, depth: bool = True) -> tuple[MyWayHome, tuple | None]:
    """ViZDoom playing MyWayHome task ``task`` (one of ``TASK_SCENARIOS``) and the ``start`` to
    give ``new_episode``: (the game, None) for the paper's tasks, whose ICM wad places the
    player; (the patched shipped wad, the pose) for the starts no scenario has."""
    if task not in TASK_SCENARIOS:
        raise ValueError(f"ViZDoom plays {', '.join(TASK_SCENARIOS)}, not {task!r}")
    scenario, start = TASK_SCENARIOS[task]
    return MyWayHome(seed, depth=depth, scenario=scenario), start


# ---------------------------------------------------------------------------------------------
# 42x42 frames


# (n_out, n_in) weights of an area-average resize along one axis: the renderer's, so that the
# frames compared in the tests are averaged by the same rule simjax draws by (cached: resize42
# runs once per evaluated step)
area_weights = cache(area_matrix)


def resize_area(image: np.ndarray, out_h: int, out_w: int) -> np.ndarray:
    """Area-average ``image`` (H, W) or (H, W, C) to (out_h, out_w[, C]); float64, unrounded."""
    img = np.asarray(image, dtype=np.float64)
    wy, wx = area_weights(img.shape[0], out_h), area_weights(img.shape[1], out_w)
    if img.ndim == 2:
        return wy @ img @ wx.T
    # two matrix products per channel: numpy's three-operand einsum takes ~200 ms a frame
    return np.stack([wy @ img[..., c] @ wx.T for c in range(img.shape[2])], axis=-1)


def resize42(frame: np.ndarray) -> np.ndarray:
    """The 160x120 frame area-averaged to 42x42 (channels kept), rounded to uint8.

    This is OpenCV's ``cv2.resize(frame, (42, 42), interpolation=cv2.INTER_AREA)`` for a
    shrink by a non-integer factor (160/42 and 120/42), computed exactly in float64 and
    rounded half to even like OpenCV's saturate_cast (OpenCV itself sums in float32, so a
    value within ~1e-4 of .5 may round the other way there). No cv2 dependency.

    Caution on "the paper's pipeline": noreward-rl's own Doom wrapper (``src/env_wrapper.py``,
    ``BufferedObsEnv._convert``) does not use INTER_AREA. For each raw tic frame it takes the
    pixelwise max of that frame and the previous tic's, converts it to luminance
    (0.299 R + 0.587 G + 0.114 B, truncated to uint8) and resizes that with PIL's
    ``Image.BILINEAR`` to 42x42 (which, for a shrink, is a triangle filter widened to the scale
    factor, not a box), then stacks 4 such frames 4 tics apart.
    """
    frame = np.asarray(frame)
    if frame.shape[:2] != (SCREEN_H, SCREEN_W):
        raise ValueError(f"expected a {SCREEN_H}x{SCREEN_W} frame, got {frame.shape}")
    return np.clip(np.rint(resize_area(frame, 42, 42)), 0, 255).astype(np.uint8)


# ---------------------------------------------------------------------------------------------


def random_walk(
    seed: int,
    steps: int,
    actions=None,
    *,
    start: tuple[float, float, float] | None = None,
    game: MyWayHome | None = None,
) -> dict:
    """Play one ViZDoom episode and record it.

    Starts an episode with ViZDoom seeded by ``seed`` (and placed at ``start`` if given), then
    plays ``actions``, or if None ``steps`` uniform random actions among the 4 drawn with
    ``np.random.default_rng(seed)``. ``game`` reuses an open :class:`MyWayHome` (an engine
    start costs ~0.15 s); otherwise one is opened and closed here.

    Returns numpy arrays, index 0 being the start, before any action:
    ``actions`` (T,) int32, ``done`` (T,) bool, ``xy`` (T+1, 2) float64,
    ``angle_deg`` (T+1,) float64, ``frames`` (F, 120, 160, 3) uint8, ``depth`` (F, 120, 160)
    uint8; plus ``length`` = T (int) and ``reached_goal`` (bool). If the episode ends early
    (armour touched, or the 525-step timeout) the walk stops there: T is the number of actions
    played, shorter than asked, the last ``xy``/``angle_deg`` are ViZDoom's last reported pose,
    and F = T because ViZDoom renders no frame after an episode's last step (F = T + 1
    otherwise).
    """
    if actions is None:
        actions = np.random.default_rng(seed).integers(0, 4, size=int(steps))
    actions = np.asarray(actions, dtype=np.int32).reshape(-1)
    own = game is None
    if own:
        game = MyWayHome(seed)
    try:
        game.new_episode(start=start, seed=seed)
        poses, frames, depths, dones = [game.pose()], [game.frame()], [game.depth()], []
        for a in actions:
            _, done = game.step(int(a))
            poses.append(game.pose())
            dones.append(done)
            if done:
                break
            frames.append(game.frame())
            depths.append(game.depth())
        reached = game.succeeded
    finally:
        if own:
            game.close()
    poses = np.asarray(poses, dtype=np.float64)
    n = len(dones)
    return {
        "actions": actions[:n].copy(),
        "done": np.asarray(dones, dtype=bool),
        "xy": poses[:, :2],
        "angle_deg": poses[:, 2],
        "frames": np.stack(frames),
        "depth": np.stack(depths),
        "length": n,
        "reached_goal": bool(reached),
    }


__all__ = [
    "GOAL_REWARD",
    "LIVING_REWARD_PER_TIC",
    "MyWayHome",
    "TASK_SCENARIOS",
    "open_task",
    "TICS_PER_STEP",
    "area_weights",
    "patched_behavior",
    "random_walk",
    "resize42",
    "resize_area",
    "write_patched_wad",
]
