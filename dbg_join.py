import tempfile, time
from pathlib import Path
from benchmarks import bench_join
from dkreason.kb import KnowledgeBase, load_platforms, load_mappings
from dkreason.parse.config import read_config
from dkreason.manager import KnowledgeManager
from dkreason.monitor import Monitor
from dkreason.stream.processor import StreamPolicy
from dkreason.live.monitor import _Live
from dkreason.kb import read_platform
import cProfile, pstats
with tempfile.TemporaryDirectory() as tmp:
    folder = Path(tmp); bench_join.write(folder, 21)
    config = read_config(folder / "monitor.toml")
    known = load_platforms(config)
    kb = KnowledgeBase(config.local, dict(known), load_mappings(config), config.rules, config, online=set(known))
    km = KnowledgeManager(kb)
    mon = Monitor(km, ["forall s in Sensor: always (Reading[s] < 1000)"], StreamPolicy())
    src = _Live(); mon.start(src)
    for n in range(1, 22):
        pcfg = read_config(folder / f"p{n}.toml")
        plat = load_platforms(pcfg)[f"p{n}"]
        t0 = time.perf_counter()
        if n == 21:
            pr = cProfile.Profile(); pr.enable()
        kb.add_platform(plat)
        t1 = time.perf_counter()
        req = mon.rematch(src)
        t2 = time.perf_counter()
        if n == 21:
            pr.disable()
        print(n, f"add {1e3*(t1-t0):.1f} ms rematch {1e3*(t2-t1):.1f} ms topics {sum(len(f.topics) for f in req.features)}")
    pstats.Stats(pr).sort_stats("cumulative").print_stats(25)
