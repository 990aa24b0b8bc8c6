"""The gallery, built from the figure scripts in ``scripts/``: one page per script with its docstring, the
command that makes its figures, the figures it wrote into ``docs/`` and its source.

The pages are written into ``docs/gallery/scripts/`` when the build starts (a generated folder, ignored by git):
a script added to :data:`SCRIPTS` appears in the gallery with nothing else to edit.
"""
import ast
import glob
import os

#: Figure script -> (the command's arguments, the figures it writes, relative to docs/).
SCRIPTS = {
    "physics_plots": ("-o docs/physics", ["physics/beam_pattern.png", "physics/ping.png"]),
    "paper_modes": ("-o docs/paper_modes", ["paper_modes/modes.png", "paper_modes/cw_incoherent_histogram.png"]),
    "paper_shipwreck": ("--figure 8 -o docs/shipwreck  (and --figure 9)",
                        ["shipwreck/fig8_fm_baseband_straight.png", "shipwreck/fig9_straight_vs_curved.png",
                         "shipwreck/fig9_tracks.png"]),
    "seafloor_gallery": ("-o docs/seafloors", ["seafloors/presets.png", "seafloors/sigma.png",
                                               "seafloors/migration.png"]),
    "multipath_figure": ("-o docs/multipath", ["multipath/waterfalls.png", "multipath/ping.png"]),
    "refraction_figure": ("-o docs/refraction", ["refraction/waterfalls.png", "refraction/ping.png"]),
    "msis_figure": ("-o docs/msis", ["msis/polar.png"]),
    "fls_figure": ("-o docs/fls", ["fls/fan.png"]),
    "device_figure": ("-o docs/device", ["device/waterfalls.png"]),
    "survey_xtf_figure": ("-o docs/survey", ["survey/xtf_waterfalls.png"]),
    "realism_figure": ("-o docs/realism", ["realism/waterfalls.png"]),
    "sas_figure": ("-o docs/sas", ["sas/sas.png"]),
    "survey_from_dem": ("-o out/survey --figure docs/survey/survey.png", ["survey/survey.png"]),
    "make_detection_dataset": ("-o out/detection --example docs/detection_example.png", ["detection_example.png"]),
    "make_assets": ("", ["demo.png"]),
    "bench_speed_vs_error": ("-o docs", ["speed_vs_error.png"]),
}


def _page(docs: str, name: str, args: str, figures: list) -> str:
    path = os.path.join(docs, os.pardir, "scripts", f"{name}.py")
    with open(path, encoding="utf-8") as fh:
        doc = ast.get_docstring(ast.parse(fh.read())) or name
    title, _, rest = doc.partition("\n")
    command = f"python scripts/{name}.py {args}".rstrip()
    lines = [f"# {title.strip()}", "", rest.strip(), "", "```bash", command, "```", ""]
    for fig in figures:
        lines += [f"![{os.path.basename(fig)}](../../{fig})", ""]
    lines += ["```{literalinclude} " + f"../../../scripts/{name}.py", ":language: python", "```", ""]
    return "\n".join(lines)


def write_pages(app) -> None:
    """Write one page per figure script and the gallery's table of contents, only where they changed."""
    docs = app.srcdir
    out = os.path.join(docs, "gallery", "scripts")
    os.makedirs(out, exist_ok=True)
    pages = {f"{name}.md": _page(docs, name, *SCRIPTS[name]) for name in sorted(SCRIPTS)}
    pages["index.md"] = "# The scripts\n\nEach figure script, its command, its figures and its source.\n\n" \
        "```{toctree}\n:maxdepth: 1\n\n" + "\n".join(sorted(n[:-3] for n in pages)) + "\n```\n"
    for name, text in pages.items():
        path = os.path.join(out, name)
        if not os.path.exists(path) or open(path, encoding="utf-8").read() != text:
            with open(path, "w", encoding="utf-8") as fh:
                fh.write(text)
    for stale in set(glob.glob(os.path.join(out, "*.md"))) - {os.path.join(out, n) for n in pages}:
        os.remove(stale)


def setup(app):
    app.connect("builder-inited", write_pages)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
