"""A plain, sequential Python rendering of DeepMind Lab's maze simplification, step by step as
``deepmind/level_generation/text_maze_generation/algorithm.cc`` (google-deepmind/lab) does it:
``RemoveDeadEnds`` (row-major visit, following each dead end's chain) and
``RemoveAllHorseshoeBends`` (``RemoveHorseshoeBends`` short-circuits after the first bend;
``RemoveHorseshoeBendAtPos`` pulls a bend until it no longer matches). The tests use it as the
oracle for the vectorised JAX version in ``simjax.envs.dmlab.dmlab_maze``.

Grids are lists of lists of characters: '*' wall, ' ' empty, '+' connector; off the grid reads
as '\\0' (neither wall nor empty), as ``TextMaze::GetCell`` returns.
"""

DIRS = ((1, 0), (-1, 0), (0, 1), (0, -1))  # PathDirections, (d_row, d_col)


def _get(g, r, c):
    return g[r][c] if 0 <= r < len(g) and 0 <= c < len(g[0]) else "\0"


def remove_dead_ends(g):
    h, w = len(g), len(g[0])
    for r0 in range(h):
        for c0 in range(w):
            r, c = r0, c0
            while True:
                if g[r][c] != " ":
                    break
                empty = walls = visits = 0
                last = None
                for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):  # VisitNeighbours, in bounds only
                    rr, cc = r + dr, c + dc
                    if not (0 <= rr < h and 0 <= cc < w):
                        continue
                    v = g[rr][cc]
                    if v == " ":
                        last = (rr, cc)
                        empty += 1
                    elif v == "*":
                        walls += 1
                    visits += 1
                if walls + 1 < visits:
                    break
                g[r][c] = "*"
                if empty == 0:
                    break
                r, c = last
    return g


def _bend_at(g, pos, size):
    is_wall = lambda p: _get(g, *p) == "*"
    is_corr = lambda p: _get(g, *p) == " "
    add = lambda p, k, d: (p[0] + k * d[0], p[1] + k * d[1])
    removed = False
    while True:
        if not is_wall(pos):
            break
        found = False
        for v in DIRS:
            u = (v[1], -v[0])
            at = lambda uu, vv, pos=pos, u=u, v=v: add(add(pos, uu, u), vv, v)
            if not all(is_wall(at(k, 0)) and is_wall(at(k, -1)) for k in range(size)):
                continue
            if not all(is_corr(at(k, 1)) for k in range(-1, size + 1)):
                continue
            if not all(is_wall(at(k, 2)) for k in range(-1, size + 1)):
                continue
            if not (is_wall(at(-2, 1)) and is_wall(at(size + 1, 1))):
                continue
            if not (is_corr(at(-1, 0)) and is_corr(at(size, 0))):
                continue
            removed = True
            for k in range(-1, size + 1):
                p1 = at(k, 1)
                if 0 <= k < size:
                    p0 = at(k, 0)
                    g[p0[0]][p0[1]] = g[p1[0]][p1[1]]
                g[p1[0]][p1[1]] = "*"
            pos = add(pos, -1, v)
            found = True
            break
        if not found:
            break
    return removed


def remove_horseshoe_bends(g):
    h, w = len(g), len(g[0])
    i = 1
    while i + 3 < w:
        removed = False
        for r in range(h):
            for c in range(w):
                removed = removed or _bend_at(g, (r, c), i)
        i = 1 if (removed and i != 1) else i + 1
    return g


def simplify(text_rows):
    """DMLab's simplify on a maze given as strings; returns strings."""
    g = [list(row) for row in text_rows]
    remove_dead_ends(g)
    remove_horseshoe_bends(g)
    return ["".join(row) for row in g]
