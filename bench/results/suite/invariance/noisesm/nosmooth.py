# monkeypatch probe: census pairs never presmoothed by QUANT_SIGMA (engine.frame_maps -> smooth False)
import runpy, sys
import flow_node.core.engine as e
_fm = e.frame_maps
def fm(*a, **k):
    maps, smooth = _fm(*a, **k)
    return maps, False
e.frame_maps = fm
sys.argv = ["bench.suite"] + sys.argv[1:]
runpy.run_module("bench.suite", run_name="__main__")
