"""variant.py with multiple_scattering.GROUND_SPLIT changed: variant_split.py scene tag split"""
import runpy, sys
import skymodel.render.multiple_scattering as ms
ms.GROUND_SPLIT = int(sys.argv[3])
sys.argv = [sys.argv[0], sys.argv[1], sys.argv[2], ""]
runpy.run_path("notebooks/truth_misses/variant.py", run_name="__main__")
