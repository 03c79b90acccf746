"""DeepMind Lab's random maze with rooms (``maze_generation.randomMazeGeneration``), in JAX.

``explore-goals`` (Explore Goal Locations Small) draws its map with DMLab's text-maze generator;
this module does the same steps, in the same order, as jit/vmap-able JAX. What each step does
was read from google-deepmind/lab (the files named; read, not copied):

``deepmind/engine/lua_maze_generation.cc`` (``LuaMazeGeneration::CreateRandom``) runs, on a
``height`` x ``width`` grid of text cells that starts all wall (``'*'``):

1. Rooms (``MakeSeparateRectangles``, ``text_maze_generation/algorithm.cc``): up to ``maxRooms``
   rectangles on the odd grid. A proposal's short side is uniform in [min, mid] and its long side
   that plus uniform [mid, max] - mid, on one axis chosen by a coin, with min, mid, max in "odd
   cells" ((size - 1) / 2 of ``roomMinSize``, ``roomMaxSize``); its corner uniform where it fits.
   A proposal overlapping a room already placed (``IsSeparate`` in ``text_maze.h``: rooms may
   touch across one wall line) is thrown away; ``retryCount`` (1000) throw-aways end the
   search. Here each room is drawn from the proposal distribution restricted to the proposals
   that fit, which is what rejection sampling draws; the search stops when none fits. (DMLab
   could give up earlier only after 1000 misses in a row while some proposal fits, each with
   probability at least 1/48 here: below 1e-9.)
2. Corridors (``FillSpaceWithMaze``, ``FillWithMaze``): every 4-connected region of odd cells
   outside the rooms, found in row-major order, becomes a randomised depth-first
   ("recursive backtracker") spanning tree: from the top of the stack, step two cells to a
   uniformly chosen unvisited neighbour, carving the cell between; pop when there is none.
3. Connections (``RandomConnectRegions``): between every two regions (rooms and corridor
   trees) that touch, one uniformly chosen wall cell between them becomes a connector; each
   other candidate also becomes one with probability ``extraConnectionProbability``.
4. Simplify (``RemoveDeadEnds``, then ``RemoveAllHorseshoeBends``): empty cells with at most
   one non-wall neighbour are walled up until none is left (connectors count as non-wall and
   stay), so a corridor tree keeps only its paths between connectors; then U-shaped detours
   ("horseshoe bends") of corridors are pulled straight, one bend per call as DMLab does
   (``RemoveHorseshoeBends`` stops at the first bend it finds in row-major order, and
   ``RemoveAllHorseshoeBends`` goes back to size 1 only after removing a bend of size > 1).
5. Entities (``AddNEntitiesToEachRoom``): in each room, ``roomSpawnCount`` random empty cells
   become spawn points ``'P'``, then ``roomObjectCount`` of the rest become objects (for
   Explore Goal Locations, the goal candidates ``'G'``).
6. A connector whose far side (toward the region with the larger id, i.e. the corridor for a
   room-corridor pair) was walled up becomes wall; the others open (``hasDoors`` false: no door).

Cells are ``kGridWidth`` = 100 world units (``lua_maze_generation.cc``); text row ``r``, column
``c`` (0-based) is centred at x = 100 c + 50, y = 100 (height - 1 - r) + 50 (``toWorldPos``).

The level's settings (``game_scripts/factories/explore/factory.lua`` defaults, used unchanged by
``goal_locations_factory.lua`` and ``levels/contributed/dmlab30/explore_goal_locations_small.lua``):
mazeHeight = mazeWidth = 11, roomCount (maxRooms) 4, roomMinSize 3, roomMaxSize 5, spawnCount 5,
objectCount 4 (entity 'G'), extraConnectionProbability 0.0, hasDoors false, maxVariations 1 (every
room gets the same variation, the corridors the default one), decalFrequency 0.1; retryCount is
not set, so ``lua_maze_generation.cc``'s default 1000; simplify is not set, so true.
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np

from simjax.envs import raycaster
from simjax.envs.maze import Layout

WALL, EMPTY, CONNECTOR, OUTSIDE = 0, 1, 2, 3  # text-cell states ('*', ' ', a connector, off the grid)
MISHMASH_SIZE = 20  # walls and floors in texture_sets.MISHMASH (simjax.envs.dmlab.look.MISHMASH_WALLS, _FLOORS)
_FAR = 1e9
# DMLab's PathDirections order, as (d_row, d_col)
_DIRS = ((1, 0), (-1, 0), (0, 1), (0, -1))


@dataclasses.dataclass(frozen=True)
class DMLabMazeGenerator:
    """DMLab's ``randomMazeGeneration`` with Explore Goal Locations Small's settings (module
    docstring), turned into raycaster layouts: every face between an open and a walled text
    cell is a wall row.

    Looks (``look``): DMLab draws its maps in the theme MISHMASH (common/make_map.lua:44;
    themes/themes.lua): every room is one variation ('A': maxVariations 1,
    lua_maze_generation.cc:279-287) whose wall and floor are drawn once per map from MISHMASH's
    20 walls and 20 floors (``theme:mazeVariation``), and the corridors are the default
    variation, MISHMASH's first wall and floor (lg_style_01_wall_green, lg_style_01_floor_orange).
    A face takes the variation of the open cell it faces. With ``look`` "dmlab" (the default)
    each maze draws so: a wall row's texture indexes ``simjax.envs.dmlab.look.MISHMASH_WALLS``
    and the layout's ``floor`` grid holds each cell's index into ``MISHMASH_FLOORS``. DMLab also
    hangs pictures (decals) on about a tenth of the wall faces (decalFrequency 0.1); they are left
    out. With "invented" (the look before 2026-12-07) each maze draws two distinct looks of the
    raycaster's twelve, one for faces of room cells and one for corridor faces, each face taking
    a uniformly random look instead with probability ``decal_frequency`` (the stand-in for a
    decal), and there is no floor grid."""

    height: int = 11  # factory.lua mazeHeight
    width: int = 11  # factory.lua mazeWidth
    max_rooms: int = 4  # factory.lua roomCount, passed as maxRooms
    room_min_size: int = 3  # factory.lua roomMinSize
    room_max_size: int = 5  # factory.lua roomMaxSize
    room_spawn_count: int = 5  # factory.lua spawnCount ('P' per room)
    room_object_count: int = 4  # factory.lua objectCount ('G' per room: goal candidates)
    extra_connection_prob: float = 0.0  # factory.lua extraConnectionProbability
    simplify: bool = True  # lua_maze_generation.cc default
    cell_size: float = 100.0  # lua_maze_generation.cc kGridWidth
    decal_frequency: float = 0.1  # factory.lua decalFrequency
    look: str = "dmlab"  # "dmlab" or "invented" (the class docstring)

    def __post_init__(self):
        if self.look not in ("dmlab", "invented"):
            raise ValueError(f"look must be 'dmlab' or 'invented', got {self.look!r}")
        for name in ("height", "width", "room_min_size", "room_max_size"):
            v = getattr(self, name)
            if v < 3 or v % 2 == 0:
                raise ValueError(f"{name} must be odd and at least 3, got {v}")
        if self.room_max_size < self.room_min_size:
            raise ValueError("room_max_size must be at least room_min_size")
        if self.room_max_size > min(self.height, self.width) - 2:
            raise ValueError("room_max_size must be at least two less than the maze's height and width")
        if not 0.0 <= self.extra_connection_prob <= 1.0:
            raise ValueError(f"extra_connection_prob must be in [0, 1], got {self.extra_connection_prob}")
        if not 0.0 <= self.decal_frequency <= 1.0:
            raise ValueError(f"decal_frequency must be in [0, 1], got {self.decal_frequency}")
        if self.max_rooms < 1 or self.room_spawn_count < 1 or self.room_object_count < 1:
            raise ValueError("max_rooms, room_spawn_count and room_object_count must be at least 1")
        if self.cell_size < 64:
            raise ValueError(f"cell_size must be at least 64 (the player is 32 wide), got {self.cell_size}")

    # ---- static tables (numpy) ------------------------------------------------------------
    @property
    def nodes_shape(self) -> tuple[int, int]:
        """The odd cells ("nodes"): node (i, j) is text cell (2 i + 1, 2 j + 1)."""
        return (self.height - 1) // 2, (self.width - 1) // 2

    @property
    def num_spawns(self) -> int:
        return self.max_rooms * self.room_spawn_count

    @property
    def num_goals(self) -> int:
        return self.max_rooms * self.room_object_count

    def room_proposals(self) -> tuple[np.ndarray, np.ndarray]:
        """Every rectangle ``MakeRandomRectangle`` can propose, in node units (row, col,
        height - 1, width - 1: a room covers nodes row..row+h), and its probability."""
        return _room_proposals(self.height, self.width, self.room_min_size, self.room_max_size)

    def cell_centres(self) -> np.ndarray:
        """(height, width, 2) world x, y of every text cell's centre (DMLab's toWorldPos)."""
        r, c = np.meshgrid(np.arange(self.height), np.arange(self.width), indexing="ij")
        s = self.cell_size
        return np.stack([c * s + s / 2, (self.height - 1 - r) * s + s / 2], -1).astype(np.float32)

    def faces(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The wall rows: (F, 4) segments and, per row, the flat indices of the text cells on
        either side (a row stands where exactly one of them is open). The grid's outer ring is
        always wall, so only faces touching the interior are listed."""
        return _faces(self.height, self.width, self.cell_size)

    def template(self) -> Layout:
        """Every face standing with look 0, the goal and every spawn slot at the first
        interior cell; ``generate`` fills in a maze."""
        segs, _, _ = self.faces()
        rows = [(*s, 0) for s in segs]
        first = self.cell_centres()[1, 1]
        goal = (float(first[0]), float(first[1]), raycaster.GOAL, 10.0, False)
        layout = Layout.build(rows, [goal], np.repeat(first[None], self.num_spawns, 0))
        if self.look == "dmlab":  # the floor grid, cell (iy, ix) = text cell (height - 1 - iy, ix)
            layout = layout._replace(floor=jnp.zeros((self.height, self.width), jnp.int32))
        return layout

    # ---- the generator (JAX) ------------------------------------------------------------
    def maze(self, key: jax.Array) -> dict:
        """One maze as arrays: ``grid`` (height, width) int8 final cell states (WALL / EMPTY),
        ``room`` (height, width) bool room cells, ``spawn_cells`` (num_spawns, 2) and
        ``goal_cells`` (num_goals, 2) text (row, col) of 'P' / 'G' with ``spawn_valid`` /
        ``goal_valid`` masks, and ``raw`` the grid before simplification (connectors marked
        CONNECTOR), for tests."""
        k_rooms, k_dfs, k_conn, k_ent = jax.random.split(key, 4)
        room_rc, room_valid = self._rooms(k_rooms)
        node_room = self._node_rooms(room_rc, room_valid)
        region, tree = self._corridors(k_dfs, node_room)
        chosen, far_cell = self._connect(k_conn, region)
        room_cells = self._room_cells(room_rc, room_valid)
        raw = self._carve(room_cells, tree, chosen)
        grid = simplify(raw, self.width) if self.simplify else raw
        # 6. connectors: open where the cell beyond them (toward the larger region id) is open
        ci, cj = _edge_cells(self.nodes_shape)
        fr, fc = far_cell
        conn_open = chosen & (grid[fr, fc] == EMPTY)
        grid = jnp.where(grid == CONNECTOR, WALL, grid)
        grid = grid.at[jnp.asarray(ci), jnp.asarray(cj)].set(
            jnp.where(conn_open, EMPTY, grid[jnp.asarray(ci), jnp.asarray(cj)]))
        spawn_cells, spawn_valid, goal_cells, goal_valid = self._entities(k_ent, room_rc, room_valid)
        return dict(grid=grid, room=room_cells, spawn_cells=spawn_cells, spawn_valid=spawn_valid,
                    goal_cells=goal_cells, goal_valid=goal_valid, raw=raw, room_rc=room_rc, room_valid=room_valid)

    def generate(self, key: jax.Array, template: Layout | None = None) -> Layout:
        """A random maze as a layout: the walls, a goal drawn uniformly from the 'G' cells
        (goal_locations_factory.lua: ``random:uniformInt(1, #goalLocations)`` once per episode),
        and the 'P' cells as spawn spots (slots of missing rooms sit far away, at 1e9)."""
        if template is None:
            with jax.ensure_compile_time_eval():
                template = self.template()
        k_maze, k_goal, k_look = jax.random.split(key, 3)
        m = self.maze(k_maze)
        open_flat = (m["grid"] == EMPTY).reshape(-1)
        room_flat = m["room"].reshape(-1)
        _, side_a, side_b = self.faces()
        a_open, b_open = open_flat[side_a], open_flat[side_b]
        standing = a_open != b_open
        in_room = jnp.where(a_open, room_flat[side_a], room_flat[side_b])
        floor = None
        if self.look == "invented":
            k_theme, k_decal, k_pick = jax.random.split(k_look, 3)
            corridor_look = jax.random.randint(k_theme, (), 0, raycaster.NUM_TEXTURES)
            room_look = (corridor_look + jax.random.randint(jax.random.fold_in(k_theme, 1), (), 1, raycaster.NUM_TEXTURES)
                         ) % raycaster.NUM_TEXTURES
            decal = jax.random.bernoulli(k_decal, self.decal_frequency, standing.shape)
            look = jnp.where(in_room, room_look, corridor_look)
            look = jnp.where(decal, jax.random.randint(k_pick, standing.shape, 0, raycaster.NUM_TEXTURES), look)
        else:  # MISHMASH: the rooms' wall and floor drawn once, the corridors' the first ones
            k_wall, k_floor = jax.random.split(k_look)
            room_wall = jax.random.randint(k_wall, (), 0, MISHMASH_SIZE)
            room_floor = jax.random.randint(k_floor, (), 0, MISHMASH_SIZE)
            look = jnp.where(in_room, room_wall, 0)
            floor = jnp.where(m["room"], room_floor, 0).astype(jnp.int32)[::-1]  # world rows: y up

        walls, boxes = template.walls, template.boxes
        v_open, h_open = ~standing[walls.v_index], ~standing[walls.h_index]
        walls = walls._replace(
            texture=look.astype(jnp.int32),
            v_lo=jnp.where(v_open, _FAR, walls.v_lo), v_hi=jnp.where(v_open, -_FAR, walls.v_hi),
            h_lo=jnp.where(h_open, _FAR, walls.h_lo), h_hi=jnp.where(h_open, -_FAR, walls.h_hi),
        )
        boxes = jnp.where(~standing[:, None], _FAR, boxes)
        centres = jnp.asarray(self.cell_centres())
        goal_idx = jax.random.categorical(k_goal, jnp.where(m["goal_valid"], 0.0, -jnp.inf))
        gr, gc = m["goal_cells"][goal_idx]
        items = template.items._replace(pos=centres[gr, gc][None])
        sr, sc = m["spawn_cells"][:, 0], m["spawn_cells"][:, 1]
        spawns = jnp.where(m["spawn_valid"][:, None], centres[sr, sc], _FAR)
        return template._replace(walls=walls, boxes=boxes, items=items, spawns=spawns, floor=floor)

    # ---- steps ----------------------------------------------------------------------------
    def _rooms(self, key):
        """1. Up to max_rooms rooms, each drawn from the proposals that fit."""
        props, prob = self.room_proposals()
        compat = jnp.asarray(_separate(props))
        prob = jnp.asarray(prob, jnp.float32)
        area = jnp.asarray((2 * props[:, 2] + 1) * (2 * props[:, 3] + 1))
        target = int(self.height * self.width * 1.0)  # density 1.0 (lua_maze_generation.cc)
        fits = jnp.ones(prob.shape, bool)
        cells, active = jnp.int32(0), jnp.bool_(True)
        picks, valid = [], []
        for kk in jax.random.split(key, self.max_rooms):
            p = jnp.where(fits, prob, 0.0)
            ok = active & (p.sum() > 0) & (cells < target)
            idx = jax.random.categorical(kk, jnp.where(p > 0, jnp.log(jnp.where(p > 0, p, 1.0)), -jnp.inf))
            fits = fits & (compat[idx] | ~ok)
            cells = cells + jnp.where(ok, area[idx], 0)
            active = ok
            picks.append(idx)
            valid.append(ok)
        rc = jnp.asarray(props)[jnp.stack(picks)]  # (R, 4) node row, col, h, w
        return rc, jnp.stack(valid)

    def _node_rooms(self, room_rc, room_valid):
        """(nr, nc) int: the room id (1..R) covering each node, 0 outside rooms."""
        nr, nc = self.nodes_shape
        i, j = jnp.meshgrid(jnp.arange(nr), jnp.arange(nc), indexing="ij")
        ids = jnp.zeros((nr, nc), jnp.int32)
        for k in range(self.max_rooms):
            r, c, h, w = room_rc[k]
            inside = room_valid[k] & (i >= r) & (i <= r + h) & (j >= c) & (j <= c + w)
            ids = jnp.where(inside, k + 1, ids)
        return ids

    def _room_cells(self, room_rc, room_valid):
        """(height, width) bool: the text cells of the rooms."""
        i, j = jnp.meshgrid(jnp.arange(self.height), jnp.arange(self.width), indexing="ij")
        out = jnp.zeros((self.height, self.width), bool)
        for k in range(self.max_rooms):
            r, c, h, w = room_rc[k]
            inside = (i >= 2 * r + 1) & (i <= 2 * (r + h) + 1) & (j >= 2 * c + 1) & (j <= 2 * (c + w) + 1)
            out = out | (room_valid[k] & inside)
        return out

    def _corridors(self, key, node_room):
        """2. Depth-first spanning trees of the nodes outside rooms: (region id per node,
        flat; tree edges (E,) bool). Corridor ids start after the rooms' (max_rooms + 1...)."""
        nr, nc = self.nodes_shape
        n = nr * nc
        nbr, edge = (jnp.asarray(t) for t in _node_neighbours(self.nodes_shape))
        room_flat = node_room.reshape(-1)
        free = room_flat == 0
        num_edges = int(np.asarray(_node_edges(self.nodes_shape)[0]).size)

        def body(t, s):
            visited, stack, sp, region, next_id, tree = s
            k = jax.random.fold_in(key, t)
            # an empty stack starts a new region at the first unvisited free node (row-major)
            todo = free & ~visited
            start = jnp.argmax(todo)
            can_start = (sp == 0) & todo.any()
            cur = stack[jnp.maximum(sp - 1, 0)]
            nb = nbr[cur]
            ok = (nb >= 0) & free[jnp.maximum(nb, 0)] & ~visited[jnp.maximum(nb, 0)]
            step = (sp > 0) & ok.any()
            choice = jax.random.categorical(k, jnp.where(ok, 0.0, -jnp.inf))
            nxt = nb[choice]
            pop = (sp > 0) & ~ok.any()
            new = jnp.where(can_start, start, nxt)
            push = can_start | step
            visited = visited.at[new].set(visited[new] | push)
            region = region.at[new].set(jnp.where(push, jnp.where(can_start, next_id, region[cur]), region[new]))
            tree = tree.at[edge[cur, choice]].set(tree[edge[cur, choice]] | step)
            stack = stack.at[jnp.where(push, sp, n)].set(new, mode="drop")
            sp = jnp.where(push, sp + 1, jnp.where(pop, sp - 1, sp))
            next_id = next_id + can_start.astype(jnp.int32)
            return visited, stack, sp, region, next_id, tree

        init = (jnp.zeros(n, bool), jnp.zeros(n, jnp.int32), jnp.int32(0), room_flat,
                jnp.int32(self.max_rooms + 1), jnp.zeros(num_edges, bool))
        _, _, _, region, _, tree = jax.lax.fori_loop(0, 2 * n, body, init)
        return region, tree

    def _connect(self, key, region):
        """3. One uniformly chosen connector per pair of touching regions, plus extras."""
        a, b = (jnp.asarray(v) for v in _node_edges(self.nodes_shape))
        ra, rb = region[a], region[b]
        cand = ra != rb
        lo, hi = jnp.minimum(ra, rb), jnp.maximum(ra, rb)
        num_ids = self.max_rooms + self.nodes_shape[0] * self.nodes_shape[1] + 2
        pair = lo * num_ids + hi
        k_pick, k_extra = jax.random.split(key)
        u = jnp.where(cand, jax.random.uniform(k_pick, cand.shape), -1.0)
        best = jax.ops.segment_max(u, pair, num_segments=num_ids * num_ids)
        chosen = cand & (u >= best[pair])
        if self.extra_connection_prob > 0:
            # DMLab skips an extra connector next to a connector already placed, but two
            # connectors are never 4-neighbours on the odd grid, so every candidate is
            # independent
            chosen = chosen | (cand & jax.random.bernoulli(k_extra, self.extra_connection_prob, cand.shape))
        # the cell beyond each connector, toward the region with the larger id
        far_node = jnp.where(ra > rb, a, b)
        nc = self.nodes_shape[1]
        far_cell = (2 * (far_node // nc) + 1, 2 * (far_node % nc) + 1)
        return chosen, far_cell

    def _carve(self, room_cells, tree, chosen):
        """The text grid before simplification: rooms, every node, the tree edges open;
        connectors marked."""
        nr, nc = self.nodes_shape
        grid = jnp.where(room_cells, EMPTY, WALL).astype(jnp.int8)
        grid = grid.at[1:2 * nr + 1:2, 1:2 * nc + 1:2].set(EMPTY)
        ci, cj = (jnp.asarray(v) for v in _edge_cells(self.nodes_shape))
        cur = grid[ci, cj]
        cur = jnp.where(tree, EMPTY, cur)
        cur = jnp.where(chosen, CONNECTOR, cur)
        return grid.at[ci, cj].set(cur.astype(jnp.int8))

    def _entities(self, key, room_rc, room_valid):
        """5. Per room, a random order of its cells: the first room_spawn_count are 'P', the
        next room_object_count 'G'."""
        big = self.room_max_size
        dr, dc = np.meshgrid(np.arange(big), np.arange(big), indexing="ij")
        dr, dc = jnp.asarray(dr.ravel()), jnp.asarray(dc.ravel())
        spawn, spawn_ok, goal, goal_ok = [], [], [], []
        ns, ng = self.room_spawn_count, self.room_object_count
        for k, kk in enumerate(jax.random.split(key, self.max_rooms)):
            r, c, h, w = room_rc[k]
            inside = (dr < 2 * h + 1) & (dc < 2 * w + 1)
            order = jnp.argsort(jnp.where(inside, jax.random.uniform(kk, inside.shape), 2.0))
            count = inside.sum()
            cells = jnp.stack([2 * r + 1 + dr[order], 2 * c + 1 + dc[order]], -1)
            spawn.append(cells[:ns])
            spawn_ok.append(room_valid[k] & (jnp.arange(ns) < count))
            goal.append(cells[ns:ns + ng])
            goal_ok.append(room_valid[k] & (jnp.arange(ns, ns + ng) < count))
        cat = lambda xs: jnp.concatenate(xs, 0)
        return cat(spawn), cat(spawn_ok), cat(goal), cat(goal_ok)


# ---- simplification (JAX) -------------------------------------------------------------------
def simplify(grid: jnp.ndarray, width: int) -> jnp.ndarray:
    """4. ``RemoveDeadEnds`` then ``RemoveAllHorseshoeBends`` on a (H, W) grid of WALL / EMPTY /
    CONNECTOR cells."""
    return remove_horseshoe_bends(remove_dead_ends(grid), width)


def _shift(padded, pad, dr, dc, shape):
    """The (H, W) window of ``padded`` moved by (dr, dc): cell (i, j) holds (i + dr, j + dc)."""
    h, w = shape
    return padded[pad + dr:pad + dr + h, pad + dc:pad + dc + w]


def remove_dead_ends(grid: jnp.ndarray) -> jnp.ndarray:
    """Wall up empty cells with at most one non-wall neighbour (neighbours off the grid are
    not counted, as ``VisitNeighbours`` skips them; border cells are wall anyway) until none
    is left. DMLab's pass follows each dead end's chain; the cells removed are the same
    whatever the order (a cell only ever loses neighbours), so here every dead end goes at
    once, round after round."""
    shape = grid.shape

    def nonwall(g):
        p = jnp.pad(g, 1, constant_values=WALL)
        return sum((_shift(p, 1, dr, dc, shape) != WALL).astype(jnp.int32) for dr, dc in _DIRS)

    def cond(s):
        return s[1]

    def body(s):
        g, _ = s
        dead = (g == EMPTY) & (nonwall(g) <= 1)
        return jnp.where(dead, WALL, g).astype(g.dtype), dead.any()

    return jax.lax.while_loop(cond, body, (grid, jnp.bool_(True)))[0]


@functools.cache
def _bend_rules(max_size: int) -> np.ndarray:
    """RemoveHorseshoeBendAtPos's conditions as rows (u, v, state, lo, hi): for bends up to
    ``max_size``, the cell at pos + u * u_dir + v * v_dir must hold ``state`` where the size
    ``s`` has lo <= s <= hi. With ``s`` the size: (u, 0) and (u, -1) wall for u in [0, s);
    (u, 1) empty and (u, 2) wall for u in [-1, s]; (-2, 1) and (s + 1, 1) wall; (-1, 0) and
    (s, 0) empty."""
    every = (0, max_size)
    rules = [(-2, 1, WALL, *every), (-1, 0, EMPTY, *every)]
    for u in range(-1, max_size + 2):
        if u >= 0:
            rules += [(u, 0, WALL, u + 1, max_size), (u, -1, WALL, u + 1, max_size)]
        rules += [(u, 1, EMPTY, u, max_size), (u, 2, WALL, u, max_size)]
        if u >= 2:
            rules.append((u, 1, WALL, u - 1, u - 1))
        if u >= 1:
            rules.append((u, 0, EMPTY, u, u))
    return np.asarray(rules, np.int32)


def bend_matches(grid: jnp.ndarray, size) -> jnp.ndarray:
    """(4, H, W) bool: where a horseshoe bend of ``size`` (may be traced, 1 <= size <= W - 4)
    has its mouth, per direction in DMLab's order; ``pos`` is the wall cell at the mouth.

    Every rule of every direction is one gather of the padded grid (4 x rules, H, W): one
    operation, not one slice per rule, which XLA:CPU compiles in a fraction of the time."""
    h, w = grid.shape
    max_size = w - 4
    pad = max_size + 3
    p = jnp.pad(grid, pad, constant_values=OUTSIDE)
    rules = _bend_rules(max_size)
    u, v = rules[:, 0], rules[:, 1]
    dirs = np.asarray(_DIRS)  # v_dir per direction; u_dir = {v_dir.d_col, -v_dir.d_row}
    dr = u[None] * dirs[:, 1:2] + v[None] * dirs[:, 0:1]  # (4, R)
    dc = -u[None] * dirs[:, 0:1] + v[None] * dirs[:, 1:2]
    rows = pad + dr[..., None, None] + np.arange(h)[:, None]  # (4, R, H, 1)
    cols = pad + dc[..., None, None] + np.arange(w)[None, :]  # (4, R, 1, W)
    cells = p[rows, cols]  # (4, R, H, W)
    active = (rules[:, 3] <= size) & (size <= rules[:, 4])  # (R,)
    ok = ~active[:, None, None] | (cells == jnp.asarray(rules[:, 2], grid.dtype)[:, None, None])
    return ok.all(axis=1)


def _pull(grid, pos, d, size):
    """Pull the bend at ``pos`` in direction ``d`` one cell toward its mouth: (u, 0) takes
    (u, 1)'s content (empty, as the bend matched) for u in [0, size), then (u, 1) becomes wall
    for u in [-1, size]."""
    h, w = grid.shape
    v = jnp.asarray(_DIRS)[d]
    u_dir = jnp.stack([v[1], -v[0]])
    u = jnp.arange(-1, w - 3)  # sizes are at most w - 4
    row0 = pos[None] + u[:, None] * u_dir[None]  # (U, 2) the cells (u, 0)
    row1 = row0 + v[None]  # (U, 2) the cells (u, 1)
    off = jnp.asarray([h, w])  # out of range: dropped
    walls_at = jnp.where((u <= size)[:, None], row1, off)
    empty_at = jnp.where(((u >= 0) & (u < size))[:, None], row0, off)
    grid = grid.at[walls_at[:, 0], walls_at[:, 1]].set(WALL, mode="drop")
    return grid.at[empty_at[:, 0], empty_at[:, 1]].set(EMPTY, mode="drop")


def _remove_one_bend(grid, size):
    """RemoveHorseshoeBends(size): the first bend in row-major order (first direction at that
    cell), pulled until it no longer matches (RemoveHorseshoeBendAtPos); (grid, removed).

    One loop: while searching, the position is the first cell where any direction matches;
    once a bend was pulled, the cell one step back toward its mouth (DMLab's ``pos - v_dir``)."""
    h, w = grid.shape

    def cond(s):
        return s[3]

    def body(s):
        g, pos, chained, _ = s
        m = bend_matches(g, size)  # (4, H, W)
        first = jnp.argmax(m.any(0).reshape(-1))
        pos = jnp.where(chained, pos, jnp.stack([first // w, first % w]))
        at = m[:, pos[0], pos[1]]
        go = at.any()
        d = jnp.argmax(at)
        g = jnp.where(go, _pull(g, pos, d, size), g)
        nxt = pos - jnp.asarray(_DIRS)[d]
        inb = (nxt >= 0).all() & (nxt[0] < h) & (nxt[1] < w)
        return g, jnp.clip(nxt, 0, jnp.asarray([h - 1, w - 1])), chained | go, go & inb

    g, _, removed, _ = jax.lax.while_loop(cond, body, (grid, jnp.zeros(2, jnp.int32), jnp.bool_(False),
                                                       jnp.bool_(True)))
    return g, removed


def remove_horseshoe_bends(grid: jnp.ndarray, width: int) -> jnp.ndarray:
    """RemoveAllHorseshoeBends: sizes 1, 2, ... while size + 3 < width; after removing a bend
    of size > 1, back to size 1 (after one of size 1, on to size 2, as DMLab does)."""

    def cond(s):
        return s[1] + 3 < width

    def body(s):
        g, i = s
        g, removed = _remove_one_bend(g, i)
        return g, jnp.where(removed & (i != 1), 1, i + 1)

    return jax.lax.while_loop(cond, body, (grid, jnp.int32(1)))[0]


# ---- static tables -----------------------------------------------------------------------
@functools.cache
def _room_proposals(height, width, min_size, max_size):
    nr, nc = (height - 1) // 2, (width - 1) // 2
    lo, hi = (min_size - 1) // 2, (max_size - 1) // 2
    mid = (lo + hi) // 2
    probs = {}
    uniform = lambda a, b: [(v, 1.0 / (b - a + 1)) for v in range(a, b + 1)] if a < b else [(a, 1.0)]
    for w0, pw in uniform(lo, mid):
        for h0, ph in uniform(lo, mid):
            for coin in (0, 1):
                for extra, pe in uniform(mid, hi):
                    w = w0 + (extra - mid if coin == 0 else 0)
                    h = h0 + (extra - mid if coin == 1 else 0)
                    for row, pr in uniform(0, nr - h - 1):
                        for col, pc in uniform(0, nc - w - 1):
                            k = (row, col, h, w)
                            probs[k] = probs.get(k, 0.0) + pw * ph * 0.5 * pe * pr * pc
    keys = sorted(probs)
    # (row, col, h, w) in node units: the room covers nodes row..row+h, col..col+w
    return np.asarray(keys, np.int32), np.asarray([probs[k] for k in keys], np.float64)


def _separate(props):
    """IsSeparate of the grown rectangles (text cells [2 r + 1, 2 (r + h) + 1]): touching is
    allowed, overlapping is not."""
    r0, c0 = 2 * props[:, 0] + 1, 2 * props[:, 1] + 1
    r1, c1 = r0 + 2 * props[:, 2] + 1, c0 + 2 * props[:, 3] + 1  # exclusive ends
    return ((r1[:, None] <= r0[None]) | (r1[None] <= r0[:, None])
            | (c1[:, None] <= c0[None]) | (c1[None] <= c0[:, None]))


@functools.cache
def _node_edges(shape):
    """Edges between 4-neighbour nodes: (a, b) flat node ids; horizontal ones first."""
    nr, nc = shape
    a, b = [], []
    for i in range(nr):
        for j in range(nc - 1):
            a.append(i * nc + j)
            b.append(i * nc + j + 1)
    for i in range(nr - 1):
        for j in range(nc):
            a.append(i * nc + j)
            b.append((i + 1) * nc + j)
    return np.asarray(a, np.int32), np.asarray(b, np.int32)


@functools.cache
def _edge_cells(shape):
    """The text cell between the two nodes of each edge."""
    nc = shape[1]
    a, b = _node_edges(shape)
    ra, ca, rb, cb = a // nc, a % nc, b // nc, b % nc
    return (ra + rb + 1).astype(np.int32), (ca + cb + 1).astype(np.int32)


@functools.cache
def _node_neighbours(shape):
    """(N, 4) neighbour node (-1 off the grid) and (N, 4) edge id, per DMLab direction."""
    nr, nc = shape
    a, b = _node_edges(shape)
    edge_of = {(int(x), int(y)): e for e, (x, y) in enumerate(zip(a, b))}
    edge_of.update({(y, x): e for (x, y), e in list(edge_of.items())})
    nbr = -np.ones((nr * nc, 4), np.int32)
    eid = np.zeros((nr * nc, 4), np.int32)
    for n in range(nr * nc):
        i, j = divmod(n, nc)
        for d, (dr, dc) in enumerate(_DIRS):
            ii, jj = i + dr, j + dc
            if 0 <= ii < nr and 0 <= jj < nc:
                nbr[n, d] = ii * nc + jj
                eid[n, d] = edge_of[(n, ii * nc + jj)]
    return nbr, eid


@functools.cache
def _faces(height, width, s):
    segs, side_a, side_b = [], [], []
    for r in range(1, height - 1):  # vertical faces between (r, c) and (r, c + 1)
        for c in range(width - 1):
            x = (c + 1) * s
            segs.append((x, (height - 1 - r) * s, x, (height - r) * s))
            side_a.append(r * width + c)
            side_b.append(r * width + c + 1)
    for r in range(height - 1):  # horizontal faces between (r, c) and (r + 1, c)
        for c in range(1, width - 1):
            y = (height - 1 - r) * s
            segs.append((c * s, y, (c + 1) * s, y))
            side_a.append(r * width + c)
            side_b.append((r + 1) * width + c)
    return np.asarray(segs, np.float32), np.asarray(side_a, np.int32), np.asarray(side_b, np.int32)


def to_text(grid, spawn_cells=None, goal_cells=None, spawn_valid=None, goal_valid=None) -> str:
    """A maze as DMLab prints it (``'*'`` wall, ``' '`` open, ``'P'`` / ``'G'``), on the host."""
    g = np.asarray(grid)
    chars = np.where(g == WALL, "*", np.where(g == CONNECTOR, "+", " ")).astype("<U1")
    for cells, valid, ch in ((spawn_cells, spawn_valid, "P"), (goal_cells, goal_valid, "G")):
        if cells is not None:
            for (r, c), ok in zip(np.asarray(cells), np.asarray(valid)):
                if ok:
                    chars[r, c] = ch
    return "\n".join("".join(row) for row in chars)


__all__ = ["DMLabMazeGenerator", "simplify", "remove_dead_ends", "remove_horseshoe_bends", "bend_matches", "to_text",
           "WALL", "EMPTY", "CONNECTOR"]
