"""Quantised transfer in a .glb: the _PRT_Tk float accessors rewritten as normalised integers (scale, offset).

Blender's exporter writes the transfer as VEC4 FLOAT accessors; this rewrites those of every
baked mesh (the names in its extras' `attributes` and `bounce_attributes`) as normalised SHORT
(`snorm16`) or BYTE (`snorm8`) accessors and drops the float bytes from the BIN chunk (the other
buffer views are kept, in order, re-packed). Per attribute name and component, over every
primitive of the mesh: offset = (max + min) / 2 and scale = (max - min) / 2, stored
q = round((t - offset) / scale * K) (K = 32767 or 127), which glTF decodes to q / K in [-1, 1]
(normalised), so t = offset + scale * q / K. The mesh's extras get `transfer_encoding` and
`decode` ([{"offset": [4], "scale": [4]}] in the order of attributes + bounce_attributes) and
`version` 2. docs/export.md ("Quantised transfer") is the format.
"""

import numpy as np

FLOAT = 5126
ENCODINGS = {
    # name: (glTF componentType, K, numpy type)
    "snorm16": (5122, 32767, "<i2"),
    "snorm8": (5120, 127, "i1"),
}
TRANSFER_ENCODINGS = ("float32",) + tuple(ENCODINGS)
VERSION = 2  # mesh extras of a quantised transfer: a viewer of version 1 would read q / K as t


def _view_bytes(document, binary, view_index):
    view = document["bufferViews"][view_index]
    start = view.get("byteOffset", 0)
    return binary[start : start + view["byteLength"]]


def read_float(document, binary, accessor, width=4):
    """(count, width) float32 of a VEC<width> FLOAT accessor (byteStride honoured)."""
    if accessor.get("componentType") != FLOAT or accessor.get("type") != f"VEC{width}" or "bufferView" not in accessor:
        raise ValueError(f"a transfer accessor is not a VEC{width} FLOAT one")
    view = document["bufferViews"][accessor["bufferView"]]
    data = _view_bytes(document, binary, accessor["bufferView"])
    size = 4 * width
    stride = view.get("byteStride", size)
    count, start = accessor["count"], accessor.get("byteOffset", 0)
    raw = np.frombuffer(data, np.uint8, count * stride - (stride - size) if count else 0, start)
    rows = np.lib.stride_tricks.as_strided(raw, (count, size), (stride, 1)) if count else raw.reshape(0, size)
    return np.ascontiguousarray(rows).view(np.float32).reshape(count, width)


def decode(q, offset, scale, k):
    """The transfer a viewer decodes from the stored integers q (glTF's normalised rule)."""
    return np.asarray(offset) + np.asarray(scale) * np.maximum(np.asarray(q, np.float64) / k, -1.0)


def encode(values, k):
    """(q integers, offset, scale) of float rows (count, 4): per component over the rows."""
    values = np.asarray(values, np.float64)
    lo, hi = values.min(axis=0), values.max(axis=0)
    offset, scale = 0.5 * (hi + lo), 0.5 * (hi - lo)
    safe = np.where(scale > 0, scale, 1.0)
    q = np.rint(np.clip((values - offset) / safe, -1.0, 1.0) * k)
    return q, offset, np.where(scale > 0, scale, 0.0)


def pack_views(document, chunks, replaced, extra):
    """Rewrite the BIN chunk without the buffer views in `replaced` (no accessor left using them),
    appending the `extra` payloads as new views; returns (chunks, [index of each new view])."""
    binary = chunks[0][1]
    views, out, offset, remap = document["bufferViews"], [], 0, {}
    kept = []
    for index, view in enumerate(views):
        if index in replaced:
            continue
        data = _view_bytes(document, binary, index)
        pad = -offset % 8
        out.append(b"\0" * pad)
        offset += pad
        view = dict(view, byteOffset=offset)
        out.append(data)
        offset += len(data)
        remap[index] = len(kept)
        kept.append(view)
    added = []
    for payload in extra:
        pad = -offset % 8
        out.append(b"\0" * pad)
        offset += pad
        added.append(len(kept))
        kept.append({"buffer": 0, "byteOffset": offset, "byteLength": len(payload), "target": 34962})
        out.append(payload)
        offset += len(payload)
    document["bufferViews"] = kept
    for accessor in document.get("accessors", []):
        if "bufferView" in accessor and accessor["bufferView"] in remap:
            accessor["bufferView"] = remap[accessor["bufferView"]]
    for image in document.get("images", []):
        if "bufferView" in image:
            image["bufferView"] = remap[image["bufferView"]]
    body = b"".join(out)
    document["buffers"][0]["byteLength"] = len(body)
    return [(chunks[0][0], body)] + list(chunks[1:]), added


def quantise(document, chunks, encoding, extras_key="PRT_lighting"):
    """Rewrite the transfer accessors of the baked meshes of a .glb (JSON dict, chunks after the
    JSON one, BIN first) as `encoding`; returns the new chunks (document changed in place)."""
    if encoding == "float32":
        return chunks
    if encoding not in ENCODINGS:
        raise ValueError(f"unknown transfer encoding '{encoding}' (one of {', '.join(TRANSFER_ENCODINGS)})")
    component, k, dtype = ENCODINGS[encoding]
    binary = chunks[0][1]
    accessors = document["accessors"]
    jobs, payloads = [], []  # (accessor index) per new view
    for mesh in document.get("meshes", []):
        meta = (mesh.get("extras") or {}).get(extras_key)
        if not isinstance(meta, dict) or meta.get("domain") == "TEXEL":  # (texels.py: images)
            continue
        names = list(meta.get("attributes", [])) + list(meta.get("bounce_attributes", []))
        table = []
        for name in names:
            indices = sorted({p["attributes"][name] for p in mesh["primitives"] if name in p.get("attributes", {})})
            rows = [read_float(document, binary, accessors[i]) for i in indices]
            q, offset, scale = encode(np.concatenate(rows), k)
            table.append({"offset": offset.tolist(), "scale": scale.tolist()})
            first = 0
            for index, part in zip(indices, rows):
                jobs.append(index)
                payloads.append(q[first : first + len(part)].astype(dtype).tobytes())
                first += len(part)
        meta.update(version=VERSION, transfer_encoding=encoding, decode=table)
    if not jobs:
        return chunks
    replaced = {accessors[i]["bufferView"] for i in jobs}
    still_used = {a["bufferView"] for i, a in enumerate(accessors) if i not in set(jobs) and "bufferView" in a}
    still_used |= {im["bufferView"] for im in document.get("images", []) if "bufferView" in im}
    if replaced & still_used:
        raise ValueError("a transfer buffer view is shared with other data")
    chunks, added = pack_views(document, chunks, replaced, payloads)
    for index, view in zip(jobs, added):
        accessor = accessors[index]
        accessor.update(bufferView=view, byteOffset=0, componentType=component, normalized=True)
        accessor.pop("min", None)
        accessor.pop("max", None)
    return chunks
