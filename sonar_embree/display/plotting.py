"""Figures (the only module that imports matplotlib, an optional dependency: ``pip install sonar_embree[plots]``).

Waterfall images themselves need no plotting library (:mod:`sonar_embree.display.waterfall`);
this module draws the figures around them: mode comparisons, brightness histograms,
line plots and plan views of tracks.
"""
from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..io.files import atomic_write


def _pyplot():
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # pragma: no cover - depends on the installation
        raise ConfigError("figures need matplotlib: pip install 'sonar_embree[plots]'") from None
    return plt


def _save(fig, path):
    plt = _pyplot()
    atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"), suffix=".png")
    plt.close(fig)


def brightness_histogram_png(image, path, title="Pixel brightness distribution") -> np.ndarray:
    """Histogram of the 8-bit pixel values of a waterfall image, written as a PNG.

    Parameters
    ----------
    image : (h, w) uint8
        Waterfall image.
    path : str
        Output PNG (written atomically).

    Returns
    -------
    (256,) int
        Counts per brightness value.
    """
    plt = _pyplot()
    counts = np.bincount(np.asarray(image, dtype=np.uint8).ravel(), minlength=256)
    fig, ax = plt.subplots(figsize=(5.0, 3.2))
    ax.bar(np.arange(256), counts, width=1.0, color="0.25")
    ax.set_xlim(0, 255)
    ax.set_xlabel("pixel brightness (0–255)")
    ax.set_ylabel("pixels")
    ax.set_title(title)
    fig.tight_layout()
    _save(fig, path)
    return counts


def mosaic_png(images, titles, path, columns=2) -> None:
    """Several waterfall images side by side with titles, one PNG (atomic)."""
    plt = _pyplot()
    n = len(images)
    rows = int(np.ceil(n / columns))
    h, w = np.asarray(images[0]).shape[:2]
    fig, axes = plt.subplots(rows, columns, figsize=(columns * 4.2, rows * 4.2 * h / w + 0.6 * rows),
                             squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for ax, img, title in zip(axes.ravel(), images, titles):
        ax.imshow(img, cmap="gray", vmin=0, vmax=255, aspect="auto", interpolation="nearest")
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    _save(fig, path)


def speed_error_png(series, path, title="Speed against error") -> None:
    """Error against rays per ping and against time per ping, one line per series.

    Parameters
    ----------
    series : dict
        label → dict of equal-length sequences ``rays``, ``ms``, ``max_db``, ``rms_db``
        (rays per ping, ms per ping, max and RMS |error| in dB).
    path : str
        Output PNG (written atomically).
    """
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for label, s in series.items():
        for ax, x in zip(axes, ("rays", "ms")):
            line, = ax.loglog(s[x], s["rms_db"], "o-", label=f"{label}: RMS")
            ax.loglog(s[x], s["max_db"], "s--", color=line.get_color(), alpha=0.6, label=f"{label}: max")
    axes[0].set_xlabel("rays per ping")
    axes[1].set_xlabel("ms per ping")
    for ax in axes:
        ax.set_ylabel("|error| (dB)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    _save(fig, path)


def line_panels_png(panels, path, title=None) -> None:
    """Side-by-side line plots.

    Parameters
    ----------
    panels : list of dict
        Each: ``x`` (n,), ``lines`` [(label, y (n,)[, matplotlib format]), …], ``xlabel``, ``ylabel``,
        optional ``title``, ``ylim`` (lo, hi) and ``vlines`` [(x, label), …].
    path : str
        PNG written atomically.
    """
    plt = _pyplot()
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 3.8), squeeze=False)
    for ax, p in zip(axes[0], panels):
        for label, y, *fmt in p["lines"]:
            ax.plot(p["x"], y, *fmt, label=label, lw=1.0)
        for x, label in p.get("vlines", []):
            ax.axvline(x, color="0.4", ls="--", lw=0.8)
            ax.annotate(label, (x, 0.97), xycoords=("data", "axes fraction"), fontsize=8, ha="left", va="top")
        if "ylim" in p:
            ax.set_ylim(*p["ylim"])
        ax.set_xlabel(p["xlabel"])
        ax.set_ylabel(p["ylabel"])
        ax.set_title(p.get("title", ""), fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower center" if p.get("legend_low") else "best")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    _save(fig, path)


def plan_view_png(tracks, outlines, path, title=None) -> None:
    """Plan view (x east, y north, metres): vehicle tracks over object outlines.

    Parameters
    ----------
    tracks : dict
        label → (n, 2) track positions x, y in m (an arrow marks the direction of travel).
    outlines : dict
        label → (m, 2) closed polygon x, y in m (e.g. an object's convex footprint).
    path : str
        PNG written atomically.
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 5.0))
    for label, poly in outlines.items():
        poly = np.asarray(poly, dtype=float)
        ax.fill(poly[:, 0], poly[:, 1], color="0.75", ec="0.3", lw=0.8, label=label)
    for label, xy in tracks.items():
        xy = np.asarray(xy, dtype=float)
        line, = ax.plot(xy[:, 0], xy[:, 1], lw=1.4, label=label)
        k = max(1, len(xy) // 10)
        ax.annotate("", xy[-1], xy[-1 - k], arrowprops={"arrowstyle": "->", "color": line.get_color()})
    ax.set_aspect("equal")
    ax.set_xlabel("x, east (m)")
    ax.set_ylabel("y, north (m)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    _save(fig, path)
