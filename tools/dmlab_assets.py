"""Convert the DeepMind Lab surfaces, sky and item models the DMLab worlds are drawn with into one
small .npz asset (``simjax/envs/dmlab/assets/dmlab_looks.npz``; ``simjax/envs/dmlab/look.py``
reads it).

    python tools/dmlab_assets.py [--lab GITDIR] [--miniworld GITDIR] [--out PATH] [--check]

Sources (read, never modified; licences in ``simjax/envs/dmlab/assets/DMLAB-ASSETS-LICENSE.txt``):

- google-deepmind/lab at ``LAB_COMMIT`` (a bare git mirror, ``--lab``): the shader scripts
  ``assets/scripts/lab_games.shader``, the textures ``assets/textures/...`` (.tga, CC BY 4.0,
  lab's LICENSE "License for //assets") and the item models ``assets/models/*.md3``. Each file is
  read by its blob id from ``git ls-tree``; the ids are stored in the .npz (``source_*``).
- The mirror lacks about 300 asset blobs (``git cat-file -e`` fails), among them the blue wall of
  Stairway to Melon, 15 of MISHMASH's 40 walls and floors and 4 of their glow masks (``_m``).
  Those 20 come from tomosii/Miniworld at ``MINIWORLD_COMMIT`` (``--miniworld``), whose
  ``miniworld/textures/lg_style_*`` .png files are lossless copies of lab's .tga files: every
  texture both repositories hold is checked to be pixel-identical (``verify_miniworld``; 32 of 32
  at these commits), and the run fails otherwise.
- Still missing from both: ``textures/model/apple_d``, ``lemon_d`` and ``watermelon_d`` (the fruit
  models' textures) and the side and top faces of the sky ``lg_sky_03``. ``SUBSTITUTES`` lists
  what stands in for each, and the .npz carries the list (``substitutions``).

What is stored, and how it is made (``surfaces`` etc.: see ``simjax/envs/dmlab/look.py``):

- A surface is a Quake 3 shader (``lab_games.shader``): texture stages blended in order. Each is
  composited once at full resolution (1024 x 1024) with DMLab's lighting left out (the
  ``$lightmap`` stage taken as 1, i.e. every surface at full brightness) and every animated or
  view-dependent stage replaced by its average: an ``rgbGen wave`` by the time average of the
  clamped wave, a ``tcMod scroll`` by the texture averaged along the scroll direction, a
  ``tcGen environment`` stage by the texture's mean colour. The framebuffer clamps to [0, 1]
  after each stage, as OpenGL's fixed blending does. The result is box-filtered to ``SIZE`` x
  ``SIZE`` (each stored texel the mean of a 16 x 16 block) and rounded to uint8. Row 0 is the
  image's top (t = 0), column 0 its left (s = 0), as Quake 3 maps them.
- ``surface_mean``: the mean colour (0..1) of each full-resolution composite, before the box
  filter: the summary the tests hold the stored texels to (a box filter of whole blocks keeps the
  mean, so the stored texels' mean is within rounding of it).
- The sky: Quake 3's ``skyparms`` cube (``textures/map/lab_games/sky/<name>_{up,lf,rt,ft,bk}``),
  faces box-filtered to ``SIZE``, and ``sky_elevation_rgb``: the cube's colour averaged round the
  horizon at each whole degree of elevation from -90 to 90 (``dn`` never shows above a floor, so
  the rows below the horizon repeat the lowest side-face row). The renderer draws the sky above
  the walls with this table (``look.py``).
- Items: each pickup's model (``game_scripts/common/pickups.lua``), frame 0, drawn from the side
  (looking along +y, orthographically) at 8 samples per unit, z-buffered, and box-filtered to one
  texel per world unit: an RGBA sprite with partial alpha at its edges. Texels are the model
  texture's at the interpolated (s, t) where the texture exists (the goal), else the
  substitute's flat colour. ``sprite_offsets``: (column of the model's origin, top row's height
  above the floor: the model's top + 19, since Quake 3 drops an item to 15 units above the floor
  (``FinishSpawningItem``, ITEM_RADIUS 15) and draws it 4 units higher, bobbing +-4 around that
  (``cg_ents.c`` CG_Item)).

Only numpy, Pillow (for .tga/.png) and ``git`` are used. ``--check`` rebuilds the arrays and
compares them with the packaged file instead of writing it.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import math
import os
import re
import struct
import subprocess

import numpy as np

from simjax.envs.dmlab.look import MISHMASH_FLOORS, MISHMASH_WALLS

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_OUT = os.path.join(REPO, "simjax", "envs", "dmlab", "assets", "dmlab_looks.npz")
DEFAULT_LAB = "/work/.mirror/google-deepmind+lab/repo"
DEFAULT_MINIWORLD = "/work/.mirror/tomosii+Miniworld/repo"
LAB_COMMIT = "b1db91af5b4d2f3a24466f4632a3e5e1b0829cca"
MINIWORLD_COMMIT = "a71216ab6946e70dc4a0878f088840f85fec81c0"
SIZE = 64  # stored texels a side: 1024 / 16
FULL = 1024
SAMPLES = 8  # model rasterisation samples per world unit, each way
ITEM_BASE = 15.0 + 4.0  # the model's origin above the floor (see the module docstring)

# MISHMASH's 20 floors and 20 walls, in the order the envs index them (one list, the package's)
# stairway_to_melon.map: its walls, and its floor (which also faces the cliff and the risers)
MELON_SURFACES = ("map/lab_games/lg_style_01_wall_blue",)
SURFACES = MISHMASH_FLOORS + MISHMASH_WALLS + MELON_SURFACES
SKIES = ("map/lab_games/sky/lg_sky_01",)  # lg_sky_03 is substituted (SUBSTITUTES)
SKY_FACES = ("up", "lf", "rt", "ft", "bk")
# the items in raycaster.SPRITE_LOOKS order: (name, model, texture)
ITEMS = (("goal", "models/goal_object_02.md3", "textures/model/goal_colours_d"),
         ("apple", "models/apple.md3", "textures/model/apple_d"),
         ("lemon", "models/lemon.md3", "textures/model/lemon_d"),
         ("melon", "models/watermelon.md3", "textures/model/watermelon_d"))
# what stands in for what neither repository holds: wanted -> (used, why)
SUBSTITUTES = {
    "textures/map/lab_games/sky/lg_sky_03": (
        "textures/map/lab_games/sky/lg_sky_01",
        "lg_sky_03's up, lf, rt, ft and bk faces are missing (only dn, which never shows, is "
        "present); lg_sky_01 is the same family's cube, the sky Stairway to Melon uses"),
    "textures/model/apple_d": (
        "rgb 0.85 0.08 0.08",
        "missing; no texture of the apple model exists here (apple2_d is the white base that "
        "hr_apple2's pattern levels tint), so the model is painted the invented look's apple "
        "red (raycaster.SPRITE_LOOKS), flat"),
    "textures/model/lemon_d": (
        "rgb 0.98 0.92 0.15",
        "missing; painted the invented look's lemon yellow, flat"),
    "textures/model/watermelon_d": (
        "rgb 0.05 0.40 0.12",
        "missing; painted the invented look's melon green, flat"),
}


# ---- reading the repositories ------------------------------------------------------------
class Repo:
    """A bare git directory read at one commit: blobs by path, with their ids."""

    def __init__(self, git_dir: str, commit: str, name: str):
        self.git_dir, self.commit, self.name = git_dir, commit, name

    def _git(self, *args) -> bytes:
        return subprocess.run(["git", "--git-dir", self.git_dir, *args], capture_output=True, check=True).stdout

    def blob_id(self, path: str) -> str | None:
        out = self._git("ls-tree", self.commit, "--", path).decode().split()
        return out[2] if len(out) >= 4 else None

    def read(self, path: str) -> tuple[bytes, str] | None:
        """(bytes, blob id) of ``path``, or None where the tree has no such file or the blob is absent."""
        blob = self.blob_id(path)
        if blob is None:
            return None
        try:
            return self._git("cat-file", "blob", blob), blob
        except subprocess.CalledProcessError:
            return None


def decode_image(data: bytes) -> np.ndarray:
    """(H, W, 4) float64 RGBA in 0..1, row 0 at the image's top (Pillow's order for .tga and .png)."""
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(data)).convert("RGBA"), np.float64) / 255.0


def miniworld_names(texture: str) -> tuple[str, ...]:
    """Miniworld's file names for lab's ``textures/map/lab_games/<name>`` (one of two suffixes)."""
    base = texture.rsplit("/", 1)[1]
    stem = base[:-2] if base.endswith("_d") else base
    return (f"miniworld/textures/{stem}_1.png", f"miniworld/textures/{base}_result.png")


class Sources:
    """Textures by their lab path (no extension), from lab or else Miniworld, with provenance."""

    def __init__(self, lab: Repo, miniworld: Repo):
        self.lab, self.miniworld = lab, miniworld
        self.used: dict[str, tuple[str, str, str]] = {}  # texture -> (repo, path, blob)
        self._cache: dict[str, np.ndarray] = {}

    def texture(self, name: str) -> np.ndarray | None:
        """(H, W, 4) RGBA of ``textures/...`` name ``name`` (no extension), or None."""
        if name in self._cache:
            return self._cache[name]
        path = f"assets/{name}.tga"
        got = self.lab.read(path)
        where = (f"google-deepmind/lab@{LAB_COMMIT[:7]}", path)
        if got is None and name.startswith("textures/map/lab_games/"):
            for candidate in miniworld_names(name):
                got = self.miniworld.read(candidate)
                if got is not None:
                    where = (f"tomosii/Miniworld@{MINIWORLD_COMMIT[:7]}", candidate)
                    break
        if got is None:
            return None
        data, blob = got
        self.used[name] = (*where, blob)
        self._cache[name] = decode_image(data)
        return self._cache[name]


def verify_miniworld(lab: Repo, miniworld: Repo) -> int:
    """Check that every lg_style texture both repositories hold is pixel-identical; the count."""
    listing = miniworld._git("ls-tree", "--name-only", miniworld.commit, "miniworld/textures/").decode().split()
    checked = 0
    for path in listing:
        m = re.fullmatch(r"miniworld/textures/(lg_style_\w+?)(?:_1|_result)\.png", path)
        if not m:
            continue
        stem = m.group(1)
        lab_name = stem + "_d" if path.endswith("_1.png") else stem
        got = lab.read(f"assets/textures/map/lab_games/{lab_name}.tga")
        if got is None:
            continue
        a, b = decode_image(got[0]), decode_image(miniworld.read(path)[0])
        if a.shape != b.shape or np.abs(a - b).max() > 0:
            raise ValueError(f"{path} differs from lab's {lab_name}.tga: Miniworld is no copy of it")
        checked += 1
    if checked == 0:
        raise ValueError("no texture in both repositories: nothing vouches for Miniworld's copies")
    return checked


# ---- shaders -------------------------------------------------------------------------------
def parse_shader(text: str, name: str) -> list[dict[str, list[str]]]:
    """The stages of shader ``textures/<name>`` in ``text`` (a .shader file): per stage, its
    keywords (lower case) -> argument lists."""
    text = re.sub(r"//[^\n]*", "", text)
    m = re.search(r"^textures/" + re.escape(name) + r"\s*\{", text, re.M)
    if m is None:
        raise KeyError(name)
    depth, i, stages, cur = 1, m.end(), [], None
    while depth:
        if text[i] == "{":
            depth += 1
            cur = {}
            j = text.index("}", i)
            for line in text[i + 1:j].splitlines():
                words = line.split()
                if words:
                    cur.setdefault(words[0].lower(), []).append(words[1:])
            stages.append(cur)
            depth -= 1
            i = j
        elif text[i] == "}":
            depth -= 1
        i += 1
    return stages


def wave_mean(args: list[str]) -> float:
    """Time average of ``rgbGen wave <fn> base amp phase freq``, clamped to [0, 1] as Quake 3 does."""
    fn, base, amp, phase = args[0].lower(), *map(float, args[1:4])
    x = phase + np.arange(100000) / 100000.0
    shape = {"sin": np.sin(2 * np.pi * x), "square": np.where(x % 1 < 0.5, 1.0, -1.0),
             "triangle": 1 - 4 * np.abs(x % 1 - 0.5), "sawtooth": x % 1, "inversesawtooth": 1 - x % 1}[fn]
    return float(np.clip(base + amp * shape, 0.0, 1.0).mean())


def composite(sources: Sources, stages, refs: list | None = None) -> np.ndarray:
    """(FULL, FULL, 3) the shader's stages blended, as the module docstring says; the textures
    read are appended to ``refs``."""
    dst = np.zeros((FULL, FULL, 3))
    for st in stages:
        ref = (st.get("map") or st.get("clampmap"))[0][0]
        if ref.lower() == "$lightmap":
            continue  # lighting left out: the lightmap is 1
        if refs is not None:
            refs.append(ref.rsplit(".", 1)[0])
        tex = sources.texture(ref.rsplit(".", 1)[0])
        if tex is None:
            raise FileNotFoundError(f"{ref}: in neither repository")
        if tex.shape[:2] != (FULL, FULL):
            raise ValueError(f"{ref}: {tex.shape[:2]}, expected {FULL} x {FULL}")
        rgb, alpha = tex[..., :3].copy(), tex[..., 3:].copy()
        for args in st.get("tcgen", []):
            if args[0].lower() == "environment":  # view-dependent: its mean over the views
                rgb[:], alpha[:] = rgb.mean((0, 1)), alpha.mean()
        for args in st.get("tcmod", []):
            if args[0].lower() != "scroll":
                raise ValueError(f"tcMod {args[0]}")
            if float(args[1]):  # scrolling along s: each row's mean
                rgb[:], alpha[:] = rgb.mean(1, keepdims=True), alpha.mean(1, keepdims=True)
            if float(args[2]):  # along t: each column's mean
                rgb[:], alpha[:] = rgb.mean(0, keepdims=True), alpha.mean(0, keepdims=True)
        for args in st.get("rgbgen", []):
            kind = args[0].lower()
            if kind == "const":
                rgb = rgb * np.asarray([float(v) for v in args[1:] if v not in "()"][:3])
            elif kind == "wave":
                rgb = rgb * wave_mean(args[1:])
            elif kind not in ("identity", "identitylighting"):
                raise ValueError(f"rgbGen {kind}")
        blend = " ".join(" ".join(a) for a in st.get("blendfunc", [])).lower()
        if blend == "":
            dst = rgb
        elif blend in ("add", "gl_one gl_one"):
            dst = dst + rgb
        elif blend in ("blend", "gl_src_alpha gl_one_minus_src_alpha"):
            dst = rgb * alpha + dst * (1 - alpha)
        elif blend == "gl_one gl_one_minus_src_alpha":
            dst = rgb + dst * (1 - alpha)
        elif blend == "gl_src_color gl_one_minus_src_alpha":
            dst = rgb * rgb + dst * (1 - alpha)
        else:
            raise ValueError(f"blendFunc {blend}")
        dst = np.clip(dst, 0.0, 1.0)
    return dst


def box_down(image: np.ndarray, size: int = SIZE) -> np.ndarray:
    """(size, size, C) means of whole blocks of a (N, N, C) image, N a multiple of size."""
    n = image.shape[0] // size
    return image.reshape(size, n, size, n, -1).mean((1, 3))


def to_u8(x: np.ndarray) -> np.ndarray:
    return np.round(np.clip(x, 0.0, 1.0) * 255.0).astype(np.uint8)


# ---- sky -----------------------------------------------------------------------------------
def sky_elevation_table(faces: dict[str, np.ndarray], azimuths: int = 720) -> np.ndarray:
    """(181, 3) the cube's mean colour round the horizon at elevations -90 ... 90 degrees.
    A side face holds directions whose horizontal part points at it: row (1 - z / h) / 2 of its
    height (h the horizontal component along the face's axis), column by the sideways part;
    averaged over every azimuth the sideways order of the faces does not matter."""
    out = []
    for elev in range(-90, 91):
        e = math.radians(elev)
        a = (np.arange(azimuths) + 0.5) * 2 * np.pi / azimuths
        x, y, z = np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.full(azimuths, math.sin(e))
        cols = []
        for xi, yi, zi in zip(x, y, z):
            h = max(abs(xi), abs(yi))
            if zi > h:  # the up face: (x, y) / z across it; averaged round a circle its turn does not matter
                img = faces["up"]
                u, v = (xi / zi + 1) / 2, (yi / zi + 1) / 2
            else:
                if abs(xi) >= abs(yi):
                    img, side = (faces["ft"] if xi > 0 else faces["bk"]), yi / abs(xi)
                else:
                    img, side = (faces["lf"] if yi > 0 else faces["rt"]), xi / abs(yi)
                u, v = (side + 1) / 2, (1 - max(zi / h, -1.0)) / 2
            n = img.shape[0]
            cols.append(img[min(int(v * n), n - 1), min(int(u * n), n - 1), :3])
        out.append(np.mean(cols, 0))
    return np.asarray(out)


# ---- models ----------------------------------------------------------------------------------
def read_md3(data: bytes):
    """Frame 0 of an MD3's first surface: (shader, triangles (T, 3), st (V, 2), xyz (V, 3))."""
    if data[:4] != b"IDP3":
        raise ValueError("not an MD3")
    _, _, _, nsurf, _, _, _, osurf, _ = struct.unpack_from("<9i", data, 72)
    if nsurf != 1:
        raise ValueError(f"{nsurf} surfaces; the items have one")
    off = osurf
    _, _, _, nv, ntri, otri, osh, ost, oxyz, _ = struct.unpack_from("<10i", data, off + 68)
    shader = data[off + osh:off + osh + 64].split(b"\0")[0].decode()
    tri = np.frombuffer(data, "<i4", ntri * 3, off + otri).reshape(-1, 3)
    st = np.frombuffer(data, "<f4", nv * 2, off + ost).reshape(-1, 2).astype(np.float64)
    xyz = np.frombuffer(data, "<i2", nv * 4, off + oxyz).reshape(-1, 4)[:, :3] / 64.0  # frame 0
    return shader, tri, st, xyz


def rasterise(tri, st, xyz, texture: np.ndarray | None, colour) -> tuple[np.ndarray, tuple[int, int]]:
    """The model seen from -y looking +y (x to the right, z up), one texel per unit: (H, W, 4)
    RGBA in 0..1 and (column of x = 0, height of the top row's top above the model's origin)."""
    x0, x1 = math.floor(xyz[:, 0].min()), math.ceil(xyz[:, 0].max())
    z0, z1 = math.floor(xyz[:, 2].min()), math.ceil(xyz[:, 2].max())
    w, h = (x1 - x0) * SAMPLES, (z1 - z0) * SAMPLES
    px = (xyz[:, 0] - x0) * SAMPLES  # sample grid: column, row from the top
    pz = (z1 - xyz[:, 2]) * SAMPLES
    depth = np.full((h, w), np.inf)
    rgb = np.zeros((h, w, 3))
    for a, b, c in tri:
        xs, zs = px[[a, b, c]], pz[[a, b, c]]
        area = (xs[1] - xs[0]) * (zs[2] - zs[0]) - (xs[2] - xs[0]) * (zs[1] - zs[0])
        if abs(area) < 1e-12:
            continue
        cx0, cx1 = max(int(np.floor(xs.min())), 0), min(int(np.ceil(xs.max())), w)
        cz0, cz1 = max(int(np.floor(zs.min())), 0), min(int(np.ceil(zs.max())), h)
        if cx0 >= cx1 or cz0 >= cz1:
            continue
        gz, gx = np.mgrid[cz0:cz1, cx0:cx1] + 0.5
        l1 = ((xs[2] - gx) * (zs[0] - gz) - (xs[0] - gx) * (zs[2] - gz)) / area
        l2 = ((xs[0] - gx) * (zs[1] - gz) - (xs[1] - gx) * (zs[0] - gz)) / area
        l0 = 1 - l1 - l2
        inside = (l0 >= 0) & (l1 >= 0) & (l2 >= 0)
        d = l0 * xyz[a, 1] + l1 * xyz[b, 1] + l2 * xyz[c, 1]
        win = inside & (d < depth[cz0:cz1, cx0:cx1])
        if not win.any():
            continue
        depth[cz0:cz1, cx0:cx1] = np.where(win, d, depth[cz0:cz1, cx0:cx1])
        if texture is None:
            texel = np.broadcast_to(np.asarray(colour, np.float64), win.shape + (3,))
        else:
            s = l0 * st[a, 0] + l1 * st[b, 0] + l2 * st[c, 0]
            t = l0 * st[a, 1] + l1 * st[b, 1] + l2 * st[c, 1]
            n = texture.shape[0]
            texel = texture[np.floor(t % 1.0 * n).astype(int) % n, np.floor(s % 1.0 * n).astype(int) % n, :3]
        rgb[cz0:cz1, cx0:cx1] = np.where(win[..., None], texel, rgb[cz0:cz1, cx0:cx1])
    alpha = np.isfinite(depth)[..., None].astype(np.float64)
    rgba = np.concatenate([rgb * alpha, alpha], -1)  # premultiplied, for the box filter
    rgba = rgba.reshape(h // SAMPLES, SAMPLES, w // SAMPLES, SAMPLES, 4).mean((1, 3))
    a = rgba[..., 3:]
    rgba[..., :3] = np.where(a > 0, rgba[..., :3] / np.maximum(a, 1e-12), 0.0)  # straight alpha again
    return rgba, (-x0, z1)


# ---- the asset -------------------------------------------------------------------------------
def convert(lab_dir: str = DEFAULT_LAB, miniworld_dir: str = DEFAULT_MINIWORLD, verbose: bool = False) -> dict:
    lab = Repo(lab_dir, LAB_COMMIT, "google-deepmind/lab")
    miniworld = Repo(miniworld_dir, MINIWORLD_COMMIT, "tomosii/Miniworld")
    checked = verify_miniworld(lab, miniworld)
    if verbose:
        print(f"Miniworld: {checked} textures pixel-identical to lab's")
    sources = Sources(lab, miniworld)
    shader_path = "assets/scripts/lab_games.shader"
    shader_bytes, shader_blob = lab.read(shader_path)
    shader_text = shader_bytes.decode("latin-1")
    out: dict[str, np.ndarray] = {}

    surfaces, means, stage_sources = [], [], []
    for name in SURFACES:
        refs = []
        full = composite(sources, parse_shader(shader_text, name), refs)
        surfaces.append(to_u8(box_down(full)))
        means.append(full.mean((0, 1)))
        stage_sources.append(";".join(refs))
        if verbose:
            print(f"{name}: mean {np.round(means[-1] * 255, 1)}")
    out["surface_names"] = np.asarray(SURFACES)
    out["surfaces"] = np.stack(surfaces)
    out["surface_mean"] = np.asarray(means, np.float64)

    faces, tables = [], []
    for sky in SKIES:
        got = {f: sources.texture(f"textures/{sky}_{f}") for f in SKY_FACES}
        missing = [f for f, v in got.items() if v is None]
        if missing:
            raise FileNotFoundError(f"{sky}: faces {missing} in neither repository")
        faces.append(np.stack([to_u8(box_down(got[f][..., :3])) for f in SKY_FACES]))
        tables.append(sky_elevation_table({f: v[..., :3] for f, v in got.items()}))
    out["sky_names"] = np.asarray(SKIES)
    out["sky_faces"] = np.stack(faces)  # (K, 5, SIZE, SIZE, 3), SKY_FACES order
    out["sky_face_names"] = np.asarray(SKY_FACES)
    out["sky_elevation_rgb"] = np.asarray(tables, np.float64)  # (K, 181, 3), 0..1

    sprites, offsets, colours = [], [], []
    for item, model, texture in ITEMS:
        data, blob = lab.read(f"assets/{model}")
        sources.used[model] = (f"google-deepmind/lab@{LAB_COMMIT[:7]}", f"assets/{model}", blob)
        shader, tri, st, xyz = read_md3(data)
        if shader != texture:
            raise ValueError(f"{model} is textured {shader}, expected {texture}")
        tex = sources.texture(texture)
        colour = None
        if tex is None:
            colour = [float(v) for v in SUBSTITUTES[texture][0].split()[1:]]
        rgba, (left, top) = rasterise(tri, st, xyz, tex, colour)
        sprites.append(rgba)
        offsets.append((left, top + ITEM_BASE))
        colours.append(texture if tex is not None else SUBSTITUTES[texture][0])
        if verbose:
            print(f"{item}: {model} {rgba.shape[1]}x{rgba.shape[0]} texels, colour from {colours[-1]}")
    hs, ws = max(s.shape[0] for s in sprites), max(s.shape[1] for s in sprites)
    padded = np.zeros((len(sprites), hs, ws, 4))
    for i, s in enumerate(sprites):  # top-left aligned; the offsets place each
        padded[i, :s.shape[0], :s.shape[1]] = s
    out["sprite_names"] = np.asarray([i[0] for i in ITEMS])
    out["sprites"] = to_u8(padded)  # (N, Hs, Ws, 4) straight RGBA
    out["sprite_sizes"] = np.asarray([s.shape[:2] for s in sprites], np.int32)  # (N, 2) height, width
    out["sprite_offsets"] = np.asarray(offsets, np.float32)  # (N, 2) origin column, top height
    out["sprite_colour_from"] = np.asarray(colours)

    used = sorted(sources.used.items())
    out["source_names"] = np.asarray([k for k, _ in used] + ["scripts/lab_games.shader"])
    out["source_repos"] = np.asarray([v[0] for _, v in used] + [f"google-deepmind/lab@{LAB_COMMIT[:7]}"])
    out["source_paths"] = np.asarray([v[1] for _, v in used] + [shader_path])
    out["source_blobs"] = np.asarray([v[2] for _, v in used] + [shader_blob])
    out["surface_sources"] = np.asarray(stage_sources)
    out["substitutions"] = np.asarray([[k, *v] for k, v in SUBSTITUTES.items()])
    out["miniworld_checked"] = np.int32(checked)
    out["lab_commit"] = np.asarray(LAB_COMMIT)
    out["miniworld_commit"] = np.asarray(MINIWORLD_COMMIT)
    return out


def digest(arrays: dict) -> str:
    h = hashlib.sha256()
    for k in sorted(arrays):
        h.update(k.encode())
        h.update(np.ascontiguousarray(arrays[k]).tobytes())
    return h.hexdigest()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--lab", default=DEFAULT_LAB, help="google-deepmind/lab's git directory (default: %(default)s)")
    parser.add_argument("--miniworld", default=DEFAULT_MINIWORLD,
                        help="tomosii/Miniworld's git directory (default: %(default)s)")
    parser.add_argument("--out", default=DEFAULT_OUT, help="output .npz (default: %(default)s)")
    parser.add_argument("--check", action="store_true", help="compare with --out instead of writing it")
    parser.add_argument("--quiet", action="store_true")
    args = parser.parse_args()
    arrays = convert(args.lab, args.miniworld, verbose=not args.quiet)
    if args.check:
        with np.load(args.out, allow_pickle=False) as old:
            stored = {k: old[k] for k in old.files}
        if set(stored) != set(arrays):
            raise SystemExit(f"keys differ: {sorted(set(stored) ^ set(arrays))}")
        bad = [k for k in arrays if stored[k].shape != arrays[k].shape or not np.array_equal(stored[k], arrays[k])]
        if bad:
            raise SystemExit(f"differs from {args.out}: {bad}")
        print(f"{args.out} is what the sources make")
        return
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    np.savez_compressed(args.out, **arrays)
    print(f"wrote {args.out} ({os.path.getsize(args.out)} bytes, sha256 of arrays {digest(arrays)[:16]})")


if __name__ == "__main__":
    main()
