"""Regenerate the shipped assets deterministically: assets/scenes/anchor_mine.obj and docs/demo.png.

    python scripts/make_assets.py
"""
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main() -> int:
    from sonar_embree.cli import main as cli_main
    from sonar_embree.demo import write_anchor_mine_obj

    write_anchor_mine_obj(os.path.join(ROOT, "assets", "scenes", "anchor_mine.obj"))
    out = os.path.join(ROOT, "out", "demo")
    code = cli_main(["demo", "-o", out, "--no-progress"])
    if code == 0:
        os.makedirs(os.path.join(ROOT, "docs"), exist_ok=True)
        os.replace(os.path.join(out, "waterfall.png"), os.path.join(ROOT, "docs", "demo.png"))
    return code


if __name__ == "__main__":
    sys.exit(main())
