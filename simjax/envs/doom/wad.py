"""Doom WAD files: read the lump directory, look lumps up by name, write a PWAD back.

The one WAD reader of the project: ``tools/freedoom_assets.py`` reads the textures, palette
and map lumps of the asset with it, and ``simjax.envs.doom.vizdoom_ref`` rewrites the scenario's
wad with it. Standard library only and no imports from simjax, so that the tool can load this
file by its path without importing jax (which ``simjax.envs`` does).
"""

from __future__ import annotations

import struct


class Wad:
    """The lumps of one WAD file, in directory order, as (name, bytes); names are as stored
    and may repeat (e.g. per-map lumps)."""

    def __init__(self, lumps: list[tuple[str, bytes]]):
        self.lumps = list(lumps)

    @classmethod
    def from_bytes(cls, data: bytes, source: str = "data") -> Wad:
        """The WAD whose file contents are ``data`` (an IWAD or a PWAD); ``source`` names it
        in the error raised when it is not a WAD."""
        ident, count, table = struct.unpack_from("<4sii", data, 0)
        if ident not in (b"IWAD", b"PWAD"):
            raise ValueError(f"{source} is not a WAD")
        lumps = []
        for i in range(count):
            pos, size, name = struct.unpack_from("<ii8s", data, table + 16 * i)
            lumps.append((name.rstrip(b"\0").decode("ascii"), data[pos : pos + size]))
        return cls(lumps)

    @classmethod
    def load(cls, path: str) -> Wad:
        """The WAD file at ``path``."""
        with open(path, "rb") as f:
            return cls.from_bytes(f.read(), path)

    def find(self, name: str, markers: tuple[str, ...] = ()) -> bytes | None:
        """The last lump called ``name`` (later lumps override earlier ones, as in Doom;
        names compare case-insensitively), looking only between ``X_START``/``X_END`` (or
        ``XX_START``/``XX_END``) for the namespace letters given in ``markers``; None if
        absent."""
        name = name.upper()
        inside, found = not markers, None
        starts = {m + "_START" for m in markers} | {m * 2 + "_START" for m in markers}
        ends = {m + "_END" for m in markers} | {m * 2 + "_END" for m in markers}
        for lump_name, data in self.lumps:
            lump_name = lump_name.upper()
            if lump_name in starts:
                inside = True
            elif lump_name in ends:
                inside = False
            elif inside and lump_name == name:
                found = data
        return found

    def to_bytes(self) -> bytes:
        """A PWAD file holding these lumps in order: header, lump data, then the directory."""
        body, directory, pos = b"", b"", 12
        for name, data in self.lumps:
            directory += struct.pack("<ii8s", pos, len(data), name.encode("ascii"))
            body += data
            pos += len(data)
        return struct.pack("<4sii", b"PWAD", len(self.lumps), 12 + len(body)) + body + directory


__all__ = ["Wad"]
