"""Image output with no dependency beyond numpy and the standard library.

* :func:`write_exr` writes a scanline OpenEXR file (spec: "OpenEXR File Layout"): magic
  number 20000630, version 2, a header with the required attributes (``channels``,
  ``compression``, ``dataWindow``, ``displayWindow``, ``lineOrder``,
  ``pixelAspectRatio``, ``screenWindowCenter``, ``screenWindowWidth``) plus optional
  ``chromaticities`` and string attributes, the line offset table and the scanline
  blocks, channels in alphabetical order inside each line. Pixels are float32 (or half
  on request). Compression: ``"none"`` (1 line per block), ``"zips"`` (1 line) or
  ``"zip"`` (16 lines, the default), both zlib after OpenEXR's byte interleaving and
  delta predictor; a block whose compressed form is not smaller is stored raw, as the
  format requires.
* :func:`write_png` writes 8-bit grey/RGB/RGBA PNG (filter 0, zlib, with ``sRGB``,
  ``gAMA`` and ``cHRM`` chunks since :func:`tonemap` produces sRGB).
* :func:`tonemap` turns scene-linear Rec.709 into 8-bit sRGB for previews.
* :func:`write_spectral_npz` stores the spectral radiance cube with its geometry.
* :func:`save_outputs` writes any of EXR / PNG / NPZ from a render after validating
  every argument first.

Every writer is atomic: the data go to a temporary file in the destination folder which
is renamed over the destination only once complete, so a failure (a full disk, an
interrupt) leaves no partial file (and no temporary file) behind, and the previous file
of that name, if any, stays whole. :func:`check_output_path` creates and removes a probe
file, so a read-only folder is found before a long render. Bad arguments raise
:class:`~skymodel.errors.SkymodelInputError` naming the parameter, before anything is
created.
"""

from __future__ import annotations

import json
import math
import os
import secrets
import struct
import threading
import zlib
from collections.abc import Mapping

import numpy as np

from skymodel import scene
from skymodel.errors import SkymodelInputError
from skymodel.render.threads import SOLVER_THREADS, in_threads

__all__ = ["write_exr", "write_png", "tonemap", "write_spectral_npz", "save_outputs", "luminance_rec709",
           "srgb_oetf", "auto_exposure_luminance", "check_output_path", "CHROMATICITIES"]

# ----------------------------------------------------------------------------- files


def _check_output_path(parameter, path, extensions):
    """Validate an output path: a str/PathLike with one of ``extensions`` (lower case,
    with the dot), in an existing folder, not itself a folder. Returns ``str`` path."""
    try:
        p = os.fspath(path)
    except TypeError:
        raise SkymodelInputError(parameter, path, "a file path") from None
    if isinstance(p, bytes):
        p = os.fsdecode(p)
    ext = os.path.splitext(p)[1].lower()
    if ext not in extensions:
        raise SkymodelInputError(parameter, p, "a file name ending in " + " or ".join(extensions))
    folder = os.path.dirname(os.path.abspath(p))
    if not os.path.isdir(folder):
        raise SkymodelInputError(parameter, p, f"a file in an existing folder ({folder!r} does not exist)")
    if os.path.isdir(p):
        raise SkymodelInputError(parameter, p, "a file path, not a folder")
    _check_writable(parameter, p, folder)
    return p


def _check_writable(parameter, path, folder):
    """Create and remove a probe file in ``folder`` (what the atomic writer will do), so a
    read-only folder or file system is reported before a long render, naming ``parameter``.
    A probe, not ``os.access``: root passes ``os.access`` on a read-only mount."""
    probe = os.path.join(folder, f".{os.path.basename(path)}.{secrets.token_hex(6)}.probe")
    try:
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except OSError as e:
        raise SkymodelInputError(parameter, path, f"a file in a writable folder ({folder!r}: "
                                                  f"{e.strerror or e})") from None
    os.close(fd)
    _remove_quietly(probe)


#: Public name of the path check (callers validate output paths before a long render).
check_output_path = _check_output_path


def _write_temp(path, write_fn):
    """Write through ``write_fn(fileobj)`` to a new temporary file next to ``path`` and
    return its name; on any failure the temporary file is removed and the error re-raised."""
    folder, name = os.path.split(os.path.abspath(path))
    tmp = os.path.join(folder, f".{name}.{secrets.token_hex(6)}.tmp")
    # os.open with 0o666 honours the umask, so the final file gets ordinary permissions
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
    try:
        with os.fdopen(fd, "wb") as f:
            write_fn(f)
            f.flush()
            os.fsync(f.fileno())
    except BaseException:
        _remove_quietly(tmp)
        raise
    return tmp


def _remove_quietly(path):
    try:
        os.unlink(path)
    except OSError:
        pass


def _atomic_write(path, write_fn):
    tmp = _write_temp(path, write_fn)
    try:
        os.replace(tmp, path)
    except BaseException:
        _remove_quietly(tmp)
        raise


def _atomic_write_many(jobs):
    """``jobs``: list of (path, write_fn). All are written to temporary files first and
    renamed only when every one succeeded."""
    temps = []
    try:
        for path, fn in jobs:
            temps.append((_write_temp(path, fn), path))
        for tmp, path in temps:
            os.replace(tmp, path)
    except BaseException:
        for tmp, _ in temps:
            _remove_quietly(tmp)
        raise


# ----------------------------------------------------------------------------- EXR

_EXR_MAGIC = 20000630
_EXR_COMPRESSION = {"none": (0, 1), "zips": (2, 1), "zip": (3, 16)}  # code, scanlines per block
_HALF_MAX = 65504.0
_REQUIRED_ATTRIBUTES = {"channels", "compression", "dataWindow", "displayWindow", "lineOrder",
                        "pixelAspectRatio", "screenWindowCenter", "screenWindowWidth", "chromaticities"}

#: CIE xy chromaticities (red, green, blue, white) written in the EXR ``chromaticities``
#: attribute for each RGB working space.
CHROMATICITIES = {
    "rec709": ((0.64, 0.33), (0.30, 0.60), (0.15, 0.06), (0.3127, 0.3290)),
    "acescg": ((0.713, 0.293), (0.165, 0.830), (0.128, 0.044), (0.32168, 0.33767)),
}


def _attr(name, type_name, payload):
    return name.encode("ascii") + b"\0" + type_name.encode("ascii") + b"\0" + struct.pack("<i", len(payload)) + payload


def _exr_channels_and_data(rgb_or_channels, channels):
    """Normalise the input to (sorted names, [(H, W) planes in that order], common dtype).

    The planes are views of the caller's arrays (no copy); the common dtype is what
    stacking them would give, so every plane is converted as if stacked first."""
    if isinstance(rgb_or_channels, Mapping):
        names = [str(k) for k in rgb_or_channels]
        planes = []
        for k in rgb_or_channels:
            a = np.asarray(rgb_or_channels[k])
            if a.ndim != 2:
                raise SkymodelInputError("rgb_or_channels", f"channel {k!r} of shape {a.shape}", "2-D (H, W) planes")
            planes.append(a)
        if not planes:
            raise SkymodelInputError("rgb_or_channels", "{}", "at least one channel")
        if len({p.shape for p in planes}) != 1:
            raise SkymodelInputError("rgb_or_channels", [p.shape for p in planes], "planes of one shape")
        dtype = np.result_type(*planes)
        shape = planes[0].shape + (len(planes),)
    else:
        data = np.asarray(rgb_or_channels)
        if isinstance(channels, str):
            channels = (channels,)
        names = [str(c) for c in channels]
        if data.ndim == 2:
            data = data[:, :, None]
        if data.ndim != 3 or data.shape[2] != len(names):
            raise SkymodelInputError(
                "rgb_or_channels", f"array of shape {data.shape}",
                f"an (H, W, {len(names)}) array matching channels={tuple(names)}")
        planes = [data[:, :, i] for i in range(data.shape[2])]
        dtype, shape = data.dtype, data.shape
    if dtype.kind not in "fiu" or dtype == np.bool_:
        raise SkymodelInputError("rgb_or_channels", f"dtype {dtype}", "real numbers")
    if shape[0] == 0 or shape[1] == 0:
        raise SkymodelInputError("rgb_or_channels", f"array of shape {shape}", "at least one pixel")
    for n in names:
        if not n or len(n.encode("utf-8", "replace")) > 31 or not n.isascii() or not n.isprintable():
            raise SkymodelInputError("channels", n, "names of 1..31 printable ASCII characters")
    if len(set(names)) != len(names):
        raise SkymodelInputError("channels", tuple(names), "distinct channel names")
    order = sorted(range(len(names)), key=lambda i: names[i].encode("ascii"))
    return [names[i] for i in order], [planes[i] for i in order], dtype


#: Values (pixels x channels) the writers convert at once: they work through an image by
#: bands of rows, so what they add to a render's peak memory does not grow with the image
#: beyond one float32 (or half) copy for the EXR, the luminance and the 8-bit PNG rows.
BAND_VALUES = 1 << 19


def _row_bands(height, values_per_row):
    """``range`` starts and the band height: rows in bands of about :data:`BAND_VALUES` values."""
    rows = max(1, BAND_VALUES // max(int(values_per_row), 1))
    return range(0, int(height), rows), rows


def _plane_rows(plane, dtype, r0, r1):
    """Rows ``r0:r1`` of ``plane`` in ``dtype`` (a view when it already has it)."""
    part = plane[r0:r1]
    return part if part.dtype == dtype else part.astype(dtype)


class _ExrValueCheck:
    """The EXR's value checks, accumulated over bands of rows: every value finite, and
    within +-65504 for half floats or the float32 range for float64 input."""

    def __init__(self, dtype, half):
        self.dtype, self.half = np.dtype(dtype), bool(half)
        self.nonfinite = 0
        self.max_abs = 0.0
        self._lock = threading.Lock()  # bands may be added from several threads

    def add(self, block):
        fin = np.isfinite(block)
        bad = 0 if fin.all() else int((~fin).sum())
        top = float(np.abs(block).max()) if block.size and not bad else 0.0
        with self._lock:
            self.nonfinite += bad
            self.max_abs = max(self.max_abs, top)

    def raise_if_bad(self):
        if self.nonfinite:
            raise SkymodelInputError("rgb_or_channels", f"{self.nonfinite} non-finite values", "finite pixel values")
        if self.half:
            if self.max_abs > _HALF_MAX:
                raise SkymodelInputError(
                    "half", True, f"values within +-{_HALF_MAX:g} for half floats (max |value| is "
                    f"{self.max_abs:.4g}); scale the image or write float32")
        elif self.dtype.kind == "f" and self.dtype.itemsize > 4 and self.max_abs > np.finfo(np.float32).max:
            raise SkymodelInputError("rgb_or_channels", self.max_abs, "values within the float32 range")


def _zip_pack(raw: bytes, level: int) -> bytes:
    """OpenEXR ZIP/ZIPS block: interleave even/odd bytes, delta predictor, zlib.
    Returns ``raw`` unchanged when compression does not make it smaller."""
    b = np.frombuffer(raw, dtype=np.uint8)
    t = np.concatenate([b[0::2], b[1::2]])
    d = t.copy()
    d[1:] = t[1:] - t[:-1] + np.uint8(128)  # uint8 arithmetic wraps modulo 256
    packed = zlib.compress(d.tobytes(), level)
    return packed if len(packed) < len(raw) else raw


def _exr_bytes_writer(names, planes, dtype, half, compression, chromaticities, attributes, zip_level):
    H, W = planes[0].shape
    C = len(planes)
    code, lines = _EXR_COMPRESSION[compression]
    pixel_type = 1 if half else 2
    file_dtype = np.dtype("<f2" if half else "<f4")

    chlist = b"".join(n.encode("ascii") + b"\0" + struct.pack("<iB3xii", pixel_type, 0, 1, 1) for n in names) + b"\0"
    box = struct.pack("<iiii", 0, 0, W - 1, H - 1)
    header = [_attr("channels", "chlist", chlist)]
    if chromaticities is not None:
        header.append(_attr("chromaticities", "chromaticities",
                            struct.pack("<8f", *[v for xy in chromaticities for v in xy])))
    header += [
        _attr("compression", "compression", struct.pack("<B", code)),
        _attr("dataWindow", "box2i", box),
        _attr("displayWindow", "box2i", box),
        _attr("lineOrder", "lineOrder", struct.pack("<B", 0)),  # INCREASING_Y
        _attr("pixelAspectRatio", "float", struct.pack("<f", 1.0)),
        _attr("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0)),
        _attr("screenWindowWidth", "float", struct.pack("<f", 1.0)),
    ]
    for k, v in sorted(attributes.items()):
        header.append(_attr(k, "string", v))
    head = struct.pack("<ii", _EXR_MAGIC, 2) + b"".join(header) + b"\0"
    n_chunks = -(-H // lines)

    def write(f):
        f.write(head)
        table_pos = len(head)
        f.write(b"\0" * (8 * n_chunks))
        offsets = []
        pos = table_pos + 8 * n_chunks

        def payload(k):
            y0 = k * lines
            y1 = min(y0 + lines, H)
            block = np.empty((y1 - y0, C, W), dtype=file_dtype)  # per line: channels (sorted), each W values
            for i, plane in enumerate(planes):
                block[:, i, :] = _plane_rows(plane, dtype, y0, y1)  # the cast of the whole image, by lines
            raw = block.tobytes()
            return raw if code == 0 else _zip_pack(raw, zip_level)

        # the chunks compressed on the solver's threads (zlib and numpy release the GIL; 4096x2048
        # RGB: 1.4 s of zlib on one core), written in order; a group at a time bounds the memory
        group = 64 * max(1, SOLVER_THREADS)
        for g0 in range(0, n_chunks, group):
            ks = range(g0, min(g0 + group, n_chunks))
            for k, payload_k in zip(ks, in_threads(payload, ks, SOLVER_THREADS)):
                f.write(struct.pack("<ii", k * lines, len(payload_k)))
                f.write(payload_k)
                offsets.append(pos)
                pos += 8 + len(payload_k)
        f.seek(table_pos)
        f.write(struct.pack(f"<{n_chunks}Q", *offsets))
        f.seek(0, os.SEEK_END)

    return write


def _prepare_exr(path, rgb_or_channels, channels, half, compression, chromaticities, attributes, zip_level,
                 parameter="path"):
    p = _check_output_path(parameter, path, (".exr",))
    names, planes, dtype = _exr_channels_and_data(rgb_or_channels, channels)
    comp = str(compression).lower()
    if comp not in _EXR_COMPRESSION:
        raise SkymodelInputError("compression", compression, "one of: " + ", ".join(_EXR_COMPRESSION))
    check = _ExrValueCheck(dtype, half)
    starts, rows = _row_bands(planes[0].shape[0], planes[0].shape[1])
    for plane in planes:
        for r0 in starts:
            check.add(_plane_rows(plane, dtype, r0, r0 + rows))
    check.raise_if_bad()
    if chromaticities is not None:
        try:
            chroma = tuple(tuple(float(v) for v in xy) for xy in chromaticities)
            ok = len(chroma) == 4 and all(len(xy) == 2 and all(math.isfinite(v) for v in xy) for xy in chroma)
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise SkymodelInputError("chromaticities", chromaticities, "four (x, y) pairs: red, green, blue, white")
        chromaticities = chroma
    attrs = {}
    for k, v in (attributes or {}).items():
        if not isinstance(k, str) or not k or not k.isascii() or len(k) > 31 or k in _REQUIRED_ATTRIBUTES:
            raise SkymodelInputError("attributes", k, "names of 1..31 ASCII characters other than the standard ones")
        attrs[k] = str(v).encode("utf-8")
    try:
        level = int(zip_level)
    except (TypeError, ValueError):
        level = -2
    if not 0 <= level <= 9:
        raise SkymodelInputError("zip_level", zip_level, "an integer 0..9")
    return p, _exr_bytes_writer(names, planes, dtype, bool(half), comp, chromaticities, attrs, level)


def write_exr(path, rgb_or_channels, channels=("R", "G", "B"), half=False, *, compression="zip",
              chromaticities=None, attributes=None, zip_level=4):
    """Write a scanline OpenEXR file atomically.

    ``rgb_or_channels``: an (H, W, C) array whose last axis matches ``channels`` (an
    (H, W) array for a single channel), or a mapping ``{name: (H, W) array}``. Row 0 is
    the top of the image. Values must be finite (and within +-65504 when ``half``).
    ``compression``: ``"zip"`` (default), ``"zips"`` or ``"none"``. ``chromaticities``:
    optional ((xr, yr), (xg, yg), (xb, yb), (xw, yw)), e.g. ``CHROMATICITIES["rec709"]``.
    ``attributes``: optional extra header attributes written as strings.
    Returns the path written.
    """
    p, writer = _prepare_exr(path, rgb_or_channels, channels, half, compression, chromaticities, attributes,
                             zip_level)
    _atomic_write(p, writer)
    return p


# ----------------------------------------------------------------------------- PNG

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def _prepare_png(path, rgb8, text, parameter="path"):
    p = _check_output_path(parameter, path, (".png",))
    a = np.asarray(rgb8)
    if a.dtype != np.uint8:
        raise SkymodelInputError("rgb8", f"dtype {a.dtype}", "uint8 values (use tonemap() for linear images)")
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[2] not in (1, 3, 4) or a.shape[0] == 0 or a.shape[1] == 0:
        raise SkymodelInputError("rgb8", f"array of shape {np.shape(rgb8)}", "an (H, W), (H, W, 3) or (H, W, 4) array")
    if a.shape[0] >= 2**31 or a.shape[1] >= 2**31:
        raise SkymodelInputError("rgb8", f"array of shape {a.shape}", "fewer than 2**31 rows and columns")
    chunks_text = []
    for k, v in (text or {}).items():
        try:
            kb = str(k).encode("latin-1")
            vb = str(v).encode("latin-1")
        except UnicodeEncodeError:
            raise SkymodelInputError("text", k, "Latin-1 keywords and values") from None
        if not 1 <= len(kb) <= 79 or b"\0" in kb or b"\0" in vb:
            raise SkymodelInputError("text", k, "keywords of 1..79 characters without NUL")
        chunks_text.append(_png_chunk(b"tEXt", kb + b"\0" + vb))
    H, W, C = a.shape
    colour_type = {1: 0, 3: 2, 4: 6}[C]

    def write(f):
        f.write(_PNG_SIGNATURE)
        f.write(_png_chunk(b"IHDR", struct.pack(">IIBBBBB", W, H, 8, colour_type, 0, 0, 0)))
        f.write(_png_chunk(b"sRGB", b"\x00"))  # perceptual intent
        f.write(_png_chunk(b"gAMA", struct.pack(">I", 45455)))
        f.write(_png_chunk(b"cHRM", struct.pack(">8I", 31270, 32900, 64000, 33000, 30000, 60000, 15000, 6000)))
        for c in chunks_text:
            f.write(c)
        rows = np.empty((H, 1 + W * C), dtype=np.uint8)
        rows[:, 0] = 0  # filter type None
        rows[:, 1:] = a.reshape(H, W * C)
        f.write(_png_chunk(b"IDAT", zlib.compress(memoryview(rows), 6)))
        f.write(_png_chunk(b"IEND", b""))

    return p, write


def write_png(path, rgb8, *, text=None):
    """Write an 8-bit PNG atomically: ``rgb8`` uint8 (H, W, 3) RGB, (H, W, 4) RGBA or
    (H, W) grey, row 0 at the top, values taken as sRGB. ``text``: optional
    ``{keyword: value}`` tEXt chunks (Latin-1). Returns the path written."""
    p, writer = _prepare_png(path, rgb8, text)
    _atomic_write(p, writer)
    return p


# ----------------------------------------------------------------------------- tone mapping

#: Rec.709 / sRGB luminance weights (the Y row of the RGB -> XYZ matrix).
_Y709 = np.array([0.2126, 0.7152, 0.0722])


def luminance_rec709(rgb):
    """Relative luminance Y of linear Rec.709 RGB (..., 3)."""
    return np.asarray(rgb, dtype=float) @ _Y709


def srgb_oetf(v):
    """The sRGB transfer function of IEC 61966-2-1 (linear [0, 1] -> encoded [0, 1])."""
    v = np.clip(np.asarray(v, dtype=float), 0.0, 1.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1.0 / 2.4) - 0.055)


def _check_number(parameter, value, low, high, open_low=False):
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = float("nan")
    ok = (low < v if open_low else low <= v) and v <= high
    if isinstance(value, bool) or not ok:
        lb = "(" if open_low else "["
        raise SkymodelInputError(parameter, value, f"a number in {lb}{low:g}, {high:g}]")
    return v


def auto_exposure_luminance(rgb_linear, valid=None):
    """The scene luminance that :func:`tonemap` maps to the key when not told: the
    log-average exp(mean(log Y)) over valid pixels, with Y floored at 1e-3 x the median
    of the positive Y (so black ground or the night side do not drag it to 0). 1.0 for
    an image with no positive luminance."""
    return _log_average(luminance_rec709(rgb_linear), valid)


def _log_average(Y, valid=None):
    """:func:`auto_exposure_luminance` of the luminance ``Y`` itself (``Y`` is not changed)."""
    if valid is not None:
        v = np.asarray(valid, dtype=bool)
        Y = Y[v] if not v.all() else Y.ravel()
    fin = np.isfinite(Y)
    if not fin.all():
        Y = Y[fin]
    del fin
    pos = Y[Y > 0]
    if pos.size == 0:
        return 1.0
    floor = 1e-3 * float(np.median(pos, overwrite_input=True))
    del pos
    t = np.maximum(Y, floor)
    np.log(t, out=t)
    return float(np.exp(np.mean(t)))


def _all_finite(a):
    """Whether every value of ``a`` (H, ...) is finite, checked by bands of rows."""
    if a.ndim == 0 or a.shape[0] == 0:
        return bool(np.all(np.isfinite(a)))
    starts, rows = _row_bands(a.shape[0], a.size // a.shape[0])
    return all(bool(np.isfinite(a[r0:r0 + rows]).all()) for r0 in starts)


#: :func:`tonemap`'s default key (middle grey) and white (in key-scaled units).
TONEMAP_KEY, TONEMAP_WHITE = 0.18, 8.0


def tonemap(rgb_linear, exposure_ev=None, *, valid=None, average_luminance=None, key=TONEMAP_KEY,
            white=TONEMAP_WHITE, return_float=False):
    """Scene-linear Rec.709 (..., 3) -> 8-bit sRGB (..., 3) uint8 for previews.

    Exposure: the image is scaled by ``key / average_luminance * 2**exposure_ev``.
    ``average_luminance`` defaults to :func:`auto_exposure_luminance` (the log-average
    luminance of the valid pixels, Reinhard et al. 2002), so with ``exposure_ev=None``
    (= 0) the "average" sky lands on the photographic middle grey ``key = 0.18``;
    ``exposure_ev`` adds stops on top. Pass a fixed ``average_luminance`` to keep the
    exposure constant across an animation.

    Tone curve: extended Reinhard on luminance only, ``Ld = L (1 + L / white^2) / (1 + L)``
    (``white``, in key-scaled units, maps to display white), the colour scaled by
    ``Ld / L`` so hue and saturation are kept; a colour that then leaves the [0, 1] cube
    is desaturated toward the grey of the same luminance just enough to fit (rather than
    clipped per channel), so the sun and bright horizon turn white instead of shifting
    hue, and out-of-gamut (negative) channels are handled the same way. Then the sRGB
    OETF (IEC 61966-2-1) and rounding to 8 bits. Pixels where ``valid`` is False are
    black. Every channel is non-decreasing in ``exposure_ev`` and 0 maps to 0.
    ``return_float``: return the encoded values in [0, 1] instead of uint8.
    An image (3-D or more) is mapped in bands of rows, so the float64 temporaries of the
    curve stay small whatever the image size.
    """
    rgb = np.asarray(rgb_linear, dtype=float)
    if rgb.ndim < 1 or rgb.shape[-1] != 3:
        raise SkymodelInputError("rgb_linear", f"array of shape {rgb.shape}", "an (..., 3) linear RGB array")
    mask = np.ones(rgb.shape[:-1], dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
    if mask.shape != rgb.shape[:-1]:
        raise SkymodelInputError("valid", f"mask of shape {mask.shape}", f"a mask of shape {rgb.shape[:-1]}")
    bands = _leading_bands(rgb)
    bad = sum(int((mask[b] & ~np.all(np.isfinite(rgb[b]), axis=-1)).sum()) for b in bands)
    if bad:
        raise SkymodelInputError("rgb_linear", f"{bad} non-finite pixels", "finite values in valid pixels")
    ev = 0.0 if exposure_ev is None else scene.check("exposure_ev", exposure_ev)
    key = _check_number("key", key, 0.0, 1.0, open_low=True)
    white = _check_number("white", white, 0.0, 1e30, open_low=True)
    if average_luminance is None:
        Y = np.empty(rgb.shape[:-1])
        for b in bands:
            Y[b] = luminance_rec709(np.where(mask[b][..., None], rgb[b], 0.0))
        avg = _log_average(Y, mask)
        del Y
    else:
        avg = _check_number("average_luminance", average_luminance, 0.0, 1e300, open_low=True)
    scale = key / avg * 2.0**ev
    out = np.empty(rgb.shape, dtype=float if return_float else np.uint8)
    for b in bands:
        out[b] = _tone_curve(rgb[b], mask[b], scale, white, return_float)
    return out


def _leading_bands(a):
    """Index tuples that cover ``a`` (..., 3) in bands of rows of about :data:`BAND_VALUES`
    values (one band, the whole array, below 3 dimensions)."""
    if a.ndim < 3 or a.shape[0] == 0:
        return [(Ellipsis,)]
    starts, rows = _row_bands(a.shape[0], a.size // a.shape[0])
    return [(slice(r0, r0 + rows),) for r0 in starts]


def _tone_curve(rgb, mask, scale, white, return_float=False):
    """:func:`tonemap` after the exposure is known: ``rgb`` (..., 3) float64, ``mask``
    its valid pixels, ``scale`` = key / average luminance x 2^EV."""
    rgb = np.where(mask[..., None], rgb, 0.0)
    c = rgb * scale
    L = luminance_rec709(c)
    pos = L > 0
    Ls = np.where(pos, L, 1.0)
    Ld = np.where(pos, np.minimum(Ls * (1.0 + Ls / (white * white)) / (1.0 + Ls), 1.0), 0.0)
    c = c * (np.where(pos, Ld / Ls, 0.0))[..., None]
    # fit into [0, 1]^3 by moving toward (Ld, Ld, Ld) at constant luminance
    hi = c.max(axis=-1)
    lo = c.min(axis=-1)
    s = np.ones_like(Ld)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(hi > 1.0, np.minimum(s, (1.0 - Ld) / (hi - Ld)), s)
        s = np.where(lo < 0.0, np.minimum(s, Ld / (Ld - lo)), s)
    s = np.clip(np.nan_to_num(s, nan=0.0), 0.0, 1.0)
    c = Ld[..., None] + (c - Ld[..., None]) * s[..., None]
    c = np.where(pos[..., None], c, 0.0)
    enc = srgb_oetf(c)
    enc = np.where(mask[..., None], enc, 0.0)
    if return_float:
        return enc
    return np.rint(enc * 255.0).astype(np.uint8)


# ----------------------------------------------------------------------------- spectral NPZ


def _json_default(o):
    import dataclasses

    if dataclasses.is_dataclass(o) and not isinstance(o, type):
        return dataclasses.asdict(o)
    if isinstance(o, Mapping):
        return dict(o)
    if isinstance(o, (set, frozenset)):
        return sorted(o, key=repr)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, (os.PathLike,)):
        return os.fspath(o)
    raise TypeError(f"{type(o).__name__} is not JSON serialisable")


def _metadata_json(metadata, parameter="metadata"):
    try:
        return json.dumps(metadata, default=_json_default, allow_nan=False, sort_keys=True)
    except (TypeError, ValueError) as e:
        raise SkymodelInputError(parameter, str(e), "JSON-serialisable values (numbers, strings, lists, dicts)") from None


def _validate_spectral(radiance, wavelengths_nm, directions, valid):
    from skymodel.wavelengths import as_wavelengths

    rad = np.asarray(radiance)
    if rad.ndim != 3 or rad.dtype.kind not in "fiu":
        raise SkymodelInputError("radiance", f"array of shape {rad.shape}, dtype {rad.dtype}",
                                 "a real (H, W, n_wavelengths) array")
    wl = as_wavelengths(wavelengths_nm)
    if wl.size != rad.shape[2]:
        raise SkymodelInputError("wavelengths", f"{wl.size} wavelengths",
                                 f"{rad.shape[2]} wavelengths (the last axis of radiance)")
    H, W = rad.shape[:2]
    d = np.asarray(directions, dtype=float)
    if d.shape != (H, W, 3):
        raise SkymodelInputError("directions", f"array of shape {d.shape}", f"shape {(H, W, 3)}")
    v = np.ones((H, W), dtype=bool) if valid is None else np.asarray(valid)
    if v.shape != (H, W):
        raise SkymodelInputError("valid", f"mask of shape {v.shape}", f"shape {(H, W)}")
    v = v.astype(bool)
    bad = v & ~np.all(np.isfinite(rad), axis=-1)
    if bad.any():
        raise SkymodelInputError("radiance", f"{int(bad.sum())} pixels with non-finite values",
                                 "finite radiance in every valid pixel")
    negative = v & np.any(rad < 0, axis=-1)
    if negative.any():
        raise SkymodelInputError("radiance", f"{int(negative.sum())} pixels with negative values "
                                             f"(lowest {float(np.min(rad[negative])):.3g})",
                                 "non-negative radiance in every valid pixel")
    if rad.dtype.kind != "f":
        rad = rad.astype(float)
    rad = np.where(v[..., None], rad, 0.0).astype(rad.dtype, copy=False)
    return rad, wl, d, v


def _prepare_npz(path, radiance, wavelengths_nm, directions, valid, metadata, parameter="path"):
    p = _check_output_path(parameter, path, (".npz",))
    rad, wl, d, v = _validate_spectral(radiance, wavelengths_nm, directions, valid)
    meta = {"radiance_units": "W m^-2 sr^-1 nm^-1", "wavelength_units": "nm (vacuum)",
            "frame": "x east, y north, z up; image row 0 at the top", **metadata}
    meta_json = _metadata_json(meta)

    def write(f):
        np.savez(f, radiance=rad, wavelengths_nm=wl, directions=d, valid=v, metadata=np.array(meta_json))

    return p, write


def write_spectral_npz(path, radiance, wavelengths_nm, directions, valid=None, **metadata):
    """Store a spectral image atomically in an (uncompressed) ``.npz``.

    Arrays: ``radiance`` (H, W, n_wl) in W m^-2 sr^-1 nm^-1 (masked pixels stored as 0),
    ``wavelengths_nm`` (n_wl,), ``directions`` (H, W, 3) unit vectors (x east, y north,
    z up), ``valid`` (H, W) bool (all True if not given) and ``metadata``: a JSON string
    (``json.loads(str(npz["metadata"]))``) of the keyword arguments plus units and frame.
    Loads with ``np.load(path)`` (no pickle needed). Returns the path written."""
    p, writer = _prepare_npz(path, radiance, wavelengths_nm, directions, valid, metadata)
    _atomic_write(p, writer)
    return p


# ----------------------------------------------------------------------------- all outputs

_EXR_SPACES = ("rec709", "acescg", "xyz")


def save_outputs(out=None, png=None, spectral=None, *, radiance=None, wavelengths, camera, exposure_ev=None,
                 colour_space="rec709", half=False, compression="zip", metadata=None, xyz=None,
                 average_luminance=None):
    """Write the outputs of a render: any of ``out`` (``.exr``), ``png`` (``.png``) and
    ``spectral`` (``.npz``).

    ``radiance`` (H, W, n_wl) W m^-2 sr^-1 nm^-1 on ``wavelengths`` (nm) for the pixels
    of ``camera`` (a :class:`~skymodel.render.cameras.Camera`; its ``valid`` mask blacks
    out the rest). The EXR holds scene-linear radiometric colour (the CIE integrals of
    :mod:`skymodel.colorimetry`, no exposure applied): channels R, G, B in Rec.709
    (``colour_space="rec709"``, the default, Blender's working space) or ACEScg
    (``"acescg"``), with the matching ``chromaticities`` attribute, or X, Y, Z
    (``"xyz"``). The PNG is :func:`tonemap` of the Rec.709 image at ``exposure_ev`` and
    ``average_luminance`` (None: the image's log-average; :data:`TONEMAP_KEY`: the image
    scaled by ``2**exposure_ev`` alone, the exposure of :mod:`skymodel.render.exposure`). The
    NPZ is :func:`write_spectral_npz` with the camera description and ``metadata``.
    ``xyz`` (H, W, 3) instead of ``radiance``: the image already reduced to CIE XYZ (the
    same integrals; e.g. :func:`skymodel.render.sky.render_sky_reduced` with
    :func:`skymodel.render.skyview.xyz_reduction`), for renders that never hold the
    spectral cube; then no ``spectral`` output.

    Everything is validated before any file is created; the files are then written to
    temporary files and renamed into place together. Returns ``{"out": path, ...}`` for
    the files written.
    """
    from skymodel.colorimetry import spectral_to_xyz, xyz_to_rgb
    from skymodel.render.cameras import Camera

    targets = {"out": out, "png": png, "spectral": spectral}
    if all(v is None for v in targets.values()):
        raise SkymodelInputError("out", None, "at least one output path (out=.exr, png=.png, spectral=.npz)")
    exts = {"out": (".exr",), "png": (".png",), "spectral": (".npz",)}
    paths = {k: _check_output_path(k, v, exts[k]) for k, v in targets.items() if v is not None}
    seen = {}
    for k, p in paths.items():
        key = os.path.normcase(os.path.abspath(p))
        if key in seen:
            raise SkymodelInputError(k, p, f"a path different from {seen[key]}")
        seen[key] = k
    if not isinstance(camera, Camera):
        raise SkymodelInputError("camera", camera, "a Camera from skymodel.render.cameras.make_camera")
    space = str(colour_space).lower()
    if space not in _EXR_SPACES:
        raise SkymodelInputError("colour_space", colour_space, "one of: " + ", ".join(_EXR_SPACES))
    if exposure_ev is not None:
        scene.check("exposure_ev", exposure_ev)
    if average_luminance is not None:
        try:
            ok = float(average_luminance) > 0 and math.isfinite(float(average_luminance))
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise SkymodelInputError("average_luminance", average_luminance, "a positive finite luminance")
    if (radiance is None) == (xyz is None):
        raise SkymodelInputError("radiance", "both or neither of radiance and xyz", "exactly one of them")
    if xyz is not None:
        if spectral is not None:
            raise SkymodelInputError("spectral", spectral, "no spectral output from an XYZ image (render spectra)")
        xyz_in = np.asarray(xyz)
        if xyz_in.dtype.kind not in "fiu":
            xyz_in = np.asarray(xyz_in, dtype=float)
        if xyz_in.shape != camera.shape + (3,) or not _all_finite(xyz_in):
            raise SkymodelInputError("xyz", f"array of shape {xyz_in.shape}",
                                     f"finite values of shape ({camera.height}, {camera.width}, 3) for {camera!r}")
        rad = None
        valid = camera.valid_mask()
    else:
        rad = np.asarray(radiance)
        if rad.ndim != 3 or rad.shape[:2] != camera.shape:
            raise SkymodelInputError("radiance", f"array of shape {rad.shape}",
                                     f"shape ({camera.height}, {camera.width}, n_wavelengths) for {camera!r}")
        directions, valid = camera.directions()
        rad, wl, directions, valid = _validate_spectral(rad, wavelengths, directions, valid)
    meta = {"camera": camera.describe(), "colour_space": space,
            "exposure_ev": exposure_ev, **(metadata or {})}
    _metadata_json(meta)
    if rad is not None:
        xyz_in = spectral_to_xyz(rad, wl)  # invalid pixels are 0 already

    # The colour images are made by bands of rows, in float64 as a whole image would be, and
    # kept only as the EXR's float32 (or half) pixels and the PNG's 8 bits (and, until the
    # exposure is known, the float64 luminance): the writers add little to a render's peak.
    H, W = camera.shape
    starts, rows = _row_bands(H, 3 * W)

    def colour(r0):
        """XYZ (invalid pixels 0) and Rec.709 of rows r0 .. r0 + rows, float64."""
        x = np.where(valid[r0:r0 + rows, :, None], np.asarray(xyz_in[r0:r0 + rows], dtype=float), 0.0)
        return x, xyz_to_rgb(x, "rec709")

    jobs = []
    exr = Y = None
    if "out" in paths:
        exr = np.empty((H, W, 3), dtype="<f2" if half else "<f4")
        check = _ExrValueCheck(np.float64, half)
    if "png" in paths:
        Y = np.empty((H, W))

    def band(r0):
        """One band of rows into the EXR's pixels and the luminance; its non-finite PNG pixels."""
        x, rgb709 = colour(r0)
        if exr is not None:
            img = x if space == "xyz" else rgb709 if space == "rec709" else xyz_to_rgb(x, space)
            check.add(img)
            with np.errstate(over="ignore"):  # out of range: refused below, before any file
                exr[r0:r0 + rows] = img
        if Y is None:
            return 0
        Y[r0:r0 + rows] = luminance_rec709(rgb709)
        return int((valid[r0:r0 + rows] & ~np.all(np.isfinite(rgb709), axis=-1)).sum())

    # the bands on the solver's threads (each writes its own rows; numpy releases the GIL)
    bad_png = sum(in_threads(band, starts, SOLVER_THREADS))
    if exr is not None:
        check.raise_if_bad()
        if space == "xyz":
            chans, chroma = ("X", "Y", "Z"), None
        else:
            chans, chroma = ("R", "G", "B"), CHROMATICITIES[space]
        attrs = {"comments": "skymodel: scene-linear radiometric colour (CIE 1931 integrals of W m^-2 sr^-1 nm^-1)",
                 "skymodel": _metadata_json(meta)}
        jobs.append(_prepare_exr(paths["out"], exr, chans, half, compression, chroma, attrs, 4, parameter="out"))
    if Y is not None:  # tonemap(rgb709, exposure_ev, valid=valid), by bands
        if bad_png:
            raise SkymodelInputError("rgb_linear", f"{bad_png} non-finite pixels", "finite values in valid pixels")
        ev = 0.0 if exposure_ev is None else scene.check("exposure_ev", exposure_ev)
        avg = _log_average(Y, valid) if average_luminance is None else float(average_luminance)
        scale = TONEMAP_KEY / avg * 2.0**ev
        Y = None
        rgb8 = np.empty((H, W, 3), dtype=np.uint8)

        def tone(r0):
            rgb8[r0:r0 + rows] = _tone_curve(colour(r0)[1], valid[r0:r0 + rows], scale, TONEMAP_WHITE)

        in_threads(tone, starts, SOLVER_THREADS)
        jobs.append(_prepare_png(paths["png"], rgb8, {"Software": "skymodel"}, parameter="png"))
    if "spectral" in paths:
        jobs.append(_prepare_npz(paths["spectral"], rad, wl, directions, valid, meta, parameter="spectral"))
    _atomic_write_many(jobs)
    return dict(paths)
