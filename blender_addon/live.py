"""Live update: the sky follows the World panel while its settings change.

With *Live Update* on (``World.skymodel.live_update``, Environment mode), every change of
a setting the sky depends on (the update callbacks of :mod:`.props`: sun, date and time,
time zone, place, aerosol, ozone, albedo, quality, exposure...) calls :func:`on_change`,
which only counts the change (``generation``) and stamps its time; nothing is computed
in the callback. A timer (:func:`tick`, every :data:`POLL_S` s on the main thread while
anything is pending) then runs two stages with the add-on's background build
(:class:`.ops.BuildJob`: the settings read and validated on the main thread, the physics
in a thread, the scene changed on the main thread in one transaction):

1. **preview**: once the settings have been still for :data:`DEBOUNCE_S` s, a build at
   ``preview`` quality and at most the preview's image width (:data:`PREVIEW_WIDTH`);
   several quick changes give one build, of the last values. While a slider keeps moving,
   a preview starts :data:`DRAG_REFRESH_S` s after the first change not yet being built
   and again as soon as the previous one is done, so the sky follows a long drag (one
   preview at a time, of the values current when it started);
2. **final**: once the preview of the current values is shown and the settings have been
   still for :data:`SETTLE_S` s, a build at the panel's quality and width (skipped when
   the preview already is that).

A change while the chosen quality is being built supersedes that build: it is cancelled
and its result dropped. (A preview build runs on: its sky, of slightly older values, is
shown when it is done, unless a newer one has been shown, and the next preview follows
at once.) A cancelled thread stops at its next progress step, but the pixel march has none (a warm
``final`` 1024x512 marches for ~18 s), so the next build does not wait for it: it starts
beside the cancelled one, which runs on without touching the scene or writing a file (it
stops at its next step, before writing); at most :data:`MAX_CANCELLED_RUNNING` cancelled
threads run at a time (then the next build waits). Skies are shown in the order of the
settings they were computed from (``generation``): the chosen quality only for the
settings as they are now, a preview only if nothing newer is shown, so an older sky is
never shown after a newer one. Applying is what Build Sky does: the
world image, the sun lamp (and the moon's), the exposure; all or nothing, so a failed
build leaves the scene as it was and the panel shows the error (the message names the
parameter, as Build Sky's do) until the next change.

Not done by a live build: Volumetric and Auto modes (a change there waits for Build
Sky), a scene with a baked time of day (a live build would replace the bake: Build Sky
does that on purpose), and builds while Build Sky's own build runs (the live update waits
for it). Build Sky cancels a live build first. Blender's undo restores a setting without
calling its update callback, so after Ctrl+Z the sky stays as it was until the next change.

Headless and in tests there is no event loop, so timers never fire: call :func:`tick`
(``now=`` a fake clock) to run the machinery step by step.
"""

from __future__ import annotations

import dataclasses
import time
import traceback
from dataclasses import dataclass, field
from types import SimpleNamespace

import bpy
from skymodel.errors import SkymodelInputError

#: Seconds the settings must be still before the preview build starts (a drag gives one build).
DEBOUNCE_S = 0.25
#: While the settings keep changing (a drag), a preview starts this long after the first change not yet built.
DRAG_REFRESH_S = 0.5
#: Seconds the settings must be still before the chosen quality is built (after the preview is shown).
SETTLE_S = 1.0
#: Timer interval while anything is pending or running.
POLL_S = 0.1
#: Cancelled builds whose threads may still run while the next one starts (each ends at its
#: next progress step; the march has none): with 1, at most two build threads run.
MAX_CANCELLED_RUNNING = 1
#: Quality and largest image width of the preview stage.
PREVIEW_QUALITY = "preview"


def _preview_width() -> int:
    from skymodel.render.environment import IMAGE_WIDTH

    return int(IMAGE_WIDTH[PREVIEW_QUALITY])


PREVIEW_WIDTH = _preview_width()


def clock() -> float:
    return time.monotonic()


@dataclass
class LiveState:
    """The live update's state (one per Blender session: the world last changed)."""

    generation: int = 0  #: counts the changes; a result is applied only for the current one
    changed_at: float = 0.0  #: clock() of the last change
    pending_since: float = 0.0  #: clock() of the first change not yet being built
    scene: str = ""  #: names of the scene and world the changes were made in
    world: str = ""
    pending: str | None = None  #: the next stage to build: "preview", "final" or None (idle)
    job: object = None  #: the LiveJob in flight
    cancelled_jobs: list = field(default_factory=list)  #: cancelled LiveJobs whose threads still run
    shown: tuple | None = None  #: (generation, stage) the scene shows
    history: list = field(default_factory=list)  #: every (generation, stage) shown, in order
    error: str | None = None  #: the last failure (shown in the panel until the next change)
    status: str = ""  #: one line for the panel
    builds: dict = field(default_factory=lambda: {"preview": 0, "final": 0, "cancelled": 0, "dropped": 0})
    latency: dict = field(default_factory=dict)  #: stage -> seconds from the last change to the sky shown
    timer: bool = False


STATE = LiveState()


def reset():
    """Forget everything (a new file, unregister); a running thread is cancelled."""
    global STATE
    for job in [STATE.job, *STATE.cancelled_jobs]:
        if job is not None and job.running:
            job.cancel()
    _remove_timer()
    STATE = LiveState()


# --------------------------------------------------------------------------- what may run


def _settings_of(world):
    return getattr(world, "skymodel", None) if world is not None else None


def blocked_reason(scene, settings) -> str | None:
    """Why a live build cannot run for these settings now (None: it can)."""
    if settings is None:
        return "no world"
    if settings.mode != "ENVIRONMENT":
        return "Live Update works in Environment mode (use Build Sky)"
    from . import animation

    if animation.bake_record(scene):
        return "a baked time of day is in the scene (Build Sky replaces it)"
    return None


def stage_params(params, stage: str):
    """The parameters a stage builds: the panel's (``final``) or, for ``preview``, the
    preview quality at the smaller of the panel's width and :data:`PREVIEW_WIDTH`."""
    if stage == "final":
        return params
    from skymodel.render.environment import image_width

    width = min(image_width(params.image_width, params.quality), PREVIEW_WIDTH)
    return dataclasses.replace(params, quality=PREVIEW_QUALITY, image_width=width)


def final_is_preview(params) -> bool:
    """Whether the panel's own quality and width are what the preview stage builds."""
    from skymodel.render.environment import image_width

    return params.quality == PREVIEW_QUALITY and image_width(params.image_width, params.quality) <= PREVIEW_WIDTH


# --------------------------------------------------------------------------- the callbacks


def on_change(settings, context=None):
    """Update callback of the sky's settings: count the change, stamp it, cancel a build
    of older values, make sure the timer runs. Cheap; never raises."""
    try:
        if not getattr(settings, "live_update", False):
            return
        world = settings.id_data
        scene = getattr(context, "scene", None) if context is not None else None
        if scene is None or scene.world != world:
            scene = next((s for s in bpy.data.scenes if s.world == world), None)
        STATE.generation += 1
        STATE.changed_at = clock()
        if STATE.pending != "preview":
            STATE.pending_since = STATE.changed_at
        STATE.world = world.name
        STATE.scene = scene.name if scene is not None else ""
        STATE.pending = "preview"
        STATE.error = None
        _supersede()
        STATE.status = "waiting for the settings to settle"
        _ensure_timer()
    except Exception as ex:  # an update callback must not break the UI
        print(f"[skymodel] live update: {type(ex).__name__}: {ex}")


def on_toggle(settings, context=None):
    """*Live Update* switched: on builds the current settings; off stops (a running build is cancelled)."""
    if settings.live_update:
        on_change(settings, context)
    else:
        stop()


def _supersede():
    """A running build of the chosen quality for older settings: cancel it and set it aside
    (its thread ends by itself). A running preview goes on (shown if nothing newer is)."""
    job = STATE.job
    if job is not None and job.running and job.generation != STATE.generation and job.stage == "final":
        if not job.cancelled.is_set():
            job.cancel()
            STATE.builds["cancelled"] += 1
        STATE.cancelled_jobs.append(job)
        STATE.job = None


def stop(wait: float | None = None):
    """Cancel the live builds (if any) and forget what was pending; ``wait`` seconds for
    their threads to end (None: do not wait). Returns True when no live thread runs any more."""
    STATE.pending = None
    STATE.status = ""
    job = STATE.job
    if job is not None and job.running:
        if not job.cancelled.is_set():
            job.cancel()
            STATE.builds["cancelled"] += 1
        STATE.cancelled_jobs.append(job)
        STATE.job = None
    if wait:
        deadline = time.monotonic() + wait
        for j in STATE.cancelled_jobs:
            j.wait(max(0.0, deadline - time.monotonic()))
    return not running()


def running() -> bool:
    """Whether a live build's thread (current or cancelled) is still computing."""
    return any(j is not None and j.running for j in [STATE.job, *STATE.cancelled_jobs])


# --------------------------------------------------------------------------- the timer


class LiveJob:
    """A background build of one stage for one generation of the settings."""

    def __init__(self, ctx, settings, stage: str, generation: int):
        from . import ops

        self.stage = stage
        self.generation = generation
        params = stage_params(settings.to_params(), stage)
        self.job = ops.BuildJob(ctx, settings, params=params, live_stage=stage)

    @property
    def running(self):
        return self.job.running

    @property
    def cancelled(self):
        return self.job.cancelled

    def cancel(self):
        self.job.cancel()

    def wait(self, timeout=None):
        return self.job.wait(timeout)

    def start(self):
        self.job.start()
        return self


def _context(scene):
    return SimpleNamespace(scene=scene, window_manager=None)


def _order(shown: tuple) -> tuple:
    """Sort key of a (generation, stage): newer settings first, then the chosen quality over the preview."""
    return shown[0], 1 if shown[1] == "final" else 0


def _finish(job: LiveJob, scene, settings, now: float):
    """Main thread: apply a finished job: the chosen quality only for the current settings,
    a preview unless a newer sky is shown; else drop it."""
    if job.cancelled.is_set():
        return
    current = job.generation == STATE.generation
    newer_shown = STATE.shown is not None and _order(STATE.shown) >= _order((job.generation, job.stage))
    if (not current and job.stage == "final") or newer_shown:  # never an older sky after a newer one
        STATE.builds["dropped"] += 1
        return
    if blocked_reason(scene, settings):  # the mode changed or a bake came in meanwhile
        STATE.builds["dropped"] += 1
        return
    try:
        result = job.job.finish(_context(scene), settings)
    except BaseException as ex:  # the scene was rolled back by the transaction
        from .ops import BuildCancelled

        if isinstance(ex, BuildCancelled):
            return
        if not current:  # values already changed again: the newer build will say what is wrong
            return
        if not isinstance(ex, SkymodelInputError):
            traceback.print_exception(type(ex), ex, ex.__traceback__)
        STATE.error = str(ex) if isinstance(ex, SkymodelInputError) else f"{type(ex).__name__}: {ex}"
        STATE.pending = None
        STATE.status = ""
        return
    STATE.builds[job.stage] += 1
    final_needed = job.stage == "preview" and not final_is_preview(settings.to_params())
    # a preview of the panel's own quality and width is its final sky
    STATE.shown = (job.generation, "final" if current and job.stage == "preview" and not final_needed
                   else job.stage)
    STATE.history.append(STATE.shown)
    if not current:  # a preview of a drag's earlier values; the current values' preview is pending
        STATE.status = "preview of the values of a moment ago shown; following the changes"
        _redraw()
        return
    STATE.latency[job.stage] = now - STATE.changed_at
    if STATE.shown[1] == "final":
        STATE.latency["final"] = STATE.latency[job.stage]
    STATE.pending = "final" if final_needed else None
    STATE.status = (f"{job.stage} shown {STATE.latency[job.stage]:.1f} s after the last change"
                    + (" (cached image)" if result.cache_hit else ""))
    _redraw()


def tick(now: float | None = None) -> float | None:
    """One step of the live update (the timer's body; call it directly headless). Returns
    the seconds until the next step, or None when idle (the timer then ends)."""
    now = clock() if now is None else now
    scene = bpy.data.scenes.get(STATE.scene)
    world = bpy.data.worlds.get(STATE.world)
    settings = _settings_of(world)
    STATE.cancelled_jobs = [j for j in STATE.cancelled_jobs if j.running]
    _supersede()
    job = STATE.job
    if job is not None:
        if job.running:
            return POLL_S
        STATE.job = None
        if scene is not None and settings is not None:
            _finish(job, scene, settings, now)
    if STATE.pending is None or scene is None or settings is None:
        return POLL_S if STATE.cancelled_jobs else None
    if not settings.live_update:
        STATE.pending = None
        return None
    reason = blocked_reason(scene, settings)
    if reason:
        STATE.status = f"paused: {reason}"
        STATE.pending = None
        return None
    from . import ops

    if ops.JOB is not None and ops.JOB.running:  # Build Sky's own build: wait for it
        return POLL_S
    if len(STATE.cancelled_jobs) > MAX_CANCELLED_RUNNING:  # enough cancelled threads still busy: wait
        return POLL_S
    quiet = now - STATE.changed_at
    if STATE.pending == "preview":  # still for DEBOUNCE_S, or a drag going on for DRAG_REFRESH_S
        ready = quiet >= DEBOUNCE_S or now - STATE.pending_since >= DRAG_REFRESH_S
    else:
        ready = quiet >= SETTLE_S
    if not ready:
        return POLL_S
    stage = STATE.pending  # a preview of the panel's own quality stays a "preview": a drag does not cancel it
    try:
        STATE.job = LiveJob(_context(scene), settings, stage, STATE.generation).start()
    except SkymodelInputError as ex:  # bad input: named before any work; the scene untouched
        STATE.error = str(ex)
        STATE.pending = None
        STATE.status = ""
        return None
    except Exception as ex:
        traceback.print_exception(type(ex), ex, ex.__traceback__)
        STATE.error = f"{type(ex).__name__}: {ex}"
        STATE.pending = None
        return None
    STATE.pending = None
    STATE.status = f"building the {stage} sky"
    _redraw()
    return POLL_S


def _timer():
    try:
        interval = tick()
    except Exception as ex:  # a timer that raises is removed by Blender: keep ours alive
        traceback.print_exception(type(ex), ex, ex.__traceback__)
        interval = None
    if interval is None:
        STATE.timer = False
    return interval


def _ensure_timer():
    try:
        if not bpy.app.timers.is_registered(_timer):
            bpy.app.timers.register(_timer, first_interval=POLL_S)
        STATE.timer = True
    except (AttributeError, ValueError, RuntimeError):
        pass


def _remove_timer():
    try:
        if bpy.app.timers.is_registered(_timer):
            bpy.app.timers.unregister(_timer)
    except (AttributeError, ValueError, RuntimeError):
        pass


def _redraw():
    wm = getattr(bpy.context, "window_manager", None)
    for window in getattr(wm, "windows", ()):
        for area in window.screen.areas:
            if area.type in ("PROPERTIES", "VIEW_3D", "STATUSBAR"):
                area.tag_redraw()


def draw_panel(layout, settings):
    """The Live Update row and its status in the add-on's panel."""
    row = layout.row()
    row.prop(settings, "live_update")
    if not settings.live_update:
        return
    scene = bpy.context.scene
    reason = blocked_reason(scene, settings)
    if reason:
        layout.label(text=f"Live: {reason}", icon="INFO")
    elif STATE.error:
        layout.label(text=f"Live: {STATE.error}", icon="ERROR")
    elif STATE.status:
        layout.label(text=f"Live: {STATE.status}", icon="TIME" if running() or STATE.pending else "CHECKMARK")


@bpy.app.handlers.persistent
def _load_pre(*_args):
    reset()


def register():
    if _load_pre not in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.append(_load_pre)


def unregister():
    reset()
    while _load_pre in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(_load_pre)
