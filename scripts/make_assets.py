"""Regenerate the shipped assets deterministically: the meshes in assets/scenes/ and docs/demo.png.

    python scripts/make_assets.py

- assets/scenes/anchor_mine.obj   the paper's anchor-mine test scene (§4.1): sinker and three spheres
- assets/scenes/wreck.obj         the procedural patrol-boat wreck of Fig. 1, posed and sunk as in
                                  sonar_embree.shipwreck.WRECK_POSE (its floors are procedural and
                                  built on first use by the configs in assets/configs/)
- docs/demo.png                   the waterfall of ``sonar-embree demo``

Tests check that the shipped meshes equal what their generators give.
"""
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main() -> int:
    from sonar_embree.cli import main as cli_main
    from sonar_embree.demo import write_anchor_mine_obj
    from sonar_embree.shipwreck import write_wreck_obj

    scenes = os.path.join(ROOT, "assets", "scenes")
    write_anchor_mine_obj(os.path.join(scenes, "anchor_mine.obj"))
    write_wreck_obj(os.path.join(scenes, "wreck.obj"))
    out = os.path.join(ROOT, "out", "demo")
    code = cli_main(["demo", "-o", out, "--no-progress"])
    if code == 0:
        os.makedirs(os.path.join(ROOT, "docs"), exist_ok=True)
        os.replace(os.path.join(out, "waterfall.png"), os.path.join(ROOT, "docs", "demo.png"))
    return code


if __name__ == "__main__":
    sys.exit(main())
