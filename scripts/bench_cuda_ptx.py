"""Compile the GPU caster's kernel to PTX without a GPU: a check that its device code types and compiles for a
real CUDA target (numba's simulator, which the tests use, runs it as Python and checks no types).

    pip install nvidia-cuda-nvcc-cu12          # NVVM, the compiler numba.cuda drives (not a project dependency)
    python scripts/bench_cuda_ptx.py           # prints one JSON line: PTX size, float64 and local-memory use

NVVM is found in the pip wheel. numba asks the current device for its compute capability when it compiles a
device function; with no driver there is none, so this script answers sm_90 (an H100) itself. No test reads it.
"""
import glob
import json
import os
import re
import sys
import types as pytypes

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

CC = (9, 0)


def _nvvm() -> str:
    import nvidia.cuda_nvcc as nvcc            # the pip wheel of the CUDA compiler

    root = os.path.dirname(nvcc.__file__) if nvcc.__file__ else list(nvcc.__path__)[0]
    hits = glob.glob(os.path.join(root, "nvvm", "lib64", "libnvvm.so*"))
    if not hits:
        raise SystemExit(f"no libnvvm.so under {root}: pip install nvidia-cuda-nvcc-cu12")
    os.environ.setdefault("CUDA_HOME", root)
    os.environ.setdefault("NUMBA_CUDA_NVVM", hits[0])
    return hits[0]


def main() -> int:
    nvvm = _nvvm()
    import numba.cuda.dispatcher as dispatcher
    from numba import cuda, types

    from sonar_embree.kernels import bvh

    dispatcher.get_current_device = lambda: pytypes.SimpleNamespace(compute_capability=CC)
    f32, i32 = types.float32, types.int32
    sig = (f32[:, ::1], i32[:, ::1], i32[::1], f32[:, ::1], f32[:, ::1], f32[:, ::1], f32[:, ::1], f32[:, ::1], f32,
           i32[::1], f32[::1])
    bvh.cuda = cuda                             # the kernel body's global, as cuda_traverse() sets it
    ptx, _ = cuda.compile_ptx(bvh._traverse_one_ray, sig, cc=CC)
    print(json.dumps({"nvvm": nvvm, "cc": "sm_%d%d" % CC, "ptx chars": len(ptx),
                      "float64 instructions": len(re.findall(r"\.f64\b", ptx)), "local stack": ".local" in ptx}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
