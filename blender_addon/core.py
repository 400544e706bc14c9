"""Where the physics core lives.

Installed as an extension, the add-on carries its own copy of the core as the
sub-package ``<this package>.skymodel`` (``build_extension.py`` vendors it, with the
``presets`` data next to it); run from the repository (tests, ``python -m
blender_addon.render``) it uses the repository's top-level ``skymodel`` package.
Nothing here imports ``bpy``.
"""

from __future__ import annotations

import importlib
import importlib.util


def core_package_name() -> str:
    """``"<package>.skymodel"`` when the vendored copy exists, else ``"skymodel"``."""
    if __package__:
        vendored = __package__ + ".skymodel"
        try:
            if importlib.util.find_spec(vendored) is not None:
                return vendored
        except (ImportError, ValueError):
            pass
    return "skymodel"


def core(submodule: str | None = None):
    """Import the core package, or one of its modules (``core("render.sky")``)."""
    name = core_package_name()
    return importlib.import_module(name if not submodule else f"{name}.{submodule}")


def input_error_class():
    """The core's ``SkymodelInputError`` (the class the add-on reports as bad input)."""
    return core("errors").SkymodelInputError
