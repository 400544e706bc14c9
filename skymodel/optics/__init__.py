"""Optics: what the air holds at each height and how it scatters and absorbs light.

The U.S. Standard Atmosphere, Rayleigh scattering, ozone absorption, aerosol types and
their Mie optics (and the Mie lookup), Legendre moments and phase-function fits, ground
albedo, and :class:`~skymodel.optics.profile.OpticalProfile`, the per-height coefficients
(per metre) on a wavelength grid (nanometres) that every renderer consumes.
:class:`~skymodel.optics.atmosphere.Atmosphere` composes them from a month, a place and an
aerosol type. May import: the base modules (``skymodel.errors``, ``numerics``,
``geometry``, ``wavelengths``, ``sun``, ``scene``) and ``skymodel.data``; never ``render``
or anything above it.
"""
