"""Interleaved A/B frame times of one boolean setting (off, then on, alternating order frame by frame), for
a machine whose load drifts: the bench times one configuration after the other, so on a shared CPU its
before/after ratios carry the drift (its HARD rows, which no such setting touches, move by ±40 % here).

    PYTHONPATH=. python tools/ab_timing.py --setting early_skip --scenes plane,cube --resolution 384 --repeats 5

Per scene and technique: median wall time of a normal frame, median of the synchronised stages `--stages`
(default: lit_umbra + visibility, the work early_skip changes), process CPU time, and with `collect_stats`
the share of skipped pixels (skip_lit + skip_umbra over skip_candidates)."""
import argparse
import time

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--setting", default="early_skip")
    ap.add_argument("--scenes", default="plane,suzanne,tilted,grazing,cube")
    ap.add_argument("--techniques", default="HARD,PCSS,REFERENCE")
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--stages", default="lit_umbra,visibility")
    a = ap.parse_args()

    import bpy
    from penumbra.engine.blender.extract import extract
    from penumbra.engine.core.settings import RenderSettings
    from penumbra.engine.measure import scenes
    from penumbra.engine.render import pipeline

    stages = a.stages.split(",")
    print(f"{a.resolution}², {a.setting} off/on, median of {a.repeats} interleaved frames; work = "
          f"synchronised {' + '.join(stages)}; cpu = process CPU time")
    print(f"{'scene':9s} {'technique':9s} {'off ms':>8s} {'on ms':>8s} {'on/off':>6s} {'work off':>8s} "
          f"{'work on':>8s} {'cpu off':>8s} {'cpu on':>8s} {'skipped':>7s}")
    for name in a.scenes.split(","):
        scene = scenes.build(name, resolution=(a.resolution, a.resolution))
        snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
        for technique in a.techniques.split(","):
            s = {k: RenderSettings(technique=technique).with_(**{a.setting: k}) for k in (False, True)}
            for k in s:
                pipeline.render(snap, s[k])             # shaders compiled, pools filled
            wall, work, cpu = ({False: [], True: []} for _ in range(3))
            for i in range(a.repeats):
                for k in ((False, True) if i % 2 == 0 else (True, False)):
                    t0, c0 = time.perf_counter(), time.process_time()
                    pipeline.render(snap, s[k])
                    wall[k].append((time.perf_counter() - t0) * 1e3)
                    cpu[k].append((time.process_time() - c0) * 1e3)
                    t = pipeline.render(snap, s[k], stage_times=True).timings
                    work[k].append(sum(t.get(n, 0.0) for n in stages))
            st = pipeline.render(snap, s[True].with_(collect_stats=True)).stats
            n = st.get("skip_candidates", 0)
            share = f"{(st.get('skip_lit', 0) + st.get('skip_umbra', 0)) / n:7.2f}" if n else f"{'–':>7s}"
            m = {k: [float(np.median(d[k])) for d in (wall, work, cpu)] for k in (False, True)}
            print(f"{name:9s} {technique:9s} {m[False][0]:8.1f} {m[True][0]:8.1f} {m[True][0] / m[False][0]:6.2f} "
                  f"{m[False][1]:8.1f} {m[True][1]:8.1f} {m[False][2]:8.1f} {m[True][2]:8.1f} {share}", flush=True)


if __name__ == "__main__":
    main()
