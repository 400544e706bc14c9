"""Image output: EXR read back by Blender's OpenEXR reader (bpy), PNG read back by
Pillow, sRGB against colour-science, tone mapping properties, atomic writes and input
validation."""

import json
import os

import numpy as np
import pytest

from skymodel.errors import SkymodelInputError
from skymodel.render import image_io
from skymodel.render.cameras import make_camera
from skymodel.render.image_io import (CHROMATICITIES, save_outputs, tonemap, write_exr, write_png,
                                      write_spectral_npz)


def _read_exr_bpy(path):
    """Pixels (H, W, 4) float32, row 0 at the top, through Blender's image loader."""
    bpy = pytest.importorskip("bpy")
    im = bpy.data.images.load(str(path))
    try:
        w, h = im.size
        assert im.is_float
        buf = np.empty(w * h * im.channels, dtype=np.float32)
        im.pixels.foreach_get(buf)
        return buf.reshape(h, w, im.channels)[::-1]  # Blender stores rows bottom to top
    finally:
        bpy.data.images.remove(im)


def _listing(folder):
    return sorted(os.listdir(folder))


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def _smooth(h, w):
    """A compressible image (a zip block is then really compressed, not stored raw)."""
    y, x = np.mgrid[0:h, 0:w]
    return np.stack([x / w, y / h, 0.25 + 0 * x], axis=-1).astype(np.float32) * 3.0


# ------------------------------------------------------------------ EXR


@pytest.mark.blender
@pytest.mark.parametrize("compression", ["none", "zips", "zip"])
@pytest.mark.parametrize("kind", ["random", "smooth"])
def test_exr_float32_round_trip_exact_through_bpy(tmp_path, rng, compression, kind):
    h, w = 37, 53  # 37 lines: the last 16-line ZIP block is partial
    a = (rng.standard_normal((h, w, 3)) * 1e3).astype(np.float32) if kind == "random" else _smooth(h, w)
    a[0, 0] = [1e-30, -3e20, 65504.0]
    path = write_exr(tmp_path / "t.exr", a, compression=compression)
    px = _read_exr_bpy(path)
    assert px.shape == (h, w, 4)
    np.testing.assert_array_equal(px[..., :3], a)
    if kind == "smooth" and compression != "none":
        assert os.path.getsize(path) < 0.5 * a.nbytes  # the zlib path was exercised


@pytest.mark.blender
@pytest.mark.parametrize("compression", ["none", "zip"])
def test_exr_half_round_trip_through_bpy(tmp_path, rng, compression):
    a = rng.uniform(-100, 100, (20, 31, 3))
    path = write_exr(tmp_path / "h.exr", a, half=True, compression=compression)
    px = _read_exr_bpy(path)
    np.testing.assert_array_equal(px[..., :3], a.astype(np.float16).astype(np.float32))
    assert np.allclose(px[..., :3], a, rtol=2**-10, atol=0)


@pytest.mark.blender
def test_exr_channel_order_and_extra_channels(tmp_path, rng):
    """Channels given out of order are sorted by name in the file, data follows its name."""
    a = rng.uniform(0, 1, (9, 7, 4)).astype(np.float32)
    path = write_exr(tmp_path / "c.exr", a[..., [3, 2, 0, 1]], channels=("A", "B", "R", "G"),
                     chromaticities=CHROMATICITIES["rec709"], attributes={"owner": "test"})
    px = _read_exr_bpy(path)
    np.testing.assert_array_equal(px, a)
    path = write_exr(tmp_path / "m.exr", {"G": a[..., 1], "R": a[..., 0], "B": a[..., 2]})
    np.testing.assert_array_equal(_read_exr_bpy(path)[..., :3], a[..., :3])


def test_exr_header_layout(tmp_path):
    """The spec's fixed parts, read by hand: magic, version, required attributes, offset
    table pointing at chunks whose y coordinates follow the block size."""
    import struct

    path = write_exr(tmp_path / "l.exr", _smooth(40, 10), compression="zip")
    data = open(path, "rb").read()
    assert struct.unpack("<ii", data[:8]) == (20000630, 2)
    for name in (b"channels\0chlist", b"compression\0compression", b"dataWindow\0box2i", b"displayWindow\0box2i",
                 b"lineOrder\0lineOrder", b"pixelAspectRatio\0float", b"screenWindowCenter\0v2f",
                 b"screenWindowWidth\0float"):
        assert name in data
    end = data.index(b"screenWindowWidth\0float\0") + len(b"screenWindowWidth\0float\0") + 4 + 4 + 1
    offsets = struct.unpack("<3Q", data[end:end + 24])  # ceil(40 / 16) = 3 blocks
    assert offsets[0] == end + 24
    assert [struct.unpack("<i", data[o:o + 4])[0] for o in offsets] == [0, 16, 32]
    last_size = struct.unpack("<i", data[offsets[2] + 4:offsets[2] + 8])[0]
    assert offsets[2] + 8 + last_size == len(data)


@pytest.mark.parametrize("bad, parameter", [
    (dict(rgb_or_channels=np.zeros((4, 4, 2))), "rgb_or_channels"),
    (dict(rgb_or_channels=np.full((4, 4, 3), np.nan)), "rgb_or_channels"),
    (dict(rgb_or_channels=np.full((4, 4, 3), 1e5), half=True), "half"),
    (dict(compression="piz"), "compression"),
    (dict(channels=("R", "R", "B")), "channels"),
    (dict(path_name="x.tif"), "path"),
    (dict(path_name="missing/x.exr"), "path"),
])
def test_exr_bad_input_creates_nothing(tmp_path, bad, parameter):
    kwargs = dict(rgb_or_channels=np.zeros((4, 4, 3)))
    kwargs.update(bad)
    name = kwargs.pop("path_name", "x.exr")
    with pytest.raises(SkymodelInputError) as e:
        write_exr(tmp_path / name, **kwargs)
    assert e.value.parameter == parameter
    assert _listing(tmp_path) == []


def test_failed_write_leaves_no_file_and_keeps_the_old_one(tmp_path, monkeypatch):
    target = tmp_path / "keep.exr"
    target.write_bytes(b"previous contents")

    def boom(raw, level):
        raise OSError("disk full (simulated)")

    monkeypatch.setattr(image_io, "_zip_pack", boom)
    with pytest.raises(OSError, match="simulated"):
        write_exr(target, _smooth(40, 8))
    assert _listing(tmp_path) == ["keep.exr"]  # no temporary file left behind
    assert target.read_bytes() == b"previous contents"
    with pytest.raises(OSError, match="simulated"):
        write_exr(tmp_path / "new.exr", _smooth(40, 8))
    assert _listing(tmp_path) == ["keep.exr"]


def test_written_file_has_ordinary_permissions(tmp_path):
    old = os.umask(0o022)
    try:
        path = write_png(tmp_path / "p.png", np.zeros((2, 2, 3), np.uint8))
    finally:
        os.umask(old)
    assert os.stat(path).st_mode & 0o777 == 0o644


# ------------------------------------------------------------------ PNG


@pytest.mark.parametrize("shape, mode", [((13, 17, 3), "RGB"), ((5, 8, 4), "RGBA"), ((6, 3), "L"), ((1, 1, 3), "RGB")])
def test_png_round_trip_through_pillow(tmp_path, rng, shape, mode):
    from PIL import Image

    a = rng.integers(0, 256, shape, dtype=np.uint8)
    path = write_png(tmp_path / "x.png", a, text={"Software": "skymodel"})
    with Image.open(path) as im:
        im.load()
        assert im.mode == mode and im.size == (shape[1], shape[0])
        np.testing.assert_array_equal(np.asarray(im), a)
        assert im.info.get("Software") == "skymodel"


@pytest.mark.parametrize("a, parameter, name", [
    (np.zeros((4, 4, 3)), "rgb8", "x.png"),              # float, not uint8
    (np.zeros((4, 4, 2), np.uint8), "rgb8", "x.png"),
    (np.zeros((4, 4, 3), np.uint8), "path", "x.jpg"),
    (np.zeros((4, 4, 3), np.uint8), "path", "nowhere/x.png"),
])
def test_png_bad_input_creates_nothing(tmp_path, a, parameter, name):
    with pytest.raises(SkymodelInputError) as e:
        write_png(tmp_path / name, a)
    assert e.value.parameter == parameter
    assert _listing(tmp_path) == []


# ------------------------------------------------------------------ tone mapping


def test_srgb_oetf_matches_colour_science():
    colour = pytest.importorskip("colour")
    v = np.concatenate([np.linspace(0, 0.01, 50), np.linspace(0.01, 1, 200)])
    np.testing.assert_allclose(image_io.srgb_oetf(v), colour.models.eotf_inverse_sRGB(v), atol=1e-12)


def test_tonemap_zero_is_black_and_masked_is_black(rng):
    rgb = rng.uniform(0, 1, (8, 8, 3))
    rgb[0, 0] = 0.0
    valid = np.ones((8, 8), bool)
    valid[1, 1] = False
    rgb[1, 1] = np.nan  # ignored where masked
    out = tonemap(rgb, valid=valid)
    assert out.dtype == np.uint8 and out.shape == (8, 8, 3)
    assert np.all(out[0, 0] == 0) and np.all(out[1, 1] == 0)
    assert np.all(tonemap(np.zeros((3, 3, 3))) == 0)


def test_tonemap_monotone_in_exposure(rng):
    rgb = rng.uniform(0, 1, (400, 3)) ** 3 * 10 ** rng.uniform(-2, 4, (400, 1))
    rgb[:50, 0] -= 0.05 * rgb[:50, 1]  # a few out-of-gamut (negative-channel) colours
    rgb[:50] = np.where(rgb[:50] @ image_io._Y709 > 0, rgb[:50].T, 0).T
    prev = None
    for ev in np.arange(-8, 8.01, 0.25):
        out = tonemap(rgb, ev, average_luminance=1.0, return_float=True)
        if prev is not None:
            assert np.all(out >= prev - 1e-12)
        prev = out
    assert np.all(tonemap(rgb, 20.0, average_luminance=1.0) >= 254)  # everything tends to white


def test_tonemap_sun_goes_white_not_hue_shifted():
    sky = np.array([0.2, 0.3, 0.6])
    sun = np.array([1.0, 0.9, 0.7]) * 1e5
    img = np.tile(sky, (10, 10, 1))
    img[5, 5] = sun
    out = tonemap(img)
    assert tuple(out[5, 5]) == (255, 255, 255)
    s = out[0, 0].astype(float)
    assert s[2] > s[1] > s[0]  # the sky stays blue, in the same channel order
    # auto exposure: scaling the radiance does not change the picture
    np.testing.assert_array_equal(tonemap(img * 1000.0), out)
    # exposure in stops: +1 EV doubles the linear input
    np.testing.assert_array_equal(tonemap(img, 1.0), tonemap(img * 2, average_luminance=image_io.auto_exposure_luminance(img)))


def test_tonemap_preserves_hue_below_white():
    rgb = np.array([[0.02, 0.05, 0.1]])
    enc = tonemap(rgb, average_luminance=1.0, key=0.18, return_float=True)
    lin = np.where(enc <= 0.04045, enc / 12.92, ((enc + 0.055) / 1.055) ** 2.4)
    np.testing.assert_allclose(lin / lin[0, 2], rgb / rgb[0, 2], rtol=1e-9)


def test_tonemap_desaturates_instead_of_clipping():
    """A bright saturated colour keeps the tone curve's luminance (clipping the blue
    channel alone would darken it and shift its hue toward cyan)."""
    rgb = np.array([0.05, 0.1, 1.0]) * np.array([1.0, 5.0, 20.0, 50.0])[:, None]
    enc = tonemap(rgb, average_luminance=1.0, key=0.18, white=8.0, return_float=True)
    lin = np.where(enc <= 0.04045, enc / 12.92, ((enc + 0.055) / 1.055) ** 2.4)
    L = 0.18 * image_io.luminance_rec709(rgb)
    Ld = np.minimum(L * (1 + L / 64.0) / (1 + L), 1.0)
    np.testing.assert_allclose(image_io.luminance_rec709(lin), Ld, rtol=1e-9)
    assert np.all(lin <= 1.0) and np.all(lin >= 0.0)
    assert np.all(np.diff(lin[:, 0]) > 0)  # the red channel rises toward white


@pytest.mark.parametrize("kwargs, parameter", [
    (dict(exposure_ev="bright"), "exposure_ev"),
    (dict(exposure_ev=float("inf")), "exposure_ev"),
    (dict(valid=np.ones((2, 2), bool)), "valid"),
    (dict(key=0), "key"),
])
def test_tonemap_bad_input(kwargs, parameter):
    with pytest.raises(SkymodelInputError) as e:
        tonemap(np.ones((3, 3, 3)), **kwargs)
    assert e.value.parameter == parameter


# ------------------------------------------------------------------ spectral NPZ and save_outputs


def _render(camera, wl):
    """A stand-in render: smooth spectra that vary over the image."""
    d, valid = camera.directions()
    lam = (wl - 380.0) / 400.0
    rad = 0.1 * (1.0 + d[..., 2:3]) * (1.0 - 0.7 * lam) + 0.01 * np.abs(d[..., 0:1]) * lam
    return np.where(valid[..., None], rad, np.nan)  # masked pixels may hold anything


def test_spectral_npz_round_trip(tmp_path):
    cam = make_camera("fisheye", 12)
    wl = np.linspace(380, 780, 9)
    rad = _render(cam, wl)
    d, valid = cam.directions()
    path = write_spectral_npz(tmp_path / "s.npz", rad, wl, d, valid, sun_elevation_deg=np.float64(30.0), note="x")
    with np.load(path) as z:
        assert set(z.files) == {"radiance", "wavelengths_nm", "directions", "valid", "metadata"}
        np.testing.assert_array_equal(z["radiance"][valid], rad[valid])
        assert np.all(z["radiance"][~valid] == 0)
        np.testing.assert_array_equal(z["wavelengths_nm"], wl)
        np.testing.assert_array_equal(z["directions"], d)
        np.testing.assert_array_equal(z["valid"], valid)
        meta = json.loads(str(z["metadata"]))
    assert meta["sun_elevation_deg"] == 30.0 and meta["note"] == "x"
    assert meta["radiance_units"] == "W m^-2 sr^-1 nm^-1"


def test_spectral_npz_bad_input_creates_nothing(tmp_path):
    cam = make_camera("dome", 16)
    wl = np.linspace(380, 780, 5)
    d, valid = cam.directions()
    rad = _render(cam, wl)
    cases = [
        (dict(radiance=rad[..., :4]), "wavelengths"),
        (dict(directions=d[:, :3]), "directions"),
        (dict(radiance=np.where(True, np.nan, rad)), "radiance"),
        (dict(bad=object()), "metadata"),
    ]
    for override, parameter in cases:
        args = dict(radiance=rad, wavelengths_nm=wl, directions=d, valid=valid)
        args.update(override)
        with pytest.raises(SkymodelInputError) as e:
            write_spectral_npz(tmp_path / "s.npz", **args)
        assert e.value.parameter == parameter
    assert _listing(tmp_path) == []


@pytest.mark.blender
@pytest.mark.parametrize("space", ["rec709", "xyz"])
def test_save_outputs_writes_consistent_files(tmp_path, space):
    from PIL import Image

    from skymodel.colorimetry import spectral_to_rgb, spectral_to_xyz

    cam = make_camera("fisheye", 24)
    wl = np.linspace(380, 780, 41)
    rad = _render(cam, wl)
    _, valid = cam.directions()
    written = save_outputs(out=tmp_path / "sky.exr", png=tmp_path / "sky.png", spectral=tmp_path / "sky.npz",
                           radiance=rad, wavelengths=wl, camera=cam, exposure_ev=0.5, colour_space=space,
                           metadata={"run": 1})
    assert set(written) == {"out", "png", "spectral"}
    assert _listing(tmp_path) == ["sky.exr", "sky.npz", "sky.png"]
    clean = np.where(valid[..., None], rad, 0.0)
    expected = spectral_to_xyz(clean, wl) if space == "xyz" else spectral_to_rgb(clean, wl, "rec709")
    px = _read_exr_bpy(tmp_path / "sky.exr")
    np.testing.assert_array_equal(px[..., :3], expected.astype(np.float32))
    with Image.open(tmp_path / "sky.png") as im:
        png = np.asarray(im)
    rgb = spectral_to_rgb(clean, wl, "rec709")
    np.testing.assert_array_equal(png, tonemap(rgb, 0.5, valid=valid))
    assert np.all(png[~valid] == 0) and png[valid].max() > 0
    with np.load(tmp_path / "sky.npz") as z:
        meta = json.loads(str(z["metadata"]))
    assert meta["camera"]["camera"] == "fisheye" and meta["run"] == 1 and meta["colour_space"] == space


@pytest.mark.parametrize("override, parameter", [
    (dict(png="preview.jpg"), "png"),
    (dict(out="sky.hdr"), "out"),
    (dict(spectral="sky.npy"), "spectral"),
    (dict(out="no/such/folder/sky.exr"), "out"),
    (dict(colour_space="srgb"), "colour_space"),
    (dict(exposure_ev=float("nan")), "exposure_ev"),
    (dict(radiance="shape"), "radiance"),
    (dict(radiance="nan"), "radiance"),
    (dict(wavelengths=np.linspace(380, 780, 40)), "wavelengths"),
    (dict(camera="fisheye"), "camera"),
    (dict(out=None, png=None, spectral=None), "out"),
    (dict(png="sky.exr"), "png"),
    (dict(metadata={"f": lambda: 0}), "metadata"),
])
def test_save_outputs_bad_argument_creates_nothing(tmp_path, monkeypatch, override, parameter):
    monkeypatch.chdir(tmp_path)
    cam = make_camera("equirectangular", 16)
    wl = np.linspace(380, 780, 11)
    rad = _render(cam, wl)
    args = dict(out="sky.exr", png="sky.png", spectral="sky.npz", radiance=rad, wavelengths=wl, camera=cam)
    if override.get("radiance") == "shape":
        override["radiance"] = rad[:, :-1]
    elif override.get("radiance") == "nan":
        rad = rad.copy()
        rad[3, 3, 3] = np.nan
        override["radiance"] = rad
    args.update(override)
    with pytest.raises(SkymodelInputError) as e:
        save_outputs(**args)
    assert e.value.parameter == parameter
    assert _listing(tmp_path) == []


def test_save_outputs_failure_mid_way_leaves_nothing(tmp_path, monkeypatch):
    cam = make_camera("dome", 16)
    wl = np.linspace(380, 780, 5)

    def boom(*a, **k):
        raise OSError("simulated failure while writing the npz")

    monkeypatch.setattr(np, "savez", boom)
    with pytest.raises(OSError, match="simulated"):
        save_outputs(out=tmp_path / "a.exr", png=tmp_path / "a.png", spectral=tmp_path / "a.npz",
                     radiance=_render(cam, wl), wavelengths=wl, camera=cam)
    assert _listing(tmp_path) == []


# ------------------------------------------------------------------ writers by bands of rows


def _outputs(folder, xyz, cam, **kw):
    save_outputs(out=folder / "sky.exr", png=folder / "sky.png", xyz=xyz, wavelengths=None, camera=cam, **kw)
    return (folder / "sky.exr").read_bytes(), (folder / "sky.png").read_bytes()


@pytest.mark.parametrize("space, half, dtype", [("rec709", False, np.float64), ("acescg", True, np.float32),
                                                ("xyz", False, np.float32)])
def test_writers_by_bands_write_what_the_whole_image_gives(tmp_path, monkeypatch, rng, space, half, dtype):
    """The writers convert the image by bands of rows (image_io.BAND_VALUES values at a time):
    bands of one row and one band for the whole image write the same bytes, for a masked
    camera, every colour space, half floats and float32 input; so do write_exr (an array and
    a mapping of mixed dtypes) and tonemap."""
    cam = make_camera("fisheye", 37, 29)
    xyz = (rng.lognormal(-3.0, 2.0, cam.shape + (3,)) * [0.95, 1.0, 1.1]).astype(dtype)
    planes = {"Y": xyz[..., 1], "B": xyz[..., 2].astype(np.float32), "a": (xyz[..., 0] * 1e6).astype(np.int32)}
    got = []
    for band_values in (1, 1 << 40):
        monkeypatch.setattr(image_io, "BAND_VALUES", band_values)
        folder = tmp_path / str(band_values)
        folder.mkdir()
        files = _outputs(folder, xyz, cam, colour_space=space, half=half, exposure_ev=0.5)
        write_exr(folder / "a.exr", xyz, half=half, compression="zips")
        write_exr(folder / "m.exr", planes)
        rgb = xyz.astype(float)
        got.append(files + ((folder / "a.exr").read_bytes(), (folder / "m.exr").read_bytes(),
                            tonemap(rgb, 1.0, valid=cam.valid_mask()).tobytes(),
                            tonemap(rgb, return_float=True).tobytes()))
    assert got[0] == got[1]
    # and they are the float64 image's colours cast to the file's type at the end (the old
    # whole-image arithmetic): an uncompressed file's lines hold the sorted channels' values
    from skymodel.colorimetry import xyz_to_rgb

    valid = cam.valid_mask()
    np.testing.assert_array_equal(valid, cam.directions()[1])
    clean = np.where(valid[..., None], xyz.astype(float), 0.0)
    img = clean if space == "xyz" else xyz_to_rgb(clean, space)
    order = [0, 1, 2] if space == "xyz" else [2, 1, 0]  # X, Y, Z / B, G, R
    file_type = np.dtype("<f2" if half else "<f4")
    _outputs(tmp_path, xyz, cam, colour_space=space, half=half, compression="none")
    h, w = cam.shape
    line = 8 + 3 * w * file_type.itemsize
    raw = (tmp_path / "sky.exr").read_bytes()[-h * line:]
    lines = np.frombuffer(raw, np.uint8).reshape(h, line)[:, 8:].copy().view(file_type).reshape(h, 3, w)
    np.testing.assert_array_equal(lines, np.transpose(img[:, :, order], (0, 2, 1)).astype(file_type))


def test_writers_add_little_memory(tmp_path, monkeypatch):
    """save_outputs (EXR + PNG) of a float64 XYZ image adds less than 2.5 x the image's own
    bytes (the EXR's float32 pixels, the float64 luminance for the exposure, the 8-bit PNG);
    it added 11.8 x before the writers worked by bands (tracemalloc, 1024x512)."""
    import tracemalloc

    from skymodel.colorimetry import xyz_to_rgb_matrix

    xyz_to_rgb_matrix("rec709")  # imports colour-science before the measurement
    monkeypatch.setattr(image_io, "BAND_VALUES", 1 << 14)
    cam = make_camera("equirectangular", 512)
    xyz = np.random.default_rng(5).lognormal(-4.0, 1.0, cam.shape + (3,))
    tracemalloc.start()
    try:
        _outputs(tmp_path, xyz, cam)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 2.5 * xyz.nbytes, peak / xyz.nbytes
