"""Ray casters side by side: build time and rays per second of Embree, the project's BVH on the CPU and, where a
CUDA GPU is present, the same BVH on the GPU; with their hit agreement against Embree (docs/benchmarks.md).

    python scripts/bench_casters.py            # prints one JSON line
    python scripts/bench_casters.py --rays 1000000

Scenes: the 2 M-triangle height field of scripts/bench_scale.py and the shipwreck (0.2 m). Rays: one side-scan
fan's worth of directions from 8 m above the floor (down-looking hemisphere, 40 m range), cast as one batch,
best of three after a warm-up. "agree" is the share of rays with Embree's triangle and "rel" the largest
relative distance difference where they agree. No GPU figure is printed where numba.cuda sees none. No test
reads it.
"""
import argparse
import json
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

import numpy as np  # noqa: E402

import sonar_embree as se  # noqa: E402
from sonar_embree import kernels  # noqa: E402
from sonar_embree.raycast import BvhCaster, CudaCaster, EmbreeCaster  # noqa: E402
from sonar_embree.scene import shipwreck  # noqa: E402


def _rays(c, n, seed=0):
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    d[:, 2] = -np.abs(d[:, 2]) - 0.2
    d /= np.linalg.norm(d, axis=1)[:, None]
    o = np.broadcast_to(np.array([0.0, 0.0, 8.0]) - c.origin_m, (n, 3))
    return np.ascontiguousarray(o, dtype=np.float32), np.ascontiguousarray(d, dtype=np.float32)


def _measure(cls, c, o, d, ref):
    t = time.perf_counter()
    caster = cls(c)
    build = time.perf_counter() - t
    caster.cast_raw(o[:1000], d[:1000], 40.0)                       # compile / warm up
    best = np.inf
    for _ in range(3):
        t = time.perf_counter()
        prim, tfar = caster.cast_raw(o, d, 40.0)
        best = min(best, time.perf_counter() - t)
    row = {"build s": round(build, 2), "Mrays/s": round(o.shape[0] / best / 1e6, 2)}
    if ref is not None:
        same = prim == ref[0]
        hit = same & (prim >= 0)
        row["agree"] = round(float(same.mean()), 5)
        row["rel"] = float(np.max(np.abs(tfar[hit] / ref[1][hit] - 1.0))) if hit.any() else 0.0
    return row, (prim, tfar)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rays", type=int, default=262_144)
    args = ap.parse_args()
    scenes = {"height field 2M": se.Scene().add(se.seafloor.perlin((200.0, 200.0), resolution_m=0.2, seed=1),
                                                label="seafloor"),
              "shipwreck": shipwreck.shipwreck_scene(resolution_m=0.2)}
    gpu = kernels.cuda_available() and os.environ.get("NUMBA_ENABLE_CUDASIM", "0") != "1"
    out = {"threads": kernels.num_threads(), "gpu": gpu}
    for name, scene in scenes.items():
        c = scene.compiled()
        o, d = _rays(c, args.rays)
        rows = {}
        rows["embree"], ref = _measure(EmbreeCaster, c, o, d, None)
        rows["bvh (cpu)"], _ = _measure(BvhCaster, c, o, d, ref)
        if gpu:
            rows["bvh (cuda)"], _ = _measure(CudaCaster, c, o, d, ref)
        out[name] = {"triangles": int(c.faces.shape[0]), **rows}
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
