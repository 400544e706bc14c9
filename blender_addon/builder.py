"""Putting a computed sky into a Blender scene, all or nothing.

Everything the add-on creates carries the custom property ``skymodel_build`` (the build
id; world nodes included) and its objects live in the scene's own ``Skymodel``
collection. A build runs as a :class:`Transaction`: new datablocks and nodes are created
first, the world/scene settings are then switched over with every old value recorded,
and only when all of that succeeded are the previous build's datablocks removed. Any
exception before that point removes what was created and restores what was changed, so
the scene is exactly as before.

Every setting a build changes outside its own datablocks (exposure, view transform,
render engine, light-path bounces, the camera's clip end; :meth:`Transaction.set` on any
datablock but the add-on's settings) is recorded with its value before and after the
build as JSON on the scene (``scene["skymodel_restore"]``). **Remove Sky** puts each back
(:func:`restore_settings`), unless the user changed it since (then the user's value
stays); a rebuild first puts back what the previous build changed, so the record always
holds the values from before the first build.
"""

from __future__ import annotations

import json
import math
import time
import uuid

import bpy

TAG = "skymodel_build"
COLLECTION_NAME = "Skymodel"
PREVIOUS_SURFACE = "skymodel_previous_surface"
#: Scene custom property: JSON list of the settings the build changed, with their values before and after.
RESTORE_KEY = "skymodel_restore"
#: Datablock types whose settings a build may change, by RNA type name -> ``bpy.data`` collection.
_ID_COLLECTIONS = {"Scene": "scenes", "Camera": "cameras", "World": "worlds", "Object": "objects"}


def is_ours(id_or_node) -> bool:
    try:
        return TAG in id_or_node.keys()
    except (TypeError, AttributeError, ReferenceError):
        return False


class Transaction:
    """Records what a build creates and changes, to undo it on failure."""

    def __init__(self):
        self.build_id = uuid.uuid4().hex[:12]
        self.created: list[tuple[str, object]] = []  # ("images", datablock) / ("node", (tree, node))
        self.undo: list = []
        self.names: list[tuple[object, str]] = []  # (datablock or (tree, node name), wanted name)
        self.changed: list[dict] = []  # settings changed outside the add-on's data (see RESTORE_KEY)

    # -- creation
    def new(self, collection: str, *args, **kwargs):
        db = getattr(bpy.data, collection).new(*args, **kwargs)
        self.adopt(collection, db)
        if args and isinstance(args[0], str):
            self.names.append((db, args[0]))
        return db

    def adopt(self, collection: str, db):
        db[TAG] = self.build_id
        self.created.append((collection, db))
        return db

    def new_node(self, tree, idname: str, name: str, location=(0, 0)):
        node = tree.nodes.new(idname)
        node.name = name
        node.label = name
        node.location = location
        node[TAG] = self.build_id
        self.created.append(("node", (tree, node.name)))
        self.names.append(((tree, node.name), name))
        return node

    # -- changes
    def set(self, owner, attr: str, value):
        old = getattr(owner, attr)
        if hasattr(old, "copy") and not isinstance(old, (str, bytes)):
            old = old.copy()
        self.undo.append(lambda o=owner, a=attr, v=old: setattr(o, a, v))
        setattr(owner, attr, value)
        ref = _setting_ref(owner, attr)
        if ref is not None:
            ref["before"], ref["after"] = _plain(old), _plain(getattr(owner, attr))
            if ref["before"] != ref["after"]:
                self.changed.append(ref)

    def set_key(self, owner, key: str, value):
        had = key in owner.keys()
        old = owner[key] if had else None

        def restore(o=owner, k=key, h=had, v=old):
            if h:
                o[k] = v
            elif k in o.keys():
                del o[k]

        self.undo.append(restore)
        owner[key] = value

    def link_socket(self, tree, from_socket, to_socket):
        """Link, remembering the links into ``to_socket`` that it replaces."""
        old = [(lk.from_node.name, lk.from_socket.identifier) for lk in to_socket.links]
        to_node, to_id = to_socket.node.name, to_socket.identifier
        tree.links.new(from_socket, to_socket)

        def restore(t=tree, old=old, to_node=to_node, to_id=to_id):
            node = t.nodes.get(to_node)
            if node is None:
                return
            sock = next((s for s in node.inputs if s.identifier == to_id), None)
            if sock is None:
                return
            for lk in list(sock.links):
                t.links.remove(lk)
            for fn, fs in old:
                src = t.nodes.get(fn)
                out = next((s for s in src.outputs if s.identifier == fs), None) if src else None
                if out is not None:
                    t.links.new(out, sock)

        self.undo.append(restore)

    def link_object(self, collection, obj):
        collection.objects.link(obj)
        self.undo.append(lambda c=collection, o=obj: c.objects.unlink(o) if o.name in c.objects else None)

    def link_child_collection(self, parent, child):
        parent.children.link(child)
        self.undo.append(lambda p=parent, c=child: p.children.unlink(c) if c.name in p.children else None)

    # -- ending
    def rollback(self):
        for fn in reversed(self.undo):
            try:
                fn()
            except Exception as ex:  # keep undoing the rest
                print(f"[skymodel] rollback step failed: {ex!r}")
        for kind, item in reversed(self.created):
            try:
                if kind == "node":
                    tree, name = item
                    node = tree.nodes.get(name)
                    if node is not None:
                        tree.nodes.remove(node)
                else:
                    getattr(bpy.data, kind).remove(item)
            except (ReferenceError, RuntimeError) as ex:
                print(f"[skymodel] rollback removal failed: {ex!r}")
        self.undo.clear()
        self.created.clear()


# --------------------------------------------------------------------------- restoring settings


def _plain(value):
    """A JSON-able copy of a property value (vectors and colours as lists)."""
    if isinstance(value, (bool, int, float, str)) or value is None:
        return value
    try:
        return [_plain(v) for v in value]
    except TypeError:
        return str(value)


def _setting_ref(owner, attr: str) -> dict | None:
    """Where ``owner.attr`` lives, as JSON-able data (``None`` for the add-on's own settings
    and for anything that cannot be found again by name)."""
    try:
        idb = owner.id_data
        path = owner.path_from_id() if owner is not idb else ""
    except (AttributeError, ValueError, TypeError):
        return None
    kind = _ID_COLLECTIONS.get(type(idb).bl_rna.identifier)
    if kind is None or path.startswith("skymodel"):
        return None
    return {"id": [kind, idb.name], "path": path, "attr": attr}


def _resolve_setting(ref: dict):
    kind, name = ref["id"]
    idb = getattr(bpy.data, kind).get(name)
    if idb is None:
        return None
    try:
        return idb.path_resolve(ref["path"]) if ref["path"] else idb
    except ValueError:
        return None


def _same(a, b) -> bool:
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) or isinstance(b, float):
        try:
            return math.isclose(float(a), float(b), rel_tol=1e-6, abs_tol=1e-9)
        except (TypeError, ValueError):
            return False
    return a == b


def recorded_settings(scene) -> list[dict]:
    """The settings the scene's current build changed (``[]`` when none or unreadable)."""
    try:
        data = json.loads(scene.get(RESTORE_KEY, "[]"))
    except (TypeError, ValueError):
        return []
    return [r for r in data if isinstance(r, dict) and {"id", "path", "attr", "before", "after"} <= r.keys()]


def restore_settings(scene, tx: Transaction | None = None) -> list[str]:
    """Put back every setting the last build changed and that still has the build's value
    (through ``tx`` when given, so a failing rebuild undoes it); forget the record.
    Returns the settings put back, as ``"Scene.render.engine"`` text."""
    done = []
    for ref in reversed(recorded_settings(scene)):
        owner = _resolve_setting(ref)
        if owner is None or not hasattr(owner, ref["attr"]):
            continue
        if not _same(_plain(getattr(owner, ref["attr"])), ref["after"]):
            continue  # changed by the user since the build: theirs stays
        try:
            if tx is not None:
                tx.set(owner, ref["attr"], ref["before"])
            else:
                setattr(owner, ref["attr"], ref["before"])
        except (TypeError, ValueError, AttributeError) as ex:
            print(f"[skymodel] could not restore {ref['path']}.{ref['attr']}: {ex!r}")
            continue
        done.append(".".join(p for p in (ref["id"][1], ref["path"], ref["attr"]) if p))
    if RESTORE_KEY in scene.keys():
        if tx is not None:
            tx.changed.clear()  # what was just put back is no change of this build
            tx.set_key(scene, RESTORE_KEY, "[]")
        else:
            del scene[RESTORE_KEY]
    return done


# --------------------------------------------------------------------------- lookups


def find_collection(scene):
    for c in scene.collection.children:
        if is_ours(c):
            return c
    return None


def world_output(tree):
    outs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputWorld"]
    for n in outs:
        if n.is_active_output:
            return n
    return outs[0] if outs else None


def remove_previous(scene, world, build_id: str):
    """Delete the previous build's nodes, objects and datablocks (those tagged with
    another build id and no longer used)."""
    tree = world.node_tree if world is not None else None
    if tree is not None:
        for n in [n for n in tree.nodes if is_ours(n) and n[TAG] != build_id]:
            tree.nodes.remove(n)
    coll = find_collection(scene)
    datas = []
    if coll is not None:
        for obj in [o for o in coll.all_objects if is_ours(o) and o[TAG] != build_id]:
            if obj.data is not None and is_ours(obj.data):
                datas.append(obj.data)
            mats = [s.material for s in getattr(obj, "material_slots", []) if s.material is not None]
            bpy.data.objects.remove(obj)
            datas.extend(m for m in mats if is_ours(m))
    for db in datas:
        try:
            if db.users == 0:
                for kind in ("meshes", "lights", "materials"):
                    col = getattr(bpy.data, kind)
                    if db.name in col and col[db.name] == db:
                        col.remove(db)
                        break
        except ReferenceError:
            pass
    # tagged datablocks orphaned by the swap
    for kind in ("images", "materials", "meshes", "lights", "node_groups"):
        col = getattr(bpy.data, kind)
        for db in [d for d in col if is_ours(d) and d[TAG] != build_id and d.users == 0]:
            col.remove(db)


def remove_all(scene, world):
    """Remove every node, object and datablock of the add-on from this scene and world
    (the Remove Sky operator); relinks the world surface the add-on replaced and puts back
    the settings the build changed (:func:`restore_settings`)."""
    from . import animation

    animation.remove_bake(scene)  # a baked time of day: its exposure keys and images
    restore_settings(scene)
    tree = world.node_tree if world is not None else None
    prev = world.get(PREVIOUS_SURFACE) if world is not None else None
    remove_previous(scene, world, build_id="")
    coll = find_collection(scene)
    if coll is not None and len(coll.all_objects) == 0 and not coll.children:
        bpy.data.collections.remove(coll)
    if tree is not None and prev:
        src = tree.nodes.get(prev)
        out = world_output(tree)
        if src is not None and out is not None and src.outputs and not out.inputs["Surface"].links:
            tree.links.new(src.outputs[0], out.inputs["Surface"])
    if world is not None and PREVIOUS_SURFACE in world.keys():
        del world[PREVIOUS_SURFACE]


# --------------------------------------------------------------------------- pieces


def sun_rotation(elevation_deg: float, azimuth_deg: float):
    """Euler rotation of a sun lamp shining *from* (elevation, azimuth): its local +Z
    points at the sun (Blender lamps emit along local -Z)."""
    from mathutils import Vector  # after bpy

    el, az = math.radians(elevation_deg), math.radians(azimuth_deg)
    d = Vector((math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)))
    return d.to_track_quat("Z", "Y").to_euler()


def _ensure_collection(tx: Transaction, scene):
    coll = find_collection(scene)
    if coll is None:
        coll = tx.new("collections", COLLECTION_NAME)
        tx.link_child_collection(scene.collection, coll)
    return coll


def _new_sun(tx: Transaction, result):
    light = tx.new("lights", "Skymodel Sun", "SUN")
    light.energy = float(result.sun_strength)
    light.color = tuple(float(c) for c in result.sun_colour)
    light.angle = math.radians(float(result.sun_angle_deg))
    obj = tx.new("objects", "Skymodel Sun", light)
    obj.rotation_mode = "XYZ"
    obj.rotation_euler = sun_rotation(result.sun_elevation_deg, result.sun_azimuth_deg)
    obj.location = (0.0, 0.0, 10.0)
    obj["skymodel_sun_elevation_deg"] = float(result.sun_elevation_deg)
    obj["skymodel_sun_azimuth_deg"] = float(result.sun_azimuth_deg)
    return obj


def _new_moon(tx: Transaction, moon: dict):
    """The moon lamp (:func:`.physics.moon_lamp`): a second sun lamp shining from the moon,
    with its irradiance at the observer, colour and apparent diameter."""
    light = tx.new("lights", "Skymodel Moon", "SUN")
    light.energy = float(moon["strength"])
    light.color = tuple(float(c) for c in moon["colour"])
    light.angle = math.radians(float(moon["angle_deg"]))
    obj = tx.new("objects", "Skymodel Moon", light)
    obj.rotation_mode = "XYZ"
    obj.rotation_euler = sun_rotation(moon["elevation_deg"], moon["azimuth_deg"])
    obj.location = (0.0, 0.0, 12.0)
    for key in ("elevation_deg", "azimuth_deg", "phase_angle_deg", "illuminated_fraction", "illuminance_lux"):
        obj[f"skymodel_moon_{key}"] = float(moon[key])
    return obj


def _world_surface(tx: Transaction, world, shader_socket):
    tree = world.node_tree
    out = world_output(tree)
    if out is None:
        out = tx.new_node(tree, "ShaderNodeOutputWorld", "Skymodel World Output", (300, 300))
    surf = out.inputs["Surface"]
    for lk in surf.links:
        if not is_ours(lk.from_node) and PREVIOUS_SURFACE not in world.keys():
            tx.set_key(world, PREVIOUS_SURFACE, lk.from_node.name)
    tx.link_socket(tree, shader_socket, surf)
    return out


def _environment_nodes(tx: Transaction, world, image):
    tree = world.node_tree
    x0, y0 = -700, 300
    env = tx.new_node(tree, "ShaderNodeTexEnvironment", "Skymodel Environment", (x0, y0))
    env.image = image
    env.projection = "EQUIRECTANGULAR"
    env.interpolation = "Linear"
    bg = tx.new_node(tree, "ShaderNodeBackground", "Skymodel Background", (x0 + 350, y0))
    bg.inputs["Strength"].default_value = 1.0
    tree.links.new(env.outputs["Color"], bg.inputs["Color"])
    _world_surface(tx, world, bg.outputs["Background"])


def _sky_texture_nodes(tx: Transaction, world, tex: dict):
    """Blender's Sky Texture (settings from physics.blender_sky_texture) -> Background."""
    tree = world.node_tree
    x0, y0 = -700, 300
    sky = tx.new_node(tree, "ShaderNodeTexSky", "Skymodel Sky Texture", (x0, y0))
    sky.sky_type = tex["sky_type"]
    sky.sun_disc = False  # the lamp is the sun
    sky.sun_elevation = math.radians(tex["sun_elevation_deg"])
    sky.sun_rotation = math.radians(tex["sun_rotation_deg"])
    sky.altitude = tex["altitude_m"]
    sky.air_density = tex["air_density"]
    sky.aerosol_density = tex["aerosol_density"]
    sky.ozone_density = tex["ozone_density"]
    bg = tx.new_node(tree, "ShaderNodeBackground", "Skymodel Background", (x0 + 350, y0))
    bg.inputs["Strength"].default_value = 1.0
    tree.links.new(sky.outputs["Color"], bg.inputs["Color"])
    _world_surface(tx, world, bg.outputs["Background"])


def black_world_nodes(tx: Transaction, world):
    """A black, zero-strength Background as the world surface (volumetric mode: the sky is in the volumes)."""
    tree = world.node_tree
    bg = tx.new_node(tree, "ShaderNodeBackground", "Skymodel Background", (-350, 300))
    bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    bg.inputs["Strength"].default_value = 0.0
    _world_surface(tx, world, bg.outputs["Background"])


def _view_settings(tx: Transaction, scene, exposure: float):
    vs = scene.view_settings
    try:
        tx.set(vs, "view_transform", "AgX")
    except TypeError:
        tx.set(vs, "view_transform", "Filmic")
    tx.set(vs, "exposure", float(exposure))


def film_exposure(settings, result) -> float:
    """The exposure Build Sky sets: the rule chosen in the panel (``exposure_rule``: the
    core's display exposure, or the incident-light rule alone) plus the user's offset."""
    base = float(result.exposure)
    if getattr(settings, "exposure_rule", "SKY") == "INCIDENT":
        base = float(result.info.get("exposure_incident", base))
    return base + float(getattr(settings, "exposure_offset", 0.0))


#: Folder beside the .blend that holds the sky images of ``image_storage = "BESIDE"``.
BESIDE_FOLDER = "skymodel_sky"


def _copy_beside_blend(tx: Transaction, path: str) -> str | None:
    """Copy the cached EXR into :data:`BESIDE_FOLDER` next to the saved .blend; returns the
    Blender-relative path (``//skymodel_sky/<name>``), or None when the file is unsaved. A copy
    this build made is deleted again if the build fails."""
    import os
    import shutil

    blend = bpy.data.filepath
    if not blend:
        return None
    folder = os.path.join(os.path.dirname(blend), BESIDE_FOLDER)
    os.makedirs(folder, exist_ok=True)
    dest = os.path.join(folder, os.path.basename(path))
    if not os.path.exists(dest):
        tmp = dest + ".part"
        shutil.copyfile(path, tmp)
        os.replace(tmp, dest)
        tx.undo.append(lambda d=dest: os.remove(d) if os.path.exists(d) else None)
    return "//" + BESIDE_FOLDER + "/" + os.path.basename(path)


def load_image(tx: Transaction, path: str, storage="PACK"):
    """Load the sky EXR as ``Skymodel Sky`` and keep it where ``storage`` says: ``"PACK"``
    (packed into the .blend, the default), ``"BESIDE"`` (a copy beside the saved .blend, by
    a relative path; packed when the file has not been saved yet). ``True`` / ``False`` are
    read as ``"PACK"`` / linked to ``path`` as it is (tests only). Returns the image and where
    it went (``"packed"``, ``"beside"``, ``"linked"``)."""
    if storage is True:
        storage = "PACK"
    where = "linked"
    if storage == "BESIDE":
        rel = _copy_beside_blend(tx, path)
        if rel is not None:
            path, where = bpy.path.abspath(rel), "beside"
        else:
            storage = "PACK"
    img = bpy.data.images.load(path, check_existing=False)
    tx.adopt("images", img)
    img.name = "Skymodel Sky"
    tx.names.append((img, "Skymodel Sky"))
    try:
        img.colorspace_settings.name = "Linear Rec.709"
    except TypeError:
        img.colorspace_settings.name = "scene_linear"
    if tuple(img.size) == (0, 0):
        raise RuntimeError(f"could not read the sky image {path}")
    if where == "beside":
        img.filepath = bpy.path.relpath(path)
    if storage == "PACK":
        img.pack()
        where = "packed"
    img["skymodel_storage"] = where
    return img


def build(scene, world, settings, result, add_content) -> str:
    """Run one build as a :class:`Transaction`, all or nothing; returns the build id.

    Creates the ``Skymodel`` collection (if needed) and the sun lamp of ``result``, calls
    ``add_content(tx, collection)`` for what the mode adds (world nodes, objects, render
    settings: everything through ``tx``), then sets the exposure (when
    ``settings.set_exposure``) and the panel's info. On any exception everything is undone
    and the exception re-raised; on success the previous build is removed and the new
    datablocks get their plain names."""
    tx = Transaction()
    try:
        restore_settings(scene, tx)  # the previous build's changes: the record keeps the first values
        coll = _ensure_collection(tx, scene)
        sun = _new_sun(tx, result)
        tx.link_object(coll, sun)
        if getattr(result, "moon", None):
            tx.link_object(coll, _new_moon(tx, result.moon))
        add_content(tx, coll)
        if settings.set_exposure:
            _view_settings(tx, scene, film_exposure(settings, result))
        _write_info(tx, settings, result)
        if tx.changed:
            tx.set_key(scene, RESTORE_KEY, json.dumps(tx.changed))
        elif RESTORE_KEY in scene.keys():
            _del_key(tx, scene, RESTORE_KEY)
        _fail_hook("after_swap")
    except BaseException:
        tx.rollback()
        raise
    remove_previous(scene, world, tx.build_id)
    from . import animation

    animation.remove_bake(scene, keep_build=tx.build_id)  # a bake this build replaced
    commit_names(tx)
    return tx.build_id


def apply_environment(scene, world, settings, result, progress=None):
    """Environment mode: image world + sun lamp. Returns the build id."""
    if progress:
        progress("loading the sky image")
    sky_texture = result.info.get("sky_texture")  # sky model "blender": its own node, no image

    def world_nodes(tx, coll):
        if sky_texture:
            _sky_texture_nodes(tx, world, sky_texture)
        else:
            # a live update's preview is always packed: previews come and go while a slider moves,
            # and copies beside the .blend would pile up there
            storage = "PACK" if result.info.get("live") == "preview" else settings.image_storage
            img = load_image(tx, result.image_path, storage)
            result.info["image_storage"] = img["skymodel_storage"]
            _environment_nodes(tx, world, img)

    return build(scene, world, settings, result, world_nodes)


def _del_key(tx: Transaction, owner, key: str):
    old = owner[key]
    del owner[key]
    tx.undo.append(lambda o=owner, k=key, v=old: o.__setitem__(k, v))


def commit_names(tx: Transaction):
    """Give the new datablocks and nodes their plain names once the previous build's
    are gone (so a rebuild is "Skymodel Sun", not "Skymodel Sun.001")."""
    for item, name in tx.names:
        try:
            if isinstance(item, tuple):
                tree, old = item
                node = tree.nodes.get(old)
                if node is not None and node.name != name:
                    node.name = name
                    node.label = name
            elif item.name != name:
                item.name = name
        except (ReferenceError, AttributeError):
            pass


def _write_info(tx: Transaction, settings, result):
    stamp = time.strftime("%Y-%m-%d %H:%M:%S")
    info = result.info
    lines = [
        f"{result.mode.title()}: sun {result.sun_elevation_deg:.2f}° el, {result.sun_azimuth_deg:.2f}° az",
        f"Sun {result.sun_strength:.3g} W/m² (Y), exposure {film_exposure(settings, result):+.2f} EV",
    ]
    moon = getattr(result, "moon", None)
    if moon:
        lines.append(f"Moon {moon['elevation_deg']:.1f}° el, {moon['azimuth_deg']:.1f}° az, "
                     f"{100 * moon['illuminated_fraction']:.0f} % lit, {moon['illuminance_lux']:.3g} lux")
    if isinstance(night := info.get("night"), dict) and result.sun_elevation_deg < 0.0:  # the core's night
        from . import physics

        lines.append(("Night (no sunlit sky below -18°): " if result.sun_elevation_deg < physics.MIN_SUN_ELEVATION_DEG
                      else "Night's light: ") + ("moonlit sky, " if night.get("moonlit_sky") else "")
                     + f"{int(night.get('stars_drawn', 0))} stars and the glow in the image")
    if sky_time := info.get("time_local"):
        lines.append(f"Time {sky_time}")
    if info.get("live"):
        lines.append(f"Live update: {info['live']} quality" + (" (the chosen quality follows)"
                                                                if info["live"] == "preview" else ""))
    if "total_s" in info:
        lines.append(f"Built in {info['total_s']:.1f} s" + (" (cached image)" if result.cache_hit else ""))
    if info.get("auto"):
        lines.append(f"Auto: {info['auto']}")
    if "sky_model" in info:
        lines.append(f"Model {info['sky_model']}")
    if info.get("image_storage"):
        lines.append({"packed": "Sky image packed into the .blend",
                      "beside": f"Sky image in //{BESIDE_FOLDER}/",
                      "linked": "Sky image linked to the cache"}.get(info["image_storage"], ""))
    lines.extend(str(w) for w in info.get("warnings", ()))
    tx.set(settings, "last_build", stamp)
    tx.set(settings, "last_info", " | ".join(lines))


#: Test hook: name of a stage at which to raise (simulates a failure inside the swap).
FAIL_AT: str | None = None


def _fail_hook(stage: str):
    if FAIL_AT == stage:
        raise RuntimeError(f"simulated failure at {stage}")
