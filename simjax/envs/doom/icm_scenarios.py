"""The paper's three MyWayHome settings, as the ICM code's scenario files start them.

The paper takes its dense, sparse and very sparse MyWayHome tasks from the ICM code
(pathak22/noreward-rl, ``doomFiles/wads/``, BSD licence: ``assets/icm/LICENSE.noreward-rl``).
Its three wads, vendored byte for byte in ``assets/icm/``, hold the same map as ViZDoom's
``my_way_home.wad`` and differ only in the ACS ENTER script that places the player at the start
of every episode:

    dense        SetActorPosition at map spot random(10, 26); SetActorAngle(random(0.0, 1.0))
    sparse       map spot 10, (240, -176);            SetActorAngle(random(0.0, 0.01))
    very sparse  map spot 15, (543.986, -672.089);    SetActorAngle(random(0.49, 0.51))

ACC compiles a fixed-point literal to ``int(value * 65536)`` (0.49 -> 32112, 0.51 -> 33423,
0.01 -> 655), ZDoom's ``random(lo, hi)`` draws an integer uniformly from lo to hi inclusive, and
``SetActorAngle`` takes it as 1/65536 of a turn, Doom's angle unit (``motion.Pose.angle``). So:
sparse faces east, 0 to 3.598 degrees; very sparse faces west, 176.40 to 183.59 degrees.

``SPARSE`` and ``VERY_SPARSE`` are those rules as numbers; ``enter_start`` reads them back out of
a wad's compiled ENTER script (the tests check that the vendored wads say exactly these), and
``vizdoom_ref`` loads the wads into real ViZDoom. Standard library only.
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import NamedTuple

from simjax.envs.doom.wad import Wad

ASSETS = Path(__file__).resolve().parent / "assets" / "icm"
WAD_FILES = {"dense": "my_way_home_dense.wad", "sparse": "my_way_home_sparse.wad",
             "very-sparse": "my_way_home_verySparse.wad"}
ANGLE_UNITS = 65536  # a turn, in SetActorAngle's fixed point and in Doom's angle unit


class EnterStart(NamedTuple):
    """Where an ENTER script puts the player: a map spot (TID) drawn uniformly from ``spots``
    and an angle from ``angles`` (Doom angle units, 65536 a turn), both inclusive ranges."""

    spots: tuple[int, int]
    angles: tuple[int, int]


DENSE = EnterStart((10, 26), (0, ANGLE_UNITS))  # 65536 is a whole turn: angle 0 again
SPARSE = EnterStart((10, 10), (0, 655))
VERY_SPARSE = EnterStart((15, 15), (32112, 33423))
STARTS = {"dense": DENSE, "sparse": SPARSE, "very-sparse": VERY_SPARSE}


def wad_path(setting: str) -> Path:
    """The vendored ICM wad of ``setting`` (dense, sparse or very-sparse)."""
    if setting not in WAD_FILES:
        raise ValueError(f"unknown ICM setting {setting!r}; known: {', '.join(WAD_FILES)}")
    return ASSETS / WAD_FILES[setting]


# ACS p-codes (ZDoom's p_acs.h) that the scenarios' ENTER scripts use before their loop
_PUSHNUMBER, _ADD, _SUBTRACT, _ASSIGNSCRIPTVAR, _PUSHSCRIPTVAR, _PUSHMAPVAR = 3, 14, 15, 25, 28, 29
_DROP, _RANDOM, _PUSHBYTE, _PUSH2BYTES, _GETACTORX, _GETACTORY = 54, 57, 167, 176, 196, 197
_SETACTORANGLE, _SETACTORPOSITION = 276, 283
_ENTER = 4  # script type in the SPTR table


class _Random(NamedTuple):
    lo: int
    hi: int


def _chunks(behavior: bytes) -> dict[str, bytes]:
    """The chunks (SPTR, MINI, ...) of an ACSe BEHAVIOR lump."""
    if behavior[:4] != b"ACS\0":
        raise ValueError("not an ACS BEHAVIOR lump")
    directory = struct.unpack_from("<i", behavior, 4)[0]
    if behavior[directory - 4:directory] != b"ACSe":
        raise ValueError("only ACC's compressed ACSe format is read")
    at = struct.unpack_from("<i", behavior, directory - 8)[0]
    chunks = {}
    while at < directory - 8:
        name, size = behavior[at:at + 4].decode("ascii"), struct.unpack_from("<i", behavior, at + 4)[0]
        chunks[name] = behavior[at + 8:at + 8 + size]
        at += 8 + size
    return chunks


def enter_start(behavior: bytes) -> EnterStart:
    """The start rule of the ENTER script in a compiled BEHAVIOR lump: runs its code up to
    ``SetActorAngle`` on a stack that keeps ``random(lo, hi)`` as a range, and reads the TID
    that ``SetActorPosition`` takes the player's x and y from, and the angle ``SetActorAngle`` sets.
    A ValueError if the script does anything else first."""
    chunks = _chunks(behavior)
    sptr = chunks["SPTR"]
    entries = [struct.unpack_from("<HBBi", sptr, i) for i in range(0, len(sptr), 8)]
    enter = [address for _, kind, _, address in entries if kind == _ENTER]
    if len(enter) != 1:
        raise ValueError(f"expected one ENTER script, found {len(enter)}")
    mini = chunks.get("MINI", b"\0\0\0\0")
    first_var = struct.unpack_from("<i", mini, 0)[0]
    map_vars = {first_var + i: v for i, v in enumerate(struct.unpack_from(f"<{len(mini) // 4 - 1}i", mini, 4))}

    def as_range(v):
        return (v.lo, v.hi) if isinstance(v, _Random) else (v, v)

    stack, script_vars, spots, pc = [], {}, None, enter[0]
    while True:
        op = behavior[pc]
        pc += 1
        if op >= 240:  # a two-byte p-code
            op, pc = 240 + ((op - 240) << 8) + behavior[pc], pc + 1
        if op == _PUSHNUMBER:
            stack.append(struct.unpack_from("<i", behavior, pc)[0])
            pc += 4
        elif op == _PUSHBYTE:
            stack.append(behavior[pc])
            pc += 1
        elif op == _PUSH2BYTES:
            stack += [behavior[pc], behavior[pc + 1]]
            pc += 2
        elif op in (_PUSHSCRIPTVAR, _PUSHMAPVAR, _ASSIGNSCRIPTVAR):
            index, pc = behavior[pc], pc + 1
            if op == _ASSIGNSCRIPTVAR:
                script_vars[index] = stack.pop()
            else:
                stack.append((script_vars if op == _PUSHSCRIPTVAR else map_vars)[index])
        elif op in (_ADD, _SUBTRACT):
            b, a = stack.pop(), stack.pop()
            stack.append(a + b if op == _ADD else a - b)
        elif op == _RANDOM:
            hi, lo = stack.pop(), stack.pop()
            stack.append(_Random(min(lo, hi), max(lo, hi)))
        elif op in (_GETACTORX, _GETACTORY):
            stack.append((op, as_range(stack.pop())))
        elif op == _SETACTORPOSITION:
            _fog, _z, y, x, _tid = (stack.pop() for _ in range(5))
            if not (x[0] == _GETACTORX and y[0] == _GETACTORY and x[1] == y[1]):
                raise ValueError("SetActorPosition does not take a map spot's x and y")
            spots = x[1]
            stack.append(1)  # its success flag
        elif op == _DROP:
            stack.pop()
        elif op == _SETACTORANGLE:
            angle, _tid = stack.pop(), stack.pop()
            if spots is None:
                raise ValueError("the ENTER script sets the angle before placing the player")
            return EnterStart(spots, as_range(angle))
        else:
            raise ValueError(f"p-code {op} at {pc - 1} before SetActorAngle: not a start rule this reader knows")


def wad_start(path) -> EnterStart:
    """The start rule of the wad at ``path`` (its last BEHAVIOR lump, the one ZDoom runs)."""
    behavior = Wad.load(str(path)).find("BEHAVIOR")
    if behavior is None:
        raise ValueError(f"{path} has no BEHAVIOR lump")
    return enter_start(behavior)


def degrees(angles: tuple[int, int]) -> tuple[float, float]:
    """An angle range in degrees."""
    return tuple(a * 360.0 / ANGLE_UNITS for a in angles)


__all__ = ["ANGLE_UNITS", "DENSE", "EnterStart", "SPARSE", "STARTS", "VERY_SPARSE", "WAD_FILES", "degrees",
           "enter_start", "wad_path", "wad_start"]
