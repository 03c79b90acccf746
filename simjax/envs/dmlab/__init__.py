"""The paper's two DeepMind Lab levels rebuilt on the maze env (``simjax.envs.maze``):
``melon`` (Stairway to Melon) and ``explore_goals`` (Explore Goal Locations Small, its mazes
from DMLab's generator, ``dmlab_maze``), moving as DMLab's player does (``pmove``) and drawn with
DMLab's textures, sky and item models (``look``)."""
