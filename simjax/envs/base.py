"""brax's ``Env`` and ``State``: the interface every simjax env implements, imported quietly.

Importing anything from brax imports mujoco.mjx, whose warp module prints "Failed to import
warp: ..." and "Failed to import mujoco_warp: ..." to stdout wherever NVIDIA's warp is not
installed. warp only serves mujoco's GPU physics, which simjax never uses, so exactly those
lines are dropped here; anything else the import prints passes through.
"""

from __future__ import annotations

import contextlib
import io
import sys

_NOISE = ("Failed to import warp:", "Failed to import mujoco_warp:")

_printed = io.StringIO()
with contextlib.redirect_stdout(_printed):
    from brax.envs.base import Env, State
sys.stdout.write("".join(line for line in _printed.getvalue().splitlines(keepends=True)
                         if not line.startswith(_NOISE)))

__all__ = ["Env", "State"]
