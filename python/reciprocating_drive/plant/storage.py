"""The measured input kept compactly, and the twin's state kept at intervals (docs/plant.md
"Storage"): what makes every per-sample output of a run recomputable bit for bit.

A *block* holds the input lines the twin consumed between two checkpoints (the lines exactly as
the core read them: a CSV file's own text, or the OPC UA source's lines of `repr` numbers), so that
feeding them again to the twin restored from a *snapshot* (a stored `Twin.checkpoint()`) gives the
same rows. Keeping the text, not parsed doubles, is what makes the round trip exact whatever the
source wrote (a CSV file's "0.001016" and "1.016e-3" read back the same; their lines' numbers in
messages too).

Codec "cols-zstd": the lines cut into their comma-separated fields and stored column after column
(the time column's digits then repeat in place, and so do the angle's), compressed with zstd at
level 3 through pyarrow, a dependency already, rather than a codec written here. Measured on the
shipped sample in blocks of 10 000 lines: 4.2 bytes a sample, against 5.5 for the lines as they
are (codec "lines-zstd", used when the lines do not all have the same number of fields) and 14 as
a CSV file. Every block carries the SHA-256 of its stored bytes: a damaged block is named with its
lines and times, never read as something else.
"""

from __future__ import annotations

import hashlib
import json

import pyarrow as pa

CODEC_LEVEL = 3
_ZSTD = pa.Codec("zstd", compression_level=CODEC_LEVEL)


class BlockError(ValueError):
    """A stored block or snapshot that does not read back (its checksum differs)."""


def checksum(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _zstd(raw: bytes) -> bytes:
    # The raw size first: pyarrow's zstd decompression wants it.
    return len(raw).to_bytes(8, "little") + _ZSTD.compress(raw, asbytes=True)


def _unzstd(data: bytes) -> bytes:
    n = int.from_bytes(data[:8], "little")
    return _ZSTD.decompress(data[8:], decompressed_size=n, asbytes=True)


def encode_lines(lines: list[str]) -> tuple[str, bytes]:
    """(codec, bytes) of these input lines; `decode_lines` gives them back exactly."""
    fields = lines[0].count(",") if lines else 0
    text = "\n".join(lines)
    if lines and "\x00" not in text and all(s.count(",") == fields for s in lines):
        # Reversible: every line has the same number of commas, and no field holds a newline
        # (a line cannot) or a NUL (checked), the column and field separators below.
        cols = zip(*(s.split(",") for s in lines))
        raw = "\x00".join("\n".join(c) for c in cols).encode("utf-8", "surrogatepass")
        return "cols-zstd", _zstd(raw)
    return "lines-zstd", _zstd(text.encode("utf-8", "surrogatepass"))


def decode_lines(codec: str, data: bytes) -> list[str]:
    raw = _unzstd(data).decode("utf-8", "surrogatepass")
    if codec == "lines-zstd":
        return raw.split("\n")
    if codec == "cols-zstd":
        cols = [c.split("\n") for c in raw.split("\x00")]
        return [",".join(r) for r in zip(*cols)]
    raise BlockError(f"unknown codec {codec!r}")


def encode_state(state: dict) -> bytes:
    """A snapshot of the twin (`Twin.checkpoint()`), JSON compressed."""
    return _zstd(json.dumps(state, separators=(",", ":")).encode())


def decode_state(data: bytes) -> dict:
    return json.loads(_unzstd(data))
