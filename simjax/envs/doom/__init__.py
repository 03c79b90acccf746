"""MyWayHome as ViZDoom plays it: the map (``mywayhome_map``), Doom's player motion
(``motion``), ZDoom's software renderer at 42x42 (``doom_render``) with Freedoom's textures
(``doom_assets``, the ``assets/`` it reads; ``wad`` reads WAD files), and the real game beside it:
``vizdoom_ref`` drives ViZDoom, ``fidelity`` measures simjax against it.

Every maze world moves with this motion (``simjax.envs.maze``), the DMLab ones too; they draw
with the raycaster's invented looks, MyWayHome with this renderer.
Imports here reach down to ``simjax.envs.raycaster`` only.
"""
