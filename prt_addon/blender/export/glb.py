"""Reading and rewriting the JSON chunk of a binary glTF (.glb) file, the BIN chunk untouched."""

import json
import struct

MAGIC = 0x46546C67  # "glTF"
CHUNK_JSON = 0x4E4F534A  # "JSON"
CHUNK_BIN = 0x004E4942  # "BIN\0"


def split(data):
    """(json dict, [(chunk type, bytes)] of the chunks after the JSON one) of .glb bytes."""
    if len(data) < 20:
        raise ValueError("not a binary glTF file (too short)")
    magic, version, length = struct.unpack_from("<III", data, 0)
    if magic != MAGIC or version != 2 or length != len(data):
        raise ValueError("not a binary glTF 2.0 file (bad header)")
    offset, chunks = 12, []
    while offset < length:
        size, kind = struct.unpack_from("<II", data, offset)
        chunks.append((kind, bytes(data[offset + 8 : offset + 8 + size])))
        offset += 8 + size
    if not chunks or chunks[0][0] != CHUNK_JSON:
        raise ValueError("binary glTF file without a JSON chunk first")
    return json.loads(chunks[0][1].decode("utf-8")), chunks[1:]


def join(document, chunks):
    """.glb bytes of a JSON dict and the other chunks, each chunk padded to 4 bytes (JSON with
    spaces, BIN with zeros, as the glTF specification requires)."""
    text = json.dumps(document, separators=(",", ":"), allow_nan=False).encode("utf-8")
    text += b" " * (-len(text) % 4)
    parts = [struct.pack("<II", len(text), CHUNK_JSON), text]
    for kind, payload in chunks:
        payload += b"\0" * (-len(payload) % 4)
        parts += [struct.pack("<II", len(payload), kind), payload]
    body = b"".join(parts)
    return struct.pack("<III", MAGIC, 2, 12 + len(body)) + body


def read(path):
    with open(path, "rb") as f:
        return split(f.read())


def write(path, document, chunks):
    with open(path, "wb") as f:
        f.write(join(document, chunks))
