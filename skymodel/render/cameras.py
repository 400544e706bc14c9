"""Cameras: maps between image pixels and viewing directions, nothing else.

All directions are unit vectors in the observer's frame of :mod:`skymodel.render.rays`
(x east, y north, z up); azimuth is measured clockwise from north (0 N, 90 E, 180 S,
270 W), the zenith angle from the local vertical. Images are indexed ``[row, column]``
with row 0 at the top, as they are written to PNG/EXR files.

Pixel coordinates (``Camera.project``) are continuous ``(x, y) = (column, row)`` with
pixel *centres at integers*: pixel ``[i, j]`` covers ``x in [j - 0.5, j + 0.5]`` and
``y in [i - 0.5, i + 0.5]``, so ``np.rint(xy).astype(int)`` gives its index.

The cameras
-----------
``equirectangular``
    The full sphere, ``width = 2 * height``. Rows are equal steps in zenith angle: the top
    edge of the image is the zenith, the bottom edge the nadir, the horizon the middle line.
    Columns are equal steps in azimuth, *increasing to the right* (the panorama as seen
    from inside the sphere, like every equirectangular environment map). The vertical
    centre line of the image (``x = (width - 1) / 2``, the edge between the two middle
    columns) looks toward ``center_azimuth_deg``, default 180 (south): for an observer in
    the northern hemisphere the midday sun is then in the middle of the picture, east on
    the left and west on the right. Blender's environment texture puts the image centre on
    its +X axis with the same handedness, so if the Blender scene has x east / y north,
    ``center_azimuth_deg=90`` gives an image Blender maps correctly with no rotation (with
    the default 180, rotate the texture coordinate +90 degrees about Z).
``fisheye``
    An all-sky camera looking straight up: a hemisphere in an equidistant (angular)
    projection, radius on the image proportional to the zenith angle, the zenith at the
    image centre and the horizon on the circle inscribed in the image (radius
    ``min(width, height) / 2``; ``max_zenith_deg`` > 90 extends the circle below the
    horizon). As seen *from below*, like all-sky camera images and the figures of sky
    papers: north at the top, **east on the left**, south at the bottom, west on the right.
    Pixels whose centre lies outside the circle are masked (``valid`` False).
``dome``
    A cylindrical sky dome: azimuth across (full 360 degrees, increasing to the right,
    centre line toward ``center_azimuth_deg`` exactly as for ``equirectangular``), equal
    steps in elevation down the rows, from the zenith at the top edge to the horizon at the
    bottom edge, or ``below_horizon_deg`` degrees below it. The default height keeps the
    pixels square in angle: ``round(width * (90 + below_horizon_deg) / 360)``.

Pixel solid angles
------------------
``pixel_solid_angles()`` gives the solid angle (sr) each pixel sample stands for, so
``sum(L * omega)`` over valid pixels integrates radiance over the field of view. They are
exact for the equirectangular and dome cameras (``dphi * (cos theta1 - cos theta2)``:
sums 4 pi and 2 pi (1 + sin(below_horizon))). For the fisheye each valid pixel gets the
part of the cap inside its square (interior: 3x3 Gauss-Legendre of the Jacobian
``sin(theta) / (theta k^2)``, k pixels per radian; pixels cut by the circle: 32x32
sub-samples), plus the slivers of the cap that fall in masked pixels cut by the circle,
which go to their nearest valid neighbour; the weights are therefore a partition of the
cap and sum to ``2 pi (1 - cos max_zenith)`` to ~1e-6.

Memory guard
------------
:func:`estimate_memory_bytes` estimates what a spectral render of an image needs:
``height * width * n_wavelengths * 8 bytes * MEMORY_FACTOR`` with ``MEMORY_FACTOR = 4``
(the float64 radiance cube that is kept, one cube-sized copy for the output conversions
and writers, and about two cube-sized working arrays of the march; a round estimate, not
a measurement, that assumes the marcher works through the image in tiles so that its
per-step temporaries do not grow with the image). :func:`make_camera` refuses images
whose estimate exceeds ``max_memory_bytes`` (default 4 GiB) with a
:class:`~skymodel.errors.SkymodelInputError` that shows the estimate.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from skymodel.errors import SkymodelInputError
from skymodel.wavelengths import default_wavelengths
from skymodel.render.rays import direction_from_angles

#: Multiplier of the radiance cube size in :func:`estimate_memory_bytes` (see module doc).
MEMORY_FACTOR = 4
#: Default limit of :func:`make_camera` on the estimated memory of a render, bytes.
DEFAULT_MAX_MEMORY_BYTES = 4 * 1024**3
#: Wavelength count assumed when ``make_camera`` is not told (the default 5 nm grid).
DEFAULT_N_WAVELENGTHS = int(default_wavelengths().size)


def _check_positive_int(parameter, value):
    if isinstance(value, bool):
        raise SkymodelInputError(parameter, value, "a positive whole number of pixels")
    if not isinstance(value, numbers.Integral):
        if isinstance(value, numbers.Real) and float(value).is_integer() and value > 0:
            return int(value)
        raise SkymodelInputError(parameter, value, "a positive whole number of pixels")
    if value <= 0:
        raise SkymodelInputError(parameter, value, "a positive whole number of pixels")
    return int(value)


def _check_angle(parameter, value, low, high):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SkymodelInputError(parameter, value, f"an angle in [{low:g}, {high:g}] degrees") from None
    if isinstance(value, bool) or not (low <= v <= high):
        raise SkymodelInputError(parameter, value, f"an angle in [{low:g}, {high:g}] degrees")
    return v


def _format_bytes(n):
    """``n`` bytes in the largest unit that fits, 3 significant digits; a count beyond what a
    float holds (a width of 1e157 px: the memory check refuses it) as its power of ten."""
    n = int(n)
    for unit, size in (("GiB", 1024**3), ("MiB", 1024**2), ("KiB", 1024)):
        if n >= size:
            whole = n // size
            if whole >= 10**15:
                return f"about 10^{len(str(whole)) - 1} {unit}"
            return f"{n / size:.3g} {unit}"
    return f"{n} B"


def estimate_memory_bytes(width, height, n_wavelengths) -> int:
    """Estimated peak memory (bytes) of a spectral render of ``height x width`` pixels at
    ``n_wavelengths`` wavelengths: ``H * W * n_wl * 8 * MEMORY_FACTOR``."""
    w = _check_positive_int("width", width)
    h = _check_positive_int("height", height)
    n = _check_positive_int("n_wavelengths", n_wavelengths)
    return h * w * n * 8 * MEMORY_FACTOR


def _azimuth_deg(d):
    """Azimuth clockwise from north in [0, 360) of directions (..., 3)."""
    return np.mod(np.degrees(np.arctan2(d[..., 0], d[..., 1])), 360.0)


def _zenith_deg(d):
    n = np.linalg.norm(d, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        c = np.clip(d[..., 2] / n, -1.0, 1.0)
    return np.degrees(np.arccos(c))


def _as_directions(directions):
    d = np.asarray(directions, dtype=float)
    if d.ndim < 1 or d.shape[-1] != 3:
        raise SkymodelInputError("directions", f"array of shape {d.shape}", "an array of shape (..., 3)")
    n = np.linalg.norm(d, axis=-1)
    ok = np.isfinite(n) & (n > 0)
    return d, ok


class Camera:
    """Base class: a ``height x width`` image and the viewing direction of each pixel.

    Subclasses define ``name``, ``_directions()``, ``pixel_solid_angles()`` and
    ``project()``. Attributes: ``width``, ``height``, ``shape = (height, width)``,
    ``options`` (the camera-specific keyword options, with defaults filled in)."""

    name = "camera"
    _defaults: dict = {}

    def __init__(self, width, height, **options):
        self.width = _check_positive_int("width", width)
        self.height = _check_positive_int("height", height)
        self.options = dict(self._defaults)
        self.options.update(options)

    @property
    def shape(self):
        return (self.height, self.width)

    def describe(self) -> dict:
        """JSON-friendly description (for metadata): name, width, height, options."""
        return {"camera": self.name, "width": self.width, "height": self.height, **self.options}

    def __repr__(self):
        opts = ", ".join(f"{k}={v!r}" for k, v in self.options.items())
        return f"{type(self).__name__}(width={self.width}, height={self.height}{', ' + opts if opts else ''})"

    def pixel_centres(self):
        """(rows, cols) float arrays (H, W) of pixel-centre coordinates (integers)."""
        return np.meshgrid(np.arange(self.height, dtype=float), np.arange(self.width, dtype=float), indexing="ij")

    def directions(self):
        """``(directions, valid)``: unit vectors (H, W, 3) toward which each pixel centre
        looks and a (H, W) bool mask of the pixels that belong to the image (masked pixels
        hold a unit vector too, but should be rendered black and ignored)."""
        raise NotImplementedError

    def valid_mask(self):
        """The ``valid`` mask of :meth:`directions` (H, W) without the directions (what the
        writers need: a 4096x2048 panorama's directions are 0.2 GiB)."""
        return self.directions()[1]

    def directions_rows(self, start: int, stop: int):
        """``directions()`` of the rows ``start:stop`` only: (stop - start, W, 3) and the mask
        (stop - start, W); the panoramas compute just those rows (the lookup of a large image
        goes by bands of rows and never holds every pixel's direction)."""
        d, valid = self.directions()
        return d[start:stop], valid[start:stop]

    def pixel_solid_angles(self):
        """Solid angle (sr) represented by each pixel, (H, W); 0 where masked."""
        raise NotImplementedError

    def pixels_near(self, zenith_deg: float, angle_deg: float) -> int:
        """How many pixels look within ``angle_deg`` [deg] of a direction at ``zenith_deg``
        [deg] (the memory guard's pixels marched near the sun), without computing any
        pixel's direction. Here a bound: the share 1 - cos(angle) of all pixels, that of a
        hemisphere of equal-area pixels; the panoramas count their rows exactly."""
        return int(math.ceil(self.width * self.height * (1.0 - math.cos(math.radians(float(angle_deg))))))

    def project(self, directions):
        """``(xy, visible)``: continuous pixel coordinates (..., 2) as ``(column, row)``
        with pixel centres at integers, and whether the direction is inside the image
        (NaN coordinates and False for zero or non-finite vectors). Directions need not
        be normalised."""
        raise NotImplementedError


class _PanoramaCamera(Camera):
    """Shared code of the cameras with azimuth across the columns."""

    def _column_azimuths(self):
        c = self.options["center_azimuth_deg"]
        u = (np.arange(self.width) + 0.5) / self.width
        return np.mod(c + (u - 0.5) * 360.0, 360.0)

    def _x_of_azimuth(self, az):
        c = self.options["center_azimuth_deg"]
        u = np.mod((az - c) / 360.0 + 0.5, 1.0)
        return u * self.width - 0.5

    def _row_zeniths(self):
        raise NotImplementedError

    def directions(self):
        zen = self._row_zeniths()
        az = self._column_azimuths()
        d = direction_from_angles(zen[:, None], az[None, :])
        return d, np.ones(self.shape, dtype=bool)

    def directions_rows(self, start: int, stop: int):
        zen = self._row_zeniths()[start:stop]
        d = direction_from_angles(zen[:, None], self._column_azimuths()[None, :])
        return d, np.ones(d.shape[:2], dtype=bool)

    def valid_mask(self):
        return np.ones(self.shape, dtype=bool)

    def pixels_near(self, zenith_deg: float, angle_deg: float) -> int:
        """Pixels within ``angle_deg`` [deg] of a direction at ``zenith_deg`` [deg], row by row:
        a row at zenith z holds those within the azimuth half-width dphi where
        cos z cos zs + sin z sin zs cos dphi = cos(angle), ``width * dphi / pi`` of them (the
        columns span 360 degrees), rounded up."""
        z = np.radians(self._row_zeniths())
        zs, cos_a = math.radians(float(zenith_deg)), math.cos(math.radians(float(angle_deg)))
        near = np.cos(z) * math.cos(zs)
        far = np.sin(z) * math.sin(zs)
        with np.errstate(divide="ignore", invalid="ignore"):
            c = np.where(far > 1e-12, (cos_a - near) / np.where(far > 1e-12, far, 1.0),
                         np.where(near >= cos_a, -1.0, 2.0))
        half = np.arccos(np.clip(c, -1.0, 1.0)) * (c <= 1.0)  # 0 where the row misses the cap
        return int(np.ceil(self.width * half / np.pi).sum())


class EquirectangularCamera(_PanoramaCamera):
    """Full sphere; see the module documentation for the orientation."""

    name = "equirectangular"
    _defaults = {"center_azimuth_deg": 180.0}

    def __init__(self, width, height=None, center_azimuth_deg=180.0):
        w = _check_positive_int("width", width)
        if height is None:
            if w % 2:
                raise SkymodelInputError("width", width, "an even number of pixels (equirectangular: width = 2 x height)")
            height = w // 2
        h = _check_positive_int("height", height)
        if w != 2 * h:
            raise SkymodelInputError("height", height, f"width / 2 = {w / 2:g} (equirectangular images are 2:1)")
        c = _check_angle("center_azimuth_deg", center_azimuth_deg, -360.0, 360.0)
        super().__init__(w, h, center_azimuth_deg=c)

    def _row_zeniths(self):
        return (np.arange(self.height) + 0.5) * (180.0 / self.height)

    def pixel_solid_angles(self):
        edges = np.radians(np.arange(self.height + 1) * (180.0 / self.height))
        band = np.cos(edges[:-1]) - np.cos(edges[1:])
        dphi = 2.0 * np.pi / self.width
        return np.repeat((band * dphi)[:, None], self.width, axis=1)

    def project(self, directions):
        d, ok = _as_directions(directions)
        x = self._x_of_azimuth(_azimuth_deg(d))
        y = _zenith_deg(d) * (self.height / 180.0) - 0.5
        xy = np.stack([x, y], axis=-1)
        xy[~ok] = np.nan
        return xy, ok


class DomeCamera(_PanoramaCamera):
    """Cylindrical sky dome: zenith (top) to the horizon or a little below (bottom)."""

    name = "dome"
    _defaults = {"center_azimuth_deg": 180.0, "below_horizon_deg": 0.0}

    def __init__(self, width, height=None, center_azimuth_deg=180.0, below_horizon_deg=0.0):
        w = _check_positive_int("width", width)
        b = _check_angle("below_horizon_deg", below_horizon_deg, 0.0, 90.0)
        if height is None:
            height = max(1, int(round(w * (90.0 + b) / 360.0)))
        h = _check_positive_int("height", height)
        c = _check_angle("center_azimuth_deg", center_azimuth_deg, -360.0, 360.0)
        super().__init__(w, h, center_azimuth_deg=c, below_horizon_deg=b)

    @property
    def _span_deg(self):
        return 90.0 + self.options["below_horizon_deg"]

    def _row_zeniths(self):
        return (np.arange(self.height) + 0.5) * (self._span_deg / self.height)

    def pixel_solid_angles(self):
        edges = np.radians(np.arange(self.height + 1) * (self._span_deg / self.height))
        band = np.cos(edges[:-1]) - np.cos(edges[1:])
        return np.repeat((band * (2.0 * np.pi / self.width))[:, None], self.width, axis=1)

    def project(self, directions):
        d, ok = _as_directions(directions)
        zen = _zenith_deg(d)
        x = self._x_of_azimuth(_azimuth_deg(d))
        y = zen * (self.height / self._span_deg) - 0.5
        xy = np.stack([x, y], axis=-1)
        xy[~ok] = np.nan
        with np.errstate(invalid="ignore"):
            visible = ok & (zen <= self._span_deg + 1e-9)
        return xy, visible


class FisheyeCamera(Camera):
    """All-sky (equidistant) fisheye seen from below: north up, east left."""

    name = "fisheye"
    _defaults = {"max_zenith_deg": 90.0}
    _EDGE_SUBSAMPLES = 32

    def __init__(self, width, height=None, max_zenith_deg=90.0):
        w = _check_positive_int("width", width)
        h = w if height is None else _check_positive_int("height", height)
        m = _check_angle("max_zenith_deg", max_zenith_deg, 1.0, 180.0)
        super().__init__(w, h, max_zenith_deg=m)

    # geometry: image-centre offsets in pixels, dx to the right, dy up
    @property
    def _radius_px(self):
        return min(self.width, self.height) / 2.0

    @property
    def _centre(self):
        return (self.width - 1) / 2.0, (self.height - 1) / 2.0  # (x, y) in pixel-centre coords

    @property
    def _px_per_rad(self):
        return self._radius_px / math.radians(self.options["max_zenith_deg"])

    def _offsets(self):
        rows, cols = self.pixel_centres()
        cx, cy = self._centre
        return cols - cx, cy - rows

    def _dirs_from_offsets(self, dx, dy):
        r = np.hypot(dx, dy)
        theta = r / self._px_per_rad
        s = np.sin(theta)
        with np.errstate(invalid="ignore", divide="ignore"):
            f = np.where(r > 0, s / np.where(r > 0, r, 1.0), 0.0)
        # north = +dy (up), east = -dx (left)
        return np.stack([-dx * f, dy * f, np.cos(theta)], axis=-1)

    def _valid_from_offsets(self, dx, dy):
        return np.hypot(dx, dy) <= self._radius_px * (1.0 + 1e-12)

    def directions(self):
        dx, dy = self._offsets()
        return self._dirs_from_offsets(dx, dy), self._valid_from_offsets(dx, dy)

    def valid_mask(self):
        return self._valid_from_offsets(*self._offsets())

    def _jacobian(self, r):
        """Solid angle per unit image area (sr / px^2) at radius r (px)."""
        k = self._px_per_rad
        theta = r / k
        with np.errstate(invalid="ignore", divide="ignore"):
            sinc = np.where(theta > 1e-8, np.sin(theta) / np.where(theta > 1e-8, theta, 1.0), 1.0)
        return sinc / (k * k)

    def pixel_solid_angles(self):
        dx, dy = self._offsets()
        R = self._radius_px
        rc = np.hypot(dx, dy)
        half_diag = math.sqrt(0.5)
        omega = np.zeros(self.shape)
        inner = rc + half_diag <= R
        # interior pixels: 3x3 Gauss-Legendre of the smooth Jacobian over the square
        g, gw = np.polynomial.legendre.leggauss(3)
        g, gw = g / 2.0, gw / 2.0
        ix = dx[inner]
        iy = dy[inner]
        acc = np.zeros(ix.shape)
        for a, wa in zip(g, gw):
            for b, wb in zip(g, gw):
                acc += wa * wb * self._jacobian(np.hypot(ix + a, iy + b))
        omega[inner] = acc
        # pixels cut by the circle: n x n sub-samples of Jacobian x inside-indicator
        edge = ~inner & (rc - half_diag <= R)
        n = self._EDGE_SUBSAMPLES
        s = (np.arange(n) + 0.5) / n - 0.5
        sx, sy = np.meshgrid(s, s, indexing="ij")
        sx, sy = sx.ravel(), sy.ravel()
        ei = np.flatnonzero(edge.ravel())
        edx, edy = dx.ravel()[ei], dy.ravel()[ei]
        vals = np.empty(ei.size)
        chunk = 4096
        for k in range(0, ei.size, chunk):
            px = edx[k:k + chunk, None] + sx[None, :]
            py = edy[k:k + chunk, None] + sy[None, :]
            r = np.hypot(px, py)
            vals[k:k + chunk] = np.where(r <= R, self._jacobian(r), 0.0).mean(axis=1)
        omega.ravel()[ei] = vals
        # slivers in masked pixels go to the nearest valid neighbour
        valid = self._valid_from_offsets(dx, dy)
        orphans = np.argwhere(~valid & (omega > 0))
        H, W = self.shape
        offsets = sorted(((di, dj) for di in (-1, 0, 1) for dj in (-1, 0, 1) if di or dj),
                         key=lambda o: abs(o[0]) + abs(o[1]))
        for i, j in orphans:
            best = None
            for di, dj in offsets:
                a, b = i + di, j + dj
                if 0 <= a < H and 0 <= b < W and valid[a, b]:
                    key = (abs(di) + abs(dj), rc[a, b])
                    if best is None or key < best[0]:
                        best = (key, a, b)
            if best is None:  # only in images a few pixels wide
                vi = np.argwhere(valid)
                if vi.size == 0:
                    continue
                d2 = ((vi - [i, j]) ** 2).sum(axis=1)
                a, b = vi[np.argmin(d2)]
                best = (None, a, b)
            omega[best[1], best[2]] += omega[i, j]
            omega[i, j] = 0.0
        return omega

    def project(self, directions):
        d, ok = _as_directions(directions)
        theta = np.radians(_zenith_deg(d))
        az = np.radians(_azimuth_deg(d))
        r = theta * self._px_per_rad
        cx, cy = self._centre
        x = cx - r * np.sin(az)  # east to the left
        y = cy - r * np.cos(az)  # north up (row decreases)
        xy = np.stack([x, y], axis=-1)
        xy[~ok] = np.nan
        with np.errstate(invalid="ignore"):
            visible = ok & (np.degrees(theta) <= self.options["max_zenith_deg"] + 1e-9)
        return xy, visible


#: Known cameras by name.
CAMERAS = {c.name: c for c in (EquirectangularCamera, FisheyeCamera, DomeCamera)}


def make_camera(name, width, height=None, *, n_wavelengths=None, max_memory_bytes=DEFAULT_MAX_MEMORY_BYTES,
                **options) -> Camera:
    """Build a camera by name (``"equirectangular"``, ``"fisheye"``, ``"dome"``,
    case-insensitive).

    ``height`` defaults to ``width // 2`` (equirectangular), ``width`` (fisheye) or the
    square-pixel height (dome). ``options`` are the camera's own keywords
    (``center_azimuth_deg``; ``max_zenith_deg``; ``below_horizon_deg``; see the module
    doc). The render of the image at ``n_wavelengths`` (default: the 5 nm grid, 81) must
    fit in ``max_memory_bytes`` by :func:`estimate_memory_bytes`, otherwise
    :class:`SkymodelInputError` naming ``width`` is raised with the estimate.
    """
    key = str(name).lower() if isinstance(name, str) else name
    if key not in CAMERAS:
        raise SkymodelInputError("camera", name, "one of: " + ", ".join(sorted(CAMERAS)))
    cls = CAMERAS[key]
    unknown = sorted(set(options) - set(cls._defaults))
    if unknown:
        allowed = ", ".join(sorted(cls._defaults)) or "none"
        raise SkymodelInputError(unknown[0], options[unknown[0]], f"an option of the {key} camera ({allowed})")
    cam = cls(width, height, **options)
    n_wl = DEFAULT_N_WAVELENGTHS if n_wavelengths is None else _check_positive_int("n_wavelengths", n_wavelengths)
    try:
        limit = float(max_memory_bytes)
    except (TypeError, ValueError):
        limit = float("nan")
    if not limit > 0:
        raise SkymodelInputError("max_memory_bytes", max_memory_bytes, "a positive number of bytes")
    est = estimate_memory_bytes(cam.width, cam.height, n_wl)
    if est > limit:
        raise SkymodelInputError(
            "width", width,
            f"a smaller image: {cam.width}x{cam.height} px x {n_wl} wavelengths needs an estimated "
            f"{_format_bytes(est)} ({est} bytes = H*W*n_wl*8*{MEMORY_FACTOR}), over the limit of "
            f"{_format_bytes(int(limit))} (max_memory_bytes)")
    return cam
