"""Convert the Freedoom graphics that ViZDoom draws MyWayHome with into one small .npz asset.

    python tools/freedoom_assets.py [--out PATH]

Reads the WADs shipped inside the installed ``vizdoom`` package (``freedoom2.wad``, the IWAD
ViZDoom renders with, and ``scenarios/my_way_home.wad``, the map) and writes the textures of
the map's walls, its floor/ceiling flat, the goal item's sprite, the palette and light tables,
and per-wall texture alignment in the row order of ``simjax/envs/doom/mywayhome_map.py``.
WADs are read with ``simjax/envs/doom/wad.py``, the project's one WAD reader, loaded from its file
together with the map module: only numpy and the standard library are used, so the asset can be
rebuilt (and the tests can check it against a fresh conversion) wherever vizdoom is installed.
See ``simjax/envs/doom/doom_assets.py`` for what each key holds.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import re
import struct

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DOOM = os.path.join(REPO, "simjax", "envs", "doom")
DEFAULT_OUT = os.path.join(DOOM, "assets", "freedoom_mywayhome.npz")
FLAT = "FLAT1_1"
SPRITE = "ARM1A0"


def load_doom_module(name: str):
    """The module ``simjax/envs/doom/<name>.py``, loaded from its file so that jax (imported by
    simjax.envs) is not needed here."""
    spec = importlib.util.spec_from_file_location(name, os.path.join(DOOM, f"{name}.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


Wad = load_doom_module("wad").Wad


def decode_picture(data: bytes) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """Decode a Doom picture (patch/sprite): palette indices (H, W), a mask of the texels it
    draws, and its (leftoffset, topoffset). Columns are lists of posts; a post's topdelta no
    greater than the previous one continues below it (DeePsea's tall-patch convention, which
    ZDoom reads; plain patches never trigger it)."""
    width, height, left, top = struct.unpack_from("<hhhh", data, 0)
    index = np.zeros((height, width), np.uint8)
    mask = np.zeros((height, width), bool)
    for x in range(width):
        (pos,) = struct.unpack_from("<I", data, 8 + 4 * x)
        prev = -1
        while data[pos] != 0xFF:
            delta, length = data[pos], data[pos + 1]
            y = delta + prev if delta <= prev else delta
            prev = y
            texels = np.frombuffer(data, np.uint8, length, pos + 3)[: max(0, height - y)]
            index[y:y + len(texels), x] = texels
            mask[y:y + len(texels), x] = True
            pos += length + 4
    return index, mask, (left, top)


def read_composites(wad: Wad) -> dict[str, dict]:
    """TEXTURE1/TEXTURE2 definitions (Doom format): name -> width, height, scale bytes and
    patches as (originx, originy, patch name)."""
    pnames_lump = wad.find("PNAMES")
    (count,) = struct.unpack_from("<i", pnames_lump, 0)
    pnames = [struct.unpack_from("8s", pnames_lump, 4 + 8 * i)[0].rstrip(b"\0").decode().upper()
              for i in range(count)]
    textures = {}
    for lump in filter(None, (wad.find("TEXTURE1"), wad.find("TEXTURE2"))):
        (count,) = struct.unpack_from("<i", lump, 0)
        for off in struct.unpack_from(f"<{count}i", lump, 4):
            name, _flags, scale_x, scale_y, width, height, _coldir, n = struct.unpack_from(
                "<8sHBBhhih", lump, off)
            parts = [struct.unpack_from("<hhh", lump, off + 22 + 10 * i) for i in range(n)]
            textures.setdefault(name.rstrip(b"\0").decode().upper(), dict(
                width=width, height=height, scale=(scale_x, scale_y),
                patches=[(ox, oy, pnames[p]) for ox, oy, p in parts]))
    return textures


def wall_texture(wad: Wad, composites: dict, name: str) -> tuple[np.ndarray, dict]:
    """A wall texture's palette indices (H, W), row 0 at the top, in ZDoom's lookup order:
    a TEXTURE1/2 composite first, else a flat (64x64 as a wall), else a lone patch.
    Texels of a composite that no patch covers stay palette index 0, as in ZDoom, whose
    solid walls draw them as palette colour 0 (none of MyWayHome's textures has any).
    Also returns facts worth reporting (source, holes, clipped patches)."""
    if name in composites:
        tex = composites[name]
        if tex["scale"] != (0, 0):
            raise ValueError(f"{name}: ZDoom scale bytes {tex['scale']} would change its size")
        height, width = tex["height"], tex["width"]
        index = np.zeros((height, width), np.uint8)
        covered = np.zeros((height, width), bool)
        clipped = []
        for ox, oy, pname in tex["patches"]:
            pix, mask, _ = decode_picture(wad.find(pname, ("P",)) or wad.find(pname))
            ph, pw = pix.shape
            y0, y1, x0, x1 = max(oy, 0), min(oy + ph, height), max(ox, 0), min(ox + pw, width)
            if (y0, y1, x0, x1) != (oy, oy + ph, ox, ox + pw):
                clipped.append(pname)
            if y1 <= y0 or x1 <= x0:
                continue
            src = (slice(y0 - oy, y1 - oy), slice(x0 - ox, x1 - ox))
            draw = mask[src]
            index[y0:y1, x0:x1][draw] = pix[src][draw]
            covered[y0:y1, x0:x1] |= draw
        return index, dict(source="composite", patches=tex["patches"], clipped=clipped,
                           holes=int((~covered).sum()))
    flat = wad.find(name, ("F",))
    if flat is not None:
        return np.frombuffer(flat, np.uint8, 4096).reshape(64, 64).copy(), dict(source="flat")
    patch = wad.find(name, ("P",))
    if patch is not None:
        pix, mask, _ = decode_picture(patch)
        return pix, dict(source="patch", holes=int((~mask).sum()))
    raise KeyError(f"no texture, flat or patch named {name}")


def parse_udmf(text: str) -> dict[str, list[dict]]:
    """UDMF TEXTMAP blocks by kind ('linedef', 'sidedef', 'vertex', ...), in file order,
    each a dict of its fields (strings unquoted, numbers as float, true/false as bool)."""
    text = re.sub(r"//[^\n]*|/\*.*?\*/", "", text, flags=re.S)
    blocks: dict[str, list[dict]] = {}
    for kind, body in re.findall(r"(\w+)\s*\{([^}]*)\}", text):
        fields = {}
        for key, value in re.findall(r"(\w+)\s*=\s*([^;]+);", body):
            value = value.strip()
            if value.startswith('"'):
                fields[key] = value[1:-1]
            elif value in ("true", "false"):
                fields[key] = value == "true"
            else:
                fields[key] = float(value)
        blocks.setdefault(kind.lower(), []).append(fields)
    return blocks


def match_walls(walls, names, textmap: dict) -> dict[str, np.ndarray]:
    """Per wall row: its linedef (matched by endpoints, either order), that linedef's front
    sidedef's offsets, and whether the row runs v2 -> v1 (Doom's u runs from v1 to v2 on the
    front side). Raises if a row matches no or several linedefs, the linedef is two-sided
    or lower-unpegged, or its texture is not the row's."""
    verts = [(v["x"], v["y"]) for v in textmap["vertex"]]
    lines, sides = textmap["linedef"], textmap["sidedef"]
    out = dict(wall_offset_x=[], wall_offset_y=[], wall_u_reversed=[], wall_linedef=[])
    for row, (x1, y1, x2, y2, tex) in enumerate(walls):
        hits = []
        for i, line in enumerate(lines):
            a, b = verts[int(line["v1"])], verts[int(line["v2"])]
            if {a, b} == {(x1, y1), (x2, y2)}:
                hits.append((i, a != (x1, y1)))
        if len(hits) != 1:
            raise ValueError(f"wall row {row} {walls[row][:4]} matches linedefs {hits}")
        i, reversed_ = hits[0]
        if lines[i].get("sideback", -1) != -1:
            raise ValueError(f"wall row {row}: linedef {i} is two-sided")
        if lines[i].get("dontpegbottom", False):
            raise ValueError(f"wall row {row}: linedef {i} is lower-unpegged; the asset "
                             "assumes every texture hangs from the ceiling")
        side = sides[int(lines[i]["sidefront"])]
        if side.get("texturemiddle", "-").upper() != names[tex]:
            raise ValueError(f"wall row {row}: linedef {i} has {side.get('texturemiddle')}, "
                             f"row says {names[tex]}")
        out["wall_offset_x"].append(side.get("offsetx", 0.0))
        out["wall_offset_y"].append(side.get("offsety", 0.0))
        out["wall_u_reversed"].append(reversed_)
        out["wall_linedef"].append(i)
    return dict(wall_offset_x=np.array(out["wall_offset_x"], np.float32),
                wall_offset_y=np.array(out["wall_offset_y"], np.float32),
                wall_u_reversed=np.array(out["wall_u_reversed"], bool),
                wall_linedef=np.array(out["wall_linedef"], np.int32))


def vizdoom_dir() -> str:
    """The installed vizdoom package's folder, found without importing its binary module."""
    spec = importlib.util.find_spec("vizdoom")
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit("vizdoom is not installed: it ships the WADs this tool reads")
    return list(spec.submodule_search_locations)[0]


def convert(vizdoom_path: str | None = None, verbose: bool = False, iwad_path: str | None = None) -> dict[str, np.ndarray]:
    """Every array the asset holds, by key; ``iwad_path`` reads the graphics from another
    freedoom2.wad than ``vizdoom_path``'s (the map still from there)."""
    vizdoom_path = vizdoom_path or vizdoom_dir()
    iwad = Wad.load(iwad_path or os.path.join(vizdoom_path, "freedoom2.wad"))
    level = Wad.load(os.path.join(vizdoom_path, "scenarios", "my_way_home.wad"))
    game_map = load_doom_module("mywayhome_map")
    names = tuple(n.upper() for n in game_map.TEXTURE_NAMES)

    playpal = np.frombuffer(iwad.find("PLAYPAL"), np.uint8, 768).reshape(256, 3).copy()
    colormap = np.frombuffer(iwad.find("COLORMAP"), np.uint8, 34 * 256).reshape(34, 256).copy()
    arrays = dict(playpal=playpal, colormap=colormap, texture_names=np.array(names))

    composites = read_composites(iwad)
    for name in names:
        index, info = wall_texture(iwad, composites, name)
        arrays[f"wall_{name}"] = playpal[index]
        arrays[f"wall_{name}_index"] = index
        if verbose:
            print(f"{name}: {index.shape[1]}x{index.shape[0]} {info}")

    flat = np.frombuffer(iwad.find(FLAT, ("F",)), np.uint8, 4096).reshape(64, 64).copy()
    arrays[f"flat_{FLAT}"] = playpal[flat]
    arrays[f"flat_{FLAT}_index"] = flat

    pix, mask, offset = decode_picture(iwad.find(SPRITE, ("S",)))
    alpha = np.where(mask, 255, 0).astype(np.uint8)[..., None]
    arrays[f"sprite_{SPRITE}"] = np.concatenate([playpal[pix] * mask[..., None], alpha], -1)
    arrays[f"sprite_{SPRITE}_offset"] = np.array(offset, np.int32)

    textmap = parse_udmf(level.find("TEXTMAP").decode("latin-1"))
    arrays.update(match_walls(game_map.WALLS, names, textmap))
    return arrays


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=DEFAULT_OUT, help="output .npz (default: %(default)s)")
    parser.add_argument("--vizdoom-dir", help="folder holding freedoom2.wad and scenarios/ "
                        "(default: the installed vizdoom package)")
    parser.add_argument("--iwad", help="read the graphics from this freedoom2.wad instead (e.g. an older "
                        "Freedoom's, for a diagnostic; the map still from --vizdoom-dir)")
    parser.add_argument("--quiet", action="store_true", help="do not print what was converted")
    args = parser.parse_args()
    if args.iwad is not None and not os.path.isfile(args.iwad):
        parser.error(f"--iwad: no file {args.iwad}")
    arrays = convert(args.vizdoom_dir, verbose=not args.quiet, iwad_path=args.iwad)
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    np.savez_compressed(args.out, **arrays)
    if not args.quiet:
        print(f"wrote {args.out} ({os.path.getsize(args.out)} bytes)")


if __name__ == "__main__":
    main()
