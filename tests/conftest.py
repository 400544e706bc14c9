"""Fixtures shared by the add-on test files (bpy, headless). ``bpy`` is imported only when
a fixture runs, so the core's tests never need it."""

import os
import tempfile

import pytest

# before any test module imports bpy: keep Blender's user folders and the add-on's sky cache
# out of $HOME (pytest imports this file before it collects the test modules; they rely on it)
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="skymodel-blender-user-"))
os.environ.setdefault("SKYMODEL_CACHE_DIR", tempfile.mkdtemp(prefix="skymodel-cache-"))


@pytest.fixture(scope="module")
def addon():
    """The add-on, registered for the module (and unregistered after it if still there)."""
    bpy = pytest.importorskip("bpy")
    import blender_addon

    if not hasattr(bpy.types.World, "skymodel"):
        blender_addon.register()
    yield blender_addon
    if hasattr(bpy.types.World, "skymodel"):
        blender_addon.unregister()


@pytest.fixture
def new_sky_scene(addon):
    """Factory: an empty file whose scene has a new world with the add-on's settings set
    for tiny, fast builds (``image_width`` px, ``quality``, at ``location``)."""
    import bpy

    def make(image_width=64, quality="preview", location="rural"):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        if not hasattr(bpy.types.World, "skymodel"):
            addon.register()
        sc = bpy.context.scene
        sc.world = bpy.data.worlds.new("World")
        s = sc.world.skymodel
        s.location = location
        s.image_width = image_width
        s.quality = quality
        return sc

    return make


@pytest.fixture
def small_preview(monkeypatch):
    """The ``preview`` preset with small tables, for the duration of a test: builds in seconds
    (what those tests check does not depend on the tables' size)."""
    from dataclasses import replace

    from skymodel.render.quality import QUALITIES

    q = QUALITIES["preview"]
    small = replace(q.settings, table_altitudes=10, table_mu=12, table_phi=6, table_mus=10, table_steps=16,
                    sun_table_altitudes=24, sun_table_x=32, sun_table_steps=32, grid_zenith=16,
                    grid_zenith_ground=6, grid_azimuth=9, max_orders=4)
    monkeypatch.setitem(QUALITIES, "preview", replace(q, settings=small))


class RecordingLayout:
    """Stands in for a UI layout: records every property and label the panel draws, and
    checks each drawn property exists on its data."""

    def __init__(self, log):
        self.log = log
        self.use_property_split = self.use_property_decorate = False
        self.active = self.enabled = True
        self.scale_y = 1.0

    def _child(self, *args, **kwargs):
        return RecordingLayout(self.log)

    column = row = box = split = _child

    def prop(self, data, name, **kwargs):
        assert hasattr(data, name), name
        self.log.append(("prop", name))

    def label(self, text="", **kwargs):
        self.log.append(("label", text))

    def operator(self, idname, **kwargs):
        self.log.append(("operator", idname))
        return type("Props", (), {})()

    def template_ID(self, *args, **kwargs):
        self.log.append(("template", args[1] if len(args) > 1 else ""))

    def separator(self, *args, **kwargs):
        pass


@pytest.fixture
def recording_layout():
    """The class of :class:`RecordingLayout` (panels cannot be drawn without a window)."""
    return RecordingLayout


# ---------------------------------------------------------------------------- no module skipped whole
# CI (.ci/run) sets SKYMODEL_NO_SKIPPED_MODULES=1: every optional dependency is installed there
# (the test, blender, plots and oracles extras), so a test module whose tests were all skipped,
# or that was skipped at import (pytest.importorskip at module level), hides a broken install
# and fails the run. Locally (unset) skips stay skips, listed by -ra.
_MODULE_OUTCOMES: dict[str, set] = {}
_SKIPPED_AT_IMPORT: dict[str, str] = {}


def _module_of(nodeid: str) -> str:
    return nodeid.split("::", 1)[0]


def pytest_collectreport(report):
    if report.skipped and report.nodeid.endswith(".py"):
        reason = report.longrepr[-1] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        _SKIPPED_AT_IMPORT[report.nodeid] = str(reason)


def pytest_runtest_logreport(report):
    outcomes = _MODULE_OUTCOMES.setdefault(_module_of(report.nodeid), set())
    if report.when == "call" or (report.when == "setup" and not report.passed):
        outcomes.add("skipped" if report.skipped else "ran")


def wholly_skipped_modules() -> dict:
    """Test modules none of whose tests ran: ``{module: reason}``."""
    out = dict(_SKIPPED_AT_IMPORT)
    for module, outcomes in _MODULE_OUTCOMES.items():
        if outcomes == {"skipped"}:
            out.setdefault(module, "every test in it was skipped")
    return out


def pytest_sessionfinish(session, exitstatus):
    if os.environ.get("SKYMODEL_NO_SKIPPED_MODULES") != "1" or exitstatus not in (0, 1):
        return
    if hasattr(session.config, "workerinput"):
        return  # an xdist worker sees part of a module; the controller decides
    if session.config.option.collectonly or getattr(session.config.option, "keyword", "") or \
            getattr(session.config.option, "markexpr", ""):
        return  # a selection (-k / -m) skips by design
    skipped = wholly_skipped_modules()
    if skipped:
        reporter = session.config.pluginmanager.get_plugin("terminalreporter")
        for module, why in sorted(skipped.items()):
            line = f"SKYMODEL_NO_SKIPPED_MODULES: {module} was skipped whole: {why}"
            if reporter is not None:
                reporter.write_line(line, red=True)
            else:
                print(line)
        session.exitstatus = 1
