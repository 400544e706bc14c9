"""cold: `skymodel render --camera equirectangular --size WxH --quality final` in this process with
final's sun_exact_deg set; warm: bench_skyview's warm (render_environment at sun 30, 25, 20).
usage: timing.py cold|warm exact_deg size"""
import sys, time, os, tempfile, dataclasses
t0 = time.perf_counter()
what, ex, size = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
from skymodel.render import quality as Q
q = Q.QUALITIES["final"]
Q.QUALITIES["final"] = dataclasses.replace(q, settings=dataclasses.replace(q.settings, sun_exact_deg=ex))
Q.QUALITY["final"] = Q.QUALITIES["final"].settings
if what == "cold":
    from skymodel.cli import main
    with tempfile.TemporaryDirectory() as tmp:
        os.environ.setdefault("SKYMODEL_CACHE_DIR", tmp)
        main(["render", "--camera", "equirectangular", "--size", f"{size}x{size // 2}", "--quality", "final",
              "--out", os.path.join(tmp, "sky.exr"), "--quiet"])
    print(f"cold final {size}x{size//2} sun_exact {ex:g}: {time.perf_counter() - t0:.1f} s", flush=True)
else:
    from skymodel import Atmosphere
    from skymodel.render.environment import render_environment
    atm = Atmosphere(location="rural", month=6)
    with tempfile.TemporaryDirectory() as tmp:
        for k, sun in enumerate((30.0, 25.0, 20.0)):
            t = time.perf_counter()
            _, env = render_environment(atm, sun, 180.0, quality="final", width=size, cache_dir=tmp)
            print(f"warm final {size} sun_exact {ex:g} sun {sun:g} ({'cold' if k == 0 else 'sun only'}): "
                  f"{time.perf_counter() - t:.2f} s, method {env.info.get('method')}", flush=True)
