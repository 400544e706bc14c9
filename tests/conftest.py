"""Fixtures shared by the add-on test files (bpy, headless). ``bpy`` is imported only when
a fixture runs, so the core's tests never need it."""

import os
import tempfile

import pytest

# before any test module imports bpy: keep Blender's user folders and the add-on's sky cache
# out of $HOME (a test module may still set its own first)
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
