"""A small object-detection dataset: mines and boxes on rippled sand, several seeds.

    python scripts/make_detection_dataset.py -o out/detection [--seeds 4] [--pings 160]
                                             [--workers N | --scheduler ADDRESS] [--quick] [--resume]
                                             [--example docs/detection_example.png]

Writes OUT/meshes/ (a cylindrical mine, a spherical mine, a box; metres, z up),
OUT/sweep.toml (the sweep, readable and re-runnable with ``sonar-embree batch``)
and OUT/dataset/: per job waterfall.png, labels.png, coco.json, record.zarr and
job.json, plus dataset/coco.json with every box (categories box, cylinder_mine,
sphere_mine), and OUT/example.png (or ``--example``): the first job's waterfall
above its labels. Each seed draws new ripples, object positions, headings and
backscatter; coherent CW speckle, 400 kHz, 30 m range.
"""
from __future__ import annotations

import argparse
import os
import sys

import trimesh

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

SWEEP = """\
# Mines and boxes on rippled sand, written by scripts/make_detection_dataset.py.
# sonar-embree batch sweep.toml -o dataset/
[sweep]
name = "mines-on-ripples"
seeds = {seeds}
outputs = ["png", "labels", "coco", "zarr"]
pings_per_task = 32

[sonar]
max_range_m = 30.0

[simulation]
speckle = true

[fan]
quality = {quality}

[png]
dynamic_range_db = 40.0
tvg = true

[[scenes]]
name = "ripples"
  [[scenes.objects]]
  seafloor = "ripples"
  size_m = [{floor}, {floor}]
  resolution_m = 0.2
  wavelength_m = 1.0
  height_m = 0.06
  crest_heading_deg = 20.0
  relief_m = 0.3
  material = {{backscatter_db = -27.0}}
  [[scenes.objects]]
  path = "meshes/cylinder_mine.obj"
  label = "cylinder_mine"
  count = 2
  region = [[{x0}, {x1}], [6.0, 24.0]]
  material = {{backscatter_db = [-18.0, -10.0]}}
  [[scenes.objects]]
  path = "meshes/sphere_mine.obj"
  label = "sphere_mine"
  count = 1
  region = [[{x0}, {x1}], [-24.0, -6.0]]
  material = {{backscatter_db = [-18.0, -10.0]}}
  [[scenes.objects]]
  path = "meshes/box.obj"
  label = "box"
  count = 1
  region = [[{x0}, {x1}], [-24.0, -6.0]]
  material = {{backscatter_db = [-20.0, -12.0]}}

[[trajectories]]
name = "along x"
kind = "line"
start = [{x0}, 0.0, 8.0]
end = [{x1}, 0.0, 8.0]
n_pings = {pings}
speed_m_s = 2.0
"""


def write_meshes(folder: str) -> None:
    """The three object meshes, each with its lowest point at z = 0."""
    os.makedirs(folder, exist_ok=True)
    cyl = trimesh.creation.cylinder(radius=0.27, height=1.7, sections=32)
    cyl.apply_transform(trimesh.transformations.rotation_matrix(1.5707963267948966, (0, 1, 0)))  # lying down
    meshes = {"cylinder_mine": cyl, "sphere_mine": trimesh.creation.icosphere(subdivisions=3, radius=0.5),
              "box": trimesh.creation.box((1.2, 0.8, 0.6))}
    for name, mesh in meshes.items():
        mesh.apply_translation((0.0, 0.0, -mesh.bounds[0, 2]))
        mesh.export(os.path.join(folder, f"{name}.obj"))


def write_example(job_dir: str, path: str) -> None:
    """The job's waterfall (grey) above its label image (colour), 4 white rows between (atomic)."""
    import imageio.v3 as iio
    import numpy as np

    from sonar_embree.io.files import atomic_write

    wf = iio.imread(os.path.join(job_dir, "waterfall.png"))
    lab = iio.imread(os.path.join(job_dir, "labels_preview.png"))[..., :3]
    gap = np.full((4,) + lab.shape[1:], 255, dtype=np.uint8)
    img = np.concatenate([np.repeat(wf[..., None], 3, axis=2), gap, lab], axis=0)
    atomic_write(path, lambda tmp: iio.imwrite(tmp, img, extension=".png"), suffix=".png")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("-o", "--output", default=os.path.join(ROOT, "out", "detection"), help="output folder")
    p.add_argument("--seeds", type=int, default=4, help="number of seeds (scenes), default 4")
    p.add_argument("--pings", type=int, default=160, help="pings per pass (0.25 m apart), default 160")
    p.add_argument("--workers", type=int, help="local Dask workers (default: CPU count)")
    p.add_argument("--scheduler", help="address of a running Dask scheduler")
    p.add_argument("--resume", action="store_true", help="continue an interrupted run")
    p.add_argument("--quick", action="store_true", help="2 seeds, 32 pings, quality 0.5 (for tests)")
    p.add_argument("--example", help="where to write the example image (default OUT/example.png)")
    args = p.parse_args(argv)
    sys.path.insert(0, ROOT)
    import sonar_embree as se

    seeds, pings, quality = (2, 32, 0.5) if args.quick else (args.seeds, args.pings, 1.0)
    length = 0.25 * (pings - 1)
    os.makedirs(args.output, exist_ok=True)
    write_meshes(os.path.join(args.output, "meshes"))
    sweep_path = os.path.join(args.output, "sweep.toml")
    with open(sweep_path, "w", encoding="utf-8") as fh:
        fh.write(SWEEP.format(seeds=seeds, pings=pings, quality=quality, floor=length + 70.0,
                              x0=-length / 2, x1=length / 2))
    try:
        se.batch.run(sweep_path, os.path.join(args.output, "dataset"), scheduler=args.scheduler,
                     workers=args.workers, resume=args.resume, progress=True)
    except se.SonarEmbreeError as exc:
        print(f"make_detection_dataset: error: {exc}", file=sys.stderr)
        return 2
    example = args.example or os.path.join(args.output, "example.png")
    write_example(os.path.join(args.output, "dataset", "00000"), example)
    print(os.path.join(args.output, "dataset", "coco.json"))
    print(example)
    return 0


if __name__ == "__main__":
    sys.exit(main())
