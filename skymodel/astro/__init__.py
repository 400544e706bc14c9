"""The sky beyond the sun: the moon, its light, the stars and the natural night-sky glow.

Modules
    :mod:`~skymodel.astro.moon`
        the moon's topocentric place, distance, disc size and phase (Meeus ch. 47).
    :mod:`~skymodel.astro.lunar_irradiance`
        the moon's spectral irradiance above the atmosphere, from the ROLO model of Kieffer
        & Stone (2005) times the solar spectrum of :mod:`skymodel.sun`.
    :mod:`~skymodel.astro.stars`
        a catalogue of the naked-eye stars (Hipparcos/XHIP, V <= 6.5), placed for a date,
        time and place; their spectra from B-V; splatted into an equirectangular image as
        point sources that keep their irradiance.
    :mod:`~skymodel.astro.night_background`
        the diffuse natural night sky (airglow, zodiacal light and unresolved starlight) of a
        dark site, from published broad-band surface brightnesses.
    :mod:`~skymodel.astro.night_sky`
        the three together in one equirectangular radiance image for a place and time (stars
        and the moon as point sources, the glow per row), dimmed by the caller's direct
        transmittance: the one call a renderer needs besides its own moonlit sky.

What it may import: the base modules (:mod:`skymodel.errors`, :mod:`skymodel.wavelengths`,
:mod:`skymodel.numerics`, :mod:`skymodel.sun`, :mod:`skymodel.colorimetry`,
:mod:`skymodel.scene`) and :mod:`skymodel.data`; never the optics, the renderer or
anything above them (the ``wings`` contract of ``[tool.importlinter]``). The renderer and
the add-on may import it: it sits beside :mod:`skymodel.optics`, as a source of light for
the atmosphere rather than a part of it.
"""
