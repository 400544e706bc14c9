"""max |B/A-1| of the sky grid by angle from the sun: grid_cmp_angle.py DIR tagA tagB"""
import sys, glob, os
import numpy as np
out, a, b = sys.argv[1:4]
for fa in sorted(glob.glob(f"{out}/*_{a}.npz")):
    fb = fa[: -len(f"_{a}.npz")] + f"_{b}.npz"
    if not os.path.exists(fb): continue
    A, B = np.load(fa), np.load(fb)
    name = os.path.basename(fa)[: -len(f"_{a}.npz")]
    sun = float(name.split("_")[1]); zs = np.radians(90 - sun)
    z, az = A["zen_sky"][:, None], A["az"][None, :]
    g = np.degrees(np.arccos(np.cos(z)*np.cos(zs) + np.sin(z)*np.sin(zs)*np.cos(az)))
    rel = np.abs(B["sky"] / A["sky"] - 1).max(axis=-1)
    row = [f"{name:10s}"]
    for lo, hi in ((0, 2), (2, 4), (4, 8), (8, 16), (16, 180)):
        m = (g >= lo) & (g < hi)
        row.append(f"{lo}-{hi}: {100*rel[m].max():.3f}" if m.any() else f"{lo}-{hi}: -")
    print("  ".join(row), f" t {float(A['secs']):.2f}->{float(B['secs']):.2f}")
