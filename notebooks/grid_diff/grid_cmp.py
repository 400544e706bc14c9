"""compare grid dumps: grid_cmp.py OUTDIR tagA tagB"""
import sys, glob, os
import numpy as np
out, a, b = sys.argv[1:4]
for fa in sorted(glob.glob(f"{out}/*_{a}.npz")):
    fb = fa[: -len(f"_{a}.npz")] + f"_{b}.npz"
    if not os.path.exists(fb):
        continue
    A, B = np.load(fa), np.load(fb)
    name = os.path.basename(fa)[: -len(f"_{a}.npz")]
    for side in ("sky", "ground"):
        x, y = A[side], B[side]
        ok = x > 1e-12 * x.max()
        rel = np.abs(y[ok] / x[ok] - 1)
        i = np.unravel_index(np.argmax(np.where(ok, np.abs(y / np.where(ok, x, 1) - 1), 0)), x.shape)
        print(f"{name:12s} {side:6s} median {100*np.median(rel):.5f} %  max {100*rel.max():.4f} % at (zen {i[0]}, az {i[1]}, wl {i[2]})  t {float(A['secs']):.2f} -> {float(B['secs']):.2f} s")
