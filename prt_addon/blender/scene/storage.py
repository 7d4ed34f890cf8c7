"""The on-mesh storage format of a bake: transfer attributes, the bake record, bake status.

Writing: the FLOAT_COLOR attributes `prt_tKK` (vertex and corner bakes) or a float image (texel
bakes, texel_storage) and the record mesh["prt_bake"], all meshes of a bake at once or none
(write_bakes restores the previous state if anything fails). Reading: one
record reader that checks the format version, and one status function (bake_state) whose views
are bake_status (the UI and the API) and usable_bake (the display). docs/storage.md is the
contract.

Attribute references dangle once another attribute is added or removed (the layers are
reallocated), so every access below looks the attribute up by name.
"""

import re
from dataclasses import dataclass

import numpy as np

from .. import caches
from . import back_storage, texel_storage
from .mesh_read import topology_fingerprint

PREFIX = "prt_t"
RECORD = "prt_bake"
# 2: bounce attributes; 3: texel bakes; 4: texel bakes' bounce tiles (texel_storage.record_fields).
FORMAT_VERSION, ATTRIBUTE_BOUNCE_VERSION = 4, 3  # (bakes with bounce attributes: 3, others: 1)
# prt_t00 .. prt_t99, then prt_t100 .. (bounced bakes); prt_tb00 .. the back side (back_storage).
_ATTR_RE = re.compile(r"^prt_tb?\d{2,}$")


def attribute_name(k):
    return f"{PREFIX}{k:02d}"


def attribute_count(order):
    return (order * order + 3) // 4


def is_transfer_attribute(name):
    return bool(_ATTR_RE.match(name))


def transfer_attribute_names(mesh):
    return sorted(a.name for a in mesh.attributes if is_transfer_attribute(a.name))


def snapshot(mesh):
    """Everything a bake may change on `mesh`, to restore it byte for byte."""
    attrs = []
    for name in transfer_attribute_names(mesh):
        attr = mesh.attributes[name]
        domain, data_type = attr.domain, attr.data_type
        size = len(attr.data)
        if data_type in ("FLOAT_COLOR", "BYTE_COLOR"):
            prop, width, dtype = "color", 4, np.float32
        elif data_type in ("FLOAT_VECTOR",):
            prop, width, dtype = "vector", 3, np.float32
        elif data_type == "FLOAT2":
            prop, width, dtype = "vector", 2, np.float32
        elif data_type == "INT":
            prop, width, dtype = "value", 1, np.int32
        elif data_type == "BOOLEAN":
            prop, width, dtype = "value", 1, bool
        else:
            prop, width, dtype = "value", 1, np.float32
        buf = np.empty(size * width, dtype=dtype)
        try:
            mesh.attributes[name].data.foreach_get(prop, buf)
        except (TypeError, AttributeError, RuntimeError) as error:
            raise ValueError(
                f"cannot read attribute '{name}' of mesh '{mesh.name}' to keep a copy, so the bake "
                f"would not be undoable on failure: {error}"
            ) from None
        attrs.append((name, domain, data_type, prop, buf))
    record = mesh.get(RECORD)
    record = record.to_dict() if hasattr(record, "to_dict") else record
    colors = mesh.color_attributes
    return {
        "attrs": attrs,
        "record": record,
        "active_color": colors.active_color_name,
        "default_color": colors.default_color_name,
    }


def _set_color_names(mesh, active, default):
    colors = mesh.color_attributes
    names = {a.name for a in colors}
    if active in names and colors.active_color_name != active:
        colors.active_color_name = active
    if default in names and colors.default_color_name != default:
        colors.default_color_name = default


def _remove(mesh, name):
    attr = mesh.attributes.get(name)
    if attr is not None:
        mesh.attributes.remove(attr)


def restore(mesh, snap):
    for name in transfer_attribute_names(mesh):
        _remove(mesh, name)
    for name, domain, data_type, prop, buf in snap["attrs"]:
        mesh.attributes.new(name, data_type, domain)
        mesh.attributes[name].data.foreach_set(prop, buf)
    if snap["record"] is None:
        if RECORD in mesh:
            del mesh[RECORD]
    else:
        mesh[RECORD] = snap["record"]
    _set_color_names(mesh, snap["active_color"], snap["default_color"])
    mesh.update()


def write_transfer(mesh, values, domain, record, bounce=None):
    """Write (E, n*n) float32 coefficients as prt_tKK attributes and the record on one mesh;
    bounce: None or the (E, C, n*n) bounced transfer, written after them channel by channel,
    each channel padded to the direct part's attribute count (docs/storage.md)."""
    values = np.asarray(values, dtype=np.float32)
    per_part = (values.shape[1] + 3) // 4
    parts = [values] if bounce is None else [values] + list(np.asarray(bounce, np.float32).transpose(1, 0, 2))
    count = per_part * len(parts)
    channel = np.zeros((values.shape[0], 4), dtype=np.float32)  # one attribute at a time (no packed copy)
    colors = mesh.color_attributes
    active, default = colors.active_color_name, colors.default_color_name
    for k in range(count):
        name = attribute_name(k)
        old = mesh.attributes.get(name)
        if old is not None and (old.domain != domain or old.data_type != "FLOAT_COLOR"):
            _remove(mesh, name)
        if mesh.attributes.get(name) is None:
            mesh.color_attributes.new(name, "FLOAT_COLOR", domain)
        part, first = parts[k // per_part], 4 * (k % per_part)
        width = min(4, values.shape[1] - first)
        channel[:, :width] = part[:, first : first + width]
        channel[:, width:] = 0.0
        mesh.attributes[name].data.foreach_set("color", channel.reshape(-1))
    for name in transfer_attribute_names(mesh):
        if not back_storage.is_back_attribute(name) and int(name[len(PREFIX) :]) >= count:
            _remove(mesh, name)
    channels = len(parts) - 1
    version = ATTRIBUTE_BOUNCE_VERSION if channels else 1
    mesh[RECORD] = dict(record, count=per_part, domain=domain, bounce_channels=channels, version=version)
    _set_color_names(mesh, active, default)
    mesh.update()


def write_bakes(items):
    """items: [(mesh, values, domain, record[, bounce[, back (E, n*n) or None]])], for a TEXEL
    domain [(mesh, image, "TEXEL", record, (uv name, created UVs or None[, bounced (res, res, C,
    n*n) or None[, back (res, res, n*n) or None]]))]. All are written, or none (state restored:
    attributes, records, the UV maps made; the previous images are replaced only at the end)."""
    snapshots = [(item[0], snapshot(item[0])) for item in items]
    old_images = {mesh.name: texel_storage.record_images(snap["record"]) for mesh, snap in snapshots}
    staged, made_uvs = [], []
    try:
        for mesh, values, domain, record, extra, back in (tuple(item) + (None,) * (6 - len(item)) for item in items):
            if domain == "TEXEL":
                uv_name, created, bounce, back = tuple(extra) + (None,) * (4 - len(extra))
                if created is not None and uv_name not in mesh.uv_layers:
                    made_uvs.append((mesh, uv_name))
                for name in transfer_attribute_names(mesh):
                    _remove(mesh, name)
                count = attribute_count(int(record["order"]))
                texel_storage.write_texels(mesh, values, record, count, (uv_name, created), staged, bounce, back)
            else:
                write_transfer(mesh, values, domain, record, extra)
                back_storage.write_back(mesh, back, domain)
    except BaseException:
        for image in (image for _mesh, _key, image in staged):
            texel_storage.discard_image(image)
        for mesh, snap in snapshots:
            restore(mesh, snap)
        for mesh, uv_name in made_uvs:
            if uv_name in mesh.uv_layers:
                mesh.uv_layers.remove(mesh.uv_layers[uv_name])
        raise
    names = {}
    for mesh, key, image in staged:
        mesh[RECORD][key] = texel_storage.commit_image(image, texel_storage.image_name(mesh, key == "back_image"))
        names.setdefault(mesh.name, set()).add(mesh[RECORD][key])
    for mesh_name, old in old_images.items():
        for name in old - names.get(mesh_name, set()):
            texel_storage.remove_image(name)


@dataclass
class BakeRecord:
    """The parsed mesh["prt_bake"] of a bake whose attributes are all present (docs/storage.md)."""

    order: int
    count: int  # attributes of the direct transfer (and of each bounce channel)
    domain: str
    record: object  # the IDProperty group itself
    channels: int = 0  # colour channels of the bounced transfer: 0 (direct only), 1 or 3
    resolution: int = 0  # texels per side (TEXEL domain)
    image: object = None  # the transfer image (TEXEL domain)
    uv_map: str = ""  # the UV map baked into (TEXEL domain)
    back: bool = False  # whether the back side has its own transfer (back_storage; texels: back_image)
    back_image: object = None  # the back side's transfer image (TEXEL domain)


def read_bake_record(mesh):
    """(BakeRecord, "") when the mesh holds a complete bake (stale or not: the topology is not
    checked here), else (None, why not)."""
    record = mesh.get(RECORD) if mesh is not None else None
    if record is None:
        return None, "not baked"
    try:
        version = int(record.get("version", 1))
    except (TypeError, ValueError):
        return None, "the bake record is incomplete"
    if version > FORMAT_VERSION:
        return None, (
            f"made by a newer version of PRT Lighting (storage format {version}, this "
            f"version reads up to {FORMAT_VERSION})"
        )
    try:
        order, count, domain = int(record["order"]), int(record["count"]), str(record["domain"])
    except (KeyError, TypeError, ValueError):
        return None, "the bake record is incomplete"
    try:
        channels = int(record.get("bounce_channels", 0))
    except (TypeError, ValueError):
        return None, "the bake record is incomplete"
    if order < 1 or count != attribute_count(order) or domain not in DOMAINS or channels not in (0, 1, 3):
        return None, "the bake record is inconsistent"
    if domain == "TEXEL":
        return _read_texel_record(record, order, count, channels)
    for k in range(count * (1 + channels)):
        attr = mesh.attributes.get(attribute_name(k))
        if attr is None or attr.domain != domain or attr.data_type != "FLOAT_COLOR":
            return None, f"attribute {attribute_name(k)} is missing or changed"
    problem = back_storage.missing_back(mesh, record, count, domain)
    back = bool(int(record.get("back", 0)))
    return (None, problem) if problem else (BakeRecord(order, count, domain, record, channels, back=back), "")


DOMAINS = ("POINT", "CORNER", "TEXEL")


def _read_texel_record(record, order, count, channels):
    try:
        res, name, uv_map = int(record["resolution"]), str(record["image"]), str(record["uv_map"])
    except (KeyError, TypeError, ValueError):
        return None, "the bake record is incomplete"
    image = texel_storage.find_image(name, res, count * (1 + channels))
    if image is None:
        return None, f"its transfer image '{name}' is missing or was resized"
    back, problem = texel_storage.find_back_image(record, res, count)
    if problem:
        return None, problem
    return BakeRecord(order, count, "TEXEL", record, channels, res, image, uv_map, back is not None, back), ""


def read_transfer(mesh, bake=None, padded=False):
    """(E, n*n) float32 coefficients of the last bake, or None when there is none usable.
    bake: its BakeRecord if already read; padded: keep the 4 * count channels (zero padding)."""
    if bake is None:
        bake, _problem = read_bake_record(mesh)
        if bake is None:
            return None
    return _read_part(mesh, bake, 0, padded)


def _read_part(mesh, bake, part, padded):
    names = [attribute_name(part * bake.count + k) for k in range(bake.count)]
    size = len(mesh.attributes[names[0]].data)
    packed = np.empty((bake.count, size * 4), dtype=np.float32)
    for k, name in enumerate(names):
        mesh.attributes[name].data.foreach_get("color", packed[k])
    values = packed.reshape(bake.count, size, 4).transpose(1, 0, 2).reshape(size, bake.count * 4)
    return np.ascontiguousarray(values if padded else values[:, : bake.order * bake.order])


def read_bounce(mesh, bake=None, padded=False):
    """(E, C, n*n) float32 bounced transfer of the last bake (C = 1 or 3), or None when the bake
    has no bounces (or none is usable)."""
    if bake is None:
        bake, _problem = read_bake_record(mesh)
    if bake is None or not bake.channels:
        return None
    return np.stack([_read_part(mesh, bake, 1 + c, padded) for c in range(bake.channels)], axis=1)


TOPOLOGY_CHANGED = "the topology changed since the bake"
# Fingerprints of big meshes for UI drawing, keyed by (pointer, counts): cleared when a file
# loads (handlers), since pointers are reused by the new file's data.
_fingerprint_cache = {}


def cached_fingerprint(mesh):
    """topology_fingerprint, cached for big meshes by (pointer, counts) (for UI drawing)."""
    key = (mesh.as_pointer(), len(mesh.vertices), len(mesh.edges), len(mesh.polygons), len(mesh.loops))
    if key[-1] < 200_000:
        return topology_fingerprint(mesh)
    value = _fingerprint_cache.get(key)
    if value is None:
        if len(_fingerprint_cache) > 64:
            _fingerprint_cache.clear()
        value = _fingerprint_cache[key] = topology_fingerprint(mesh)
    return value


@caches.on_geometry
def forget_cached_fingerprints(mesh):
    """Drop the cached fingerprints of `mesh` (its geometry changed, perhaps not its counts)."""
    pointer = mesh.as_pointer()
    for key in [k for k in _fingerprint_cache if k[0] == pointer]:
        del _fingerprint_cache[key]


def stale_topology(mesh, record, use_cache=False, allow_missing=False):
    """Why the fingerprint stored in the bake record does not match the mesh's topology, or ""
    when it does. A record without a fingerprint is incomplete, or accepted with allow_missing.
    use_cache: compare with cached_fingerprint (UI drawing) instead of the exact fingerprint."""
    stored = record.get("fingerprint")
    if stored is None:
        return "" if allow_missing else "the bake record is incomplete"
    current = cached_fingerprint(mesh) if use_cache else topology_fingerprint(mesh)
    return "" if current == str(stored) else TOPOLOGY_CHANGED


@dataclass
class BakeState:
    """What a mesh holds: status 'NONE', 'FRESH' or 'STALE', the reason shown to the user, the
    problem alone (without the advice), and the readable bake (also when it is stale because
    the topology changed or the mesh is in Edit Mode; None when it cannot be read)."""

    status: str
    reason: str
    problem: str = ""
    bake: object = None  # BakeRecord or None


def bake_state(mesh, topology="EXACT"):
    """The one set of rules for a mesh's bake. topology: 'EXACT' compares the exact fingerprint,
    'CACHED' the cached one (UI drawing), 'SKIP' does not compare (per-frame drawing)."""
    if mesh is None:
        return BakeState("NONE", "not a mesh", "not a mesh")
    if mesh.get(RECORD) is None:
        return BakeState("NONE", "not baked", "not baked")
    bake, problem = read_bake_record(mesh)
    if bake is None:
        return BakeState("STALE", f"{problem}: bake again", problem)
    if getattr(mesh, "is_editmode", False):
        why = "in Edit Mode"
        return BakeState("STALE", f"{why}: leave Edit Mode to check the bake", why, bake)
    if topology != "SKIP":
        problem = stale_topology(mesh, bake.record, use_cache=topology == "CACHED")
        if not problem and bake.domain == "TEXEL":
            problem = texel_storage.stale_uv_map(mesh, bake)
        if problem:
            return BakeState("STALE", f"{problem}: bake again", problem, bake)
    if bake.domain == "TEXEL":
        return BakeState("FRESH", f"order {bake.order}, {bake.resolution} x {bake.resolution} texels", "", bake)
    return BakeState("FRESH", f"order {bake.order}, {bake.domain.lower()} domain", "", bake)


def bake_status(mesh, use_cache=False):
    """('NONE' | 'FRESH' | 'STALE', reason) of the transfer stored on `mesh`."""
    state = bake_state(mesh, "CACHED" if use_cache else "EXACT")
    return state.status, state.reason


def usable_bake(mesh, check_topology=True):
    """(BakeRecord or None, problem or ""): whether the display can draw the mesh's bake.

    A bake whose topology changed still returns its BakeRecord, with the problem set; the draw
    path skips the topology check (check_topology=False) to stay cheap per frame. A record
    without a fingerprint (an incomplete record) is drawn but is stale for bake_status."""
    state = bake_state(mesh, "EXACT" if check_topology else "SKIP")
    if state.bake is None:
        return None, state.problem
    if state.status == "STALE" and state.problem == TOPOLOGY_CHANGED:
        return state.bake, "topology changed since the bake: re-bake"
    if state.status == "STALE" and state.problem.startswith("its UV map"):
        return state.bake, f"{state.problem}: re-bake"
    return state.bake, ""


@caches.on_clear
def forget_all_cached_fingerprints():
    _fingerprint_cache.clear()
