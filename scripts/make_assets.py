"""Regenerate the shipped assets deterministically: the meshes in sonar_embree/assets/scenes/ and docs/demo.png.

    python scripts/make_assets.py

- sonar_embree/assets/scenes/anchor_mine.obj   the paper's anchor-mine test scene (§4.1): sinker and three spheres
- sonar_embree/assets/scenes/moored_mine.obj   the same mine with its sinker on the origin (placed by the
                                  detection sweep, sonar_embree/assets/sweeps/detection.toml)
- sonar_embree/assets/scenes/wreck.obj         the procedural patrol-boat wreck of Fig. 1, posed and sunk as in
                                  sonar_embree.scene.shipwreck.WRECK_POSE (its floors are procedural and
                                  built on first use by the configs in sonar_embree/assets/configs/)
- docs/demo.png                   the waterfall of ``sonar-embree demo``

Tests check that the shipped meshes equal what their generators give.
"""
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main() -> int:
    from sonar_embree.runs.cli import main as cli_main
    from sonar_embree.runs.demo import write_anchor_mine_obj, write_moored_mine_obj
    from sonar_embree.scene.shipwreck import write_wreck_obj

    scenes = os.path.join(ROOT, "sonar_embree", "assets", "scenes")
    write_anchor_mine_obj(os.path.join(scenes, "anchor_mine.obj"))
    write_moored_mine_obj(os.path.join(scenes, "moored_mine.obj"))
    write_wreck_obj(os.path.join(scenes, "wreck.obj"))
    out = os.path.join(ROOT, "out", "demo")
    code = cli_main(["demo", "-o", out, "--no-progress", "--overwrite"])
    if code == 0:
        os.makedirs(os.path.join(ROOT, "docs"), exist_ok=True)
        os.replace(os.path.join(out, "waterfall.png"), os.path.join(ROOT, "docs", "demo.png"))
    return code


if __name__ == "__main__":
    sys.exit(main())
