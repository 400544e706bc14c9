"""Profile one sun-only final 1024x512 rebuild (render_environment, rural June), one thread."""
import cProfile, pstats, sys, tempfile, time
import skymodel.render.marcher as marcher
from skymodel import Atmosphere
from skymodel.render.environment import render_environment
threads = int(sys.argv[1]) if len(sys.argv) > 1 else 1
suns = [float(x) for x in (sys.argv[2] if len(sys.argv) > 2 else "30,25").split(",")]
atm = Atmosphere(location="rural", month=6)
with tempfile.TemporaryDirectory() as tmp:
    render_environment(atm, suns[0], 180.0, quality="final", width=1024, cache_dir=tmp)
    marcher.MARCH_THREADS = threads
    for sun in suns[1:]:
        t = time.perf_counter()
        render_environment(atm, sun, 180.0, quality="final", width=1024, cache_dir=tmp)
        print(f"sun {sun}: {time.perf_counter()-t:.2f} s (threads {threads})")
    pr = cProfile.Profile()
    pr.enable()
    _, env = render_environment(atm, suns[-1] + 1.0, 180.0, quality="final", width=1024, cache_dir=tmp)
    pr.disable()
    print("timings", {k: round(v, 3) if isinstance(v, float) else v for k, v in env.info.items() if k.endswith("_s")})
    st = pstats.Stats(pr); st.sort_stats("tottime").print_stats(25)
    st.sort_stats("cumulative").print_stats(40)
