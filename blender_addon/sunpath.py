"""The sun's path over the chosen day, shown in the viewport (the panel's *Sun Path*).

A poly curve object, ``Skymodel Sun Path``, through the sun's directions over the local
day of the panel's date (``year``/``month``/``day``, read in its *Time Zone*) every
:data:`STEP_MIN` minutes from local midnight to the next, on a sphere of radius
``sun_path_radius`` around the world origin (Blender's +X east, +Y north, +Z up, as the
sun lamp), and one empty per local whole hour, named by its hour (``Sun 13:00``) with the
name drawn in the viewport, placed where the sun is then. Below-horizon parts are drawn
too (as the Sun Position add-on does), so the path reads as the whole day. Directions
come from the core (:func:`skymodel.sun.solar_position`: NOAA / Meeus, no refraction; the
same the sky is built with), the local day from :func:`skymodel.scene.resolve_time`.
The objects live in their own collection ``Skymodel Sun Path``, are not rendered, and
are replaced whenever the date, the place, the zone or the radius changes while *Sun
Path* is on; switching it off deletes them (and the collection). Nothing here touches
the sky build.
"""

from __future__ import annotations

import datetime as _dt

import numpy as np

import bpy
from skymodel.errors import SkymodelInputError

TAG = "skymodel_sun_path"
COLLECTION_NAME = "Skymodel Sun Path"
PATH_NAME = "Skymodel Sun Path"
#: Minutes between the path's points.
STEP_MIN = 10

#: The last error (bad date, zone...), shown in the panel; None when the path is drawn.
ERROR: dict = {}


def day_path(latitude_deg: float, longitude_deg: float, date, timezone=None, step_min: int = STEP_MIN):
    """The sun over one local day: ``(utc datetimes, local datetimes, elevation_deg,
    azimuth_deg)`` from local midnight of ``date`` (``(year, month, day)`` or a
    :class:`datetime.date`) in ``timezone`` (None: UTC; ``auto``: the zone at the place)
    to the next midnight, every ``step_min`` minutes (real time: a day with a
    daylight-saving change has 23 or 25 hours). Raises ``SkymodelInputError`` naming the
    parameter (``day``, ``timezone``...)."""
    from skymodel import scene
    from skymodel.sun import solar_position

    y, m, d = (date.year, date.month, date.day) if isinstance(date, _dt.date) else date
    zone = scene.place_zone(timezone, latitude_deg, longitude_deg) if timezone is not None else None
    tz = scene.time_zone(zone) or _dt.timezone.utc
    start = scene.resolve_time((y, m, d, 0, 0), zone)
    nxt = _dt.date(int(y), int(m), int(d)) + _dt.timedelta(days=1)
    end = scene.resolve_time((nxt.year, nxt.month, nxt.day, 0, 0), zone)
    n = int((end.utc - start.utc).total_seconds() // (60 * step_min)) + 1
    utc = [start.utc + _dt.timedelta(minutes=step_min * k) for k in range(n)]
    times = np.array([u.replace(tzinfo=None) for u in utc], dtype="datetime64[us]")
    pos = solar_position(latitude_deg, longitude_deg, times)
    local = [u.astimezone(tz) for u in utc]
    return utc, local, np.asarray(pos.elevation_deg, float), np.asarray(pos.azimuth_deg, float)


def directions(elevation_deg, azimuth_deg) -> np.ndarray:
    """Unit vectors toward the sun in Blender's axes (x east, y north, z up), shape (n, 3)."""
    el, az = np.radians(elevation_deg), np.radians(azimuth_deg)
    return np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=-1)


def _place(settings):
    """(latitude, longitude) of the panel's place, validated by the core (the sun fields are not used)."""
    import dataclasses

    from . import physics

    params = dataclasses.replace(settings.to_params(), time_utc=None, timezone=None, moon_lamp=False)
    sky = physics.resolve(params)
    return float(sky.atmosphere.latitude), float(sky.atmosphere.longitude)


def find_collection(scene):
    for c in scene.collection.children:
        if TAG in c.keys():
            return c
    return None


def remove(scene) -> int:
    """Delete the sun path's objects, curve data and collection; returns how many objects."""
    coll = find_collection(scene)
    n = 0
    if coll is None:
        return 0
    for obj in list(coll.objects):
        data = obj.data
        bpy.data.objects.remove(obj)
        n += 1
        if data is not None and data.users == 0:
            bpy.data.curves.remove(data)
    bpy.data.collections.remove(coll)
    return n


def build(scene, settings) -> dict:
    """(Re)draw the path of the panel's day (see the module doc). Everything is computed
    before the scene changes, so bad input (raised naming the parameter) leaves the old
    path as it was. Returns ``{"points", "hours", "zone"}``."""
    lat, lon = _place(settings)
    zone = settings.timezone.strip() or None
    utc, local, el, az = day_path(lat, lon, (settings.year, settings.month, settings.day), zone)
    radius = float(settings.sun_path_radius)
    pts = directions(el, az) * radius
    hours = [k for k, t in enumerate(local[:-1]) if t.minute == 0 and t.second == 0]  # not the next midnight
    remove(scene)
    coll = bpy.data.collections.new(COLLECTION_NAME)
    coll[TAG] = 1
    scene.collection.children.link(coll)
    curve = bpy.data.curves.new(PATH_NAME, "CURVE")
    curve.dimensions = "3D"
    spline = curve.splines.new("POLY")
    spline.points.add(len(pts) - 1)
    spline.points.foreach_set("co", np.c_[pts, np.ones(len(pts))].astype(np.float32).ravel())
    curve[TAG] = 1
    path = bpy.data.objects.new(PATH_NAME, curve)
    path[TAG] = 1
    path.hide_render = True
    coll.objects.link(path)
    for k in hours:
        name = f"Sun {local[k]:%H:%M}"
        marker = bpy.data.objects.new(name, None)
        marker.empty_display_type = "SPHERE"
        marker.empty_display_size = radius * 0.015
        marker.location = tuple(float(v) for v in pts[k])
        marker.show_name = True
        marker.hide_render = True
        marker[TAG] = 1
        marker["skymodel_local_time"] = local[k].isoformat(timespec="minutes")
        marker["skymodel_sun_elevation_deg"] = float(el[k])
        marker["skymodel_sun_azimuth_deg"] = float(az[k])
        marker.parent = path
        coll.objects.link(marker)
    tz_name = local[0].tzname() or "UTC"
    path["skymodel_day"] = f"{local[0]:%Y-%m-%d} ({tz_name})"
    path["skymodel_signature"] = signature(settings)
    return {"points": len(pts), "hours": len(hours), "zone": tz_name}


def _scene_of(settings, context):
    scene = getattr(context, "scene", None) if context is not None else None
    world = settings.id_data
    if scene is None or scene.world != world:
        scene = next((s for s in bpy.data.scenes if s.world == world), None)
    return scene


def on_change(settings, context=None):
    """Update callback: draw the path when *Sun Path* is on (again after any change of the
    day, place, zone or radius), delete it when off. Never raises: an error is kept in
    :data:`ERROR` for the panel, and the old path stays."""
    scene = _scene_of(settings, context)
    if scene is None:
        return
    try:
        if settings.show_sun_path:
            build(scene, settings)
        else:
            remove(scene)
        ERROR.pop(scene.name, None)
    except SkymodelInputError as ex:
        ERROR[scene.name] = str(ex)
    except Exception as ex:  # an update callback must not break the UI
        ERROR[scene.name] = f"{type(ex).__name__}: {ex}"


def signature(settings) -> str:
    """What the path depends on (place, date, zone, radius): a change of anything else
    (the hour, the aerosol...) keeps the path as it is."""
    return repr((settings.location_source, settings.location.strip().lower(), round(settings.latitude, 9),
                 round(settings.longitude, 9), settings.year, settings.month, settings.day,
                 settings.timezone.strip(), round(settings.sun_path_radius, 6)))


def refresh(settings, context=None):
    """After a change of the sky's settings: redraw the path if it is shown and its place,
    date, zone or radius changed."""
    if not getattr(settings, "show_sun_path", False):
        return
    scene = _scene_of(settings, context)
    path = bpy.data.objects.get(PATH_NAME)
    if (scene is not None and path is not None and find_collection(scene) is not None
            and path.get("skymodel_signature") == signature(settings) and scene.name not in ERROR):
        return
    on_change(settings, context)


def draw_panel(layout, settings, scene):
    row = layout.row(align=True)
    row.prop(settings, "show_sun_path")
    if settings.show_sun_path:
        row.prop(settings, "sun_path_radius", text="Radius")
        err = ERROR.get(scene.name) if scene is not None else None
        if err:
            layout.label(text=f"Sun path: {err}", icon="ERROR")
        elif settings.sun_source != "TIME":
            layout.label(text=f"Path of {settings.year}-{settings.month:02d}-{settings.day:02d} (the Date and Time fields)")
