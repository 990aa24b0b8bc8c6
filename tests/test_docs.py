"""The documentation site (issue 36, item 7): it builds with warnings as errors, every module is in the API
reference, every figure script in the gallery, and the README stays a short front page."""
import os
import re
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.join(os.path.dirname(__file__), os.pardir)
PACKAGE = os.path.join(ROOT, "sonar_embree")


def _modules():
    out = set()
    for d, _, fs in os.walk(PACKAGE):
        for f in fs:
            if f.endswith(".py"):
                rel = os.path.relpath(os.path.join(d, f), ROOT)[:-3].replace(os.sep, ".")
                out.add(rel[:-len(".__init__")] if rel.endswith(".__init__") else rel)
    return out


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """The site built from a copy of docs/, scripts/ and the changelog (the build writes generated pages into
    its source folder), with ``-W``: any warning fails the build."""
    src = tmp_path_factory.mktemp("site")
    shutil.copytree(os.path.join(ROOT, "docs"), src / "docs",
                    ignore=shutil.ignore_patterns("_build", "generated", "scripts"))
    shutil.copytree(os.path.join(ROOT, "scripts"), src / "scripts")
    shutil.copy(os.path.join(ROOT, "CHANGELOG.md"), src / "CHANGELOG.md")
    out = src / "html"
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
                           str(src / "docs"), str(out)], capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-4000:]
    return out


def test_the_site_builds_without_warnings_and_has_every_section(site):
    for page in ("index", "getting-started", "gallery/index", "guide/simulation", "guide/sonars", "guide/environment",
                 "guide/scenes", "guide/datasets", "guide/surveys", "guide/cli", "api/index", "physics", "validation",
                 "benchmarks", "architecture", "changelog"):
        assert (site / f"{page}.html").is_file(), page


def test_every_module_has_an_api_page(site):
    pages = {p[:-5] for p in os.listdir(site / "api" / "generated") if p.endswith(".html")}
    public = {m for m in _modules() if not m.rsplit(".", 1)[-1].startswith("_")}   # _version, _numba, __main__
    assert public - pages == set()
    simulate = (site / "api" / "generated" / "sonar_embree.simulate.html").read_text(encoding="utf-8")
    assert "Parameters" in simulate and "trajectory" in simulate     # numpydoc sections rendered


def test_every_figure_script_is_in_the_gallery_with_its_figures(site):
    sys.path.insert(0, os.path.join(ROOT, "docs", "_ext"))
    try:
        from gallery import SCRIPTS
    finally:
        sys.path.pop(0)
    figure_scripts = {f[:-3] for f in os.listdir(os.path.join(ROOT, "scripts"))
                      if f.endswith(".py") and not f.startswith("bench_")}
    assert figure_scripts <= set(SCRIPTS), figure_scripts - set(SCRIPTS)
    for name, (_, figures) in SCRIPTS.items():
        page = (site / "gallery" / "scripts" / f"{name}.html").read_text(encoding="utf-8")
        assert f"scripts/{name}.py" in page
        for fig in figures:
            assert os.path.isfile(os.path.join(ROOT, "docs", fig)), fig
            assert os.path.basename(fig) in os.listdir(site / "_images"), fig


def test_the_readme_is_a_front_page_with_the_two_set_up_commands():
    text = open(os.path.join(ROOT, "README.md"), encoding="utf-8").read()
    assert len(text.splitlines()) <= 160
    blocks = re.findall(r"```bash\n(.*?)\n```", text, re.S)
    demo = ("python3 -m venv .venv && . .venv/bin/activate && python -m pip install -q -e . && "
            "sonar-embree demo -o out/demo")
    tests = ('python3 -m venv .venv && . .venv/bin/activate && python -m pip install -q -e ".[test]" && '
             "python -m pytest -q -n 2")
    assert blocks[:2] == [demo, tests]
    ci = open(os.path.join(ROOT, ".ci", "run"), encoding="utf-8").read()
    assert 'python -m pip install -q -e ".[test]" && python -m pytest -q -n 2' in ci
    for link in re.findall(r"\]\(((?!https?:)[^)#]+)\)", text):
        assert os.path.exists(os.path.join(ROOT, link)), link
