"""skymodel for Blender: a physically based, spectral sky (world environment, sun lamp,
and layered atmosphere volumes for Cycles), computed by the ``skymodel`` physics core.

Extension-style add-on (no ``bl_info``; the manifest is ``blender_manifest.toml``).
Settings live on ``World.skymodel``; the panels are in World properties and in the 3D
view sidebar ("Sky" tab). See ``docs/blender.md``.

The modules that need ``bpy`` (props, ops, ui, builder, render, animation, live: the
Live Update; sunpath: the sun's path in the viewport) are imported by
:func:`register`, so ``blender_addon.physics`` / ``blender_addon.volumetric`` (the
computations) can be used and tested without Blender.
"""


def _modules():
    from . import animation, live, ops, props, ui

    return (props, ops, animation, live, ui)


def register():
    for m in _modules():
        m.register()


def unregister():
    for m in reversed(_modules()):
        m.unregister()
