"""MyWayHome as ViZDoom plays it: the map (``mywayhome_map``), Doom's player motion
(``motion``), ZDoom's software renderer at 42x42 (``doom_render``) with Freedoom's textures
(``doom_assets``, the ``assets/`` it reads; ``wad`` reads WAD files), and the real game beside it:
``vizdoom_ref`` drives ViZDoom, ``fidelity`` measures simjax against it.

MyWayHome moves with this motion (``simjax.envs.maze``'s default, ``maze-tiny`` too) and draws with this renderer;
the DMLab worlds move with DeepMind Lab's (``simjax.envs.dmlab.pmove``; this one for their
``-doom-motion`` tasks) and draw with the raycaster's invented looks.
Imports here reach down to ``simjax.envs.raycaster`` only.
"""
