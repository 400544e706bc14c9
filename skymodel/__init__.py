"""skymodel — a physically based, spectral sky and atmosphere.

The physics core: per-height optical properties of the atmosphere from month, location
and aerosol type (:class:`Atmosphere`, :class:`OpticalProfile`), the sun, colour, and a
numpy-only spectral renderer. Nothing here imports ``bpy``.
"""

from skymodel.errors import SkymodelInputError
from skymodel.optics.profile import LayeredProfile, OpticalProfile
from skymodel.wavelengths import as_wavelengths, default_wavelengths

__version__ = "0.1.0"


def __getattr__(name):  # lazy: Atmosphere pulls in every data table
    if name == "Atmosphere":
        from skymodel.optics.atmosphere import Atmosphere

        return Atmosphere
    raise AttributeError(name)


__all__ = ["Atmosphere", "OpticalProfile", "LayeredProfile", "SkymodelInputError", "as_wavelengths",
           "default_wavelengths"]
