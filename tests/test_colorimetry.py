"""The colour-matching functions and RGB matrices of skymodel.colorimetry, read and derived
without colour-science, against colour-science (the oracle)."""

import subprocess
import sys

import numpy as np
import pytest

from skymodel import colorimetry
from skymodel.errors import SkymodelInputError


def test_cmf_table_equals_colour_science():
    colour = pytest.importorskip("colour")
    ref = colour.MSDS_CMFS[colorimetry._CMFS_NAME]
    wl, values = colorimetry._cmfs_1nm()
    np.testing.assert_array_equal(wl, ref.wavelengths)
    np.testing.assert_array_equal(values, ref.values)


def test_rgb_matrices_equal_colour_science():
    colour = pytest.importorskip("colour")
    rec709 = colour.RGB_COLOURSPACES["ITU-R BT.709"].matrix_XYZ_to_RGB
    d65 = colour.CCS_ILLUMINANTS[colorimetry._CMFS_NAME]["D65"]
    acescg = np.asarray(colour.XYZ_to_RGB(np.eye(3), colour.RGB_COLOURSPACES["ACEScg"], illuminant=d65,
                                          chromatic_adaptation_transform="CAT02")).T
    np.testing.assert_allclose(colorimetry.xyz_to_rgb_matrix("rec709"), rec709, rtol=0, atol=1e-15)
    np.testing.assert_allclose(colorimetry.xyz_to_rgb_matrix("acescg"), acescg, rtol=0, atol=1e-15)
    with pytest.raises(SkymodelInputError, match="colour_space"):
        colorimetry.xyz_to_rgb_matrix("srgb-ish")


def test_colour_weights_do_not_import_colour_science():
    """A render's colour path (CMF weights, RGB matrix) leaves colour-science (and with it
    matplotlib) unimported: its import cost every CLI render 1.5-2.7 s."""
    code = ("import sys; from skymodel.colorimetry import cmf_weights, xyz_to_rgb_matrix; "
            "import skymodel.cli.render; import numpy as np; "
            "cmf_weights(np.arange(380.0, 781.0, 5.0)); xyz_to_rgb_matrix('rec709'); xyz_to_rgb_matrix('acescg'); "
            "print(sorted(m for m in ('colour', 'matplotlib') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr
