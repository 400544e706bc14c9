"""Prototype, not in skymodel: the solver's spherical correction (orders 2.. up to
``spherical_orders``) computed on every other azimuth and interpolated back, then
``notebooks/truth_misses/variant.py`` with the same arguments.

The correction is the ratio spherical / column transport of one order's source. With an even
``table_phi`` the midpoints of half as many cells are each the mean of two neighbouring nodes,
and the column transport acts on every (azimuth, sun node) column alike, so the column
transport of the averaged source is the average of the column transport: the ratio is formed on
the coarse nodes from the averaged source and the averaged column light, and read back on the
fine nodes linearly (each fine node a quarter of a coarse cell from its coarse node; the ratio
is even about 0 and pi). The first order's spherical transport is untouched (it carries the
forward lobe). Usage, from the repository root:

    python notebooks/azimuth_count/coarse_correction.py <scenes> <tag> "table_phi=24"
"""

import os
import runpy
import sys

import numpy as np

sys.path.insert(0, os.getcwd())
import skymodel.render.multiple_scattering as ms  # noqa: E402

_init, _correction = ms._SphericalTransport.__init__, ms._SphericalTransport.correction


def _coarse_init(self, *, phi_nodes, **kw):
    assert phi_nodes.size % 2 == 0, "an even table_phi"
    self.fine_n_phi = phi_nodes.size
    _init(self, phi_nodes=0.5 * (phi_nodes[0::2] + phi_nodes[1::2]), **kw)


def _pairs_mean(a, n_mu, n_phi):
    """(W, n_mu * n_phi, ...) -> (W, n_mu * n_phi / 2, ...): the mean of azimuth nodes 2k, 2k + 1."""
    a5 = a.reshape(a.shape[0], n_mu, n_phi, *a.shape[2:])
    return (0.5 * (a5[:, :, 0::2] + a5[:, :, 1::2])).reshape(a.shape[0], n_mu * (n_phi // 2), *a.shape[2:])


def _coarse_correction(self, j_dir, lg, column_dir):
    nf, nc = self.fine_n_phi, self.n_phi
    r = _correction(self, _pairs_mean(j_dir, self.n_mu, nf), lg, _pairs_mean(column_dir, self.n_mu, nf))
    r5 = r.reshape(r.shape[0], self.n_mu, nc, self.n_h, self.n_mus)
    below = np.concatenate([r5[:, :, :1], r5[:, :, :-1]], axis=2)  # coarse k - 1 (k = 0: its mirror, itself)
    above = np.concatenate([r5[:, :, 1:], r5[:, :, -1:]], axis=2)  # coarse k + 1 (the last: its mirror)
    fine = np.empty((r.shape[0], self.n_mu, nf, self.n_h, self.n_mus), dtype=r.dtype)
    fine[:, :, 0::2] = 0.75 * r5 + 0.25 * below
    fine[:, :, 1::2] = 0.75 * r5 + 0.25 * above
    return fine.reshape(r.shape[0], self.n_mu * nf, self.n_h, self.n_mus)


ms._SphericalTransport.__init__ = _coarse_init
ms._SphericalTransport.correction = _coarse_correction
sys.argv = ["variant.py"] + sys.argv[1:]
runpy.run_path(os.path.join("notebooks", "truth_misses", "variant.py"), run_name="__main__")
