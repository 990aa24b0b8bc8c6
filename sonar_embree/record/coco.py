"""Objects in the waterfall image as COCO JSON: boxes and RLE masks (standard library and NumPy only).

One annotation per connected piece (8-connected) of an object's echo in the
waterfall image (:meth:`~sonar_embree.signal.labels.Labels.echo_mask`), with its box, area
and its mask as compressed run-length encoding, COCO's column-major RLE that
``pycocotools.mask.decode`` / ``COCO.annToMask`` read.
"""
from __future__ import annotations

import json

import numpy as np

from ..io.files import atomic_write
from ..errors import ConfigError
from ..signal.labels import _bbox


def category_of(label: str) -> str:
    """The COCO category of an object label: the label up to any ``#`` (``"mine#3"`` → ``"mine"``)."""
    return label.split("#", 1)[0]


def rle_counts(mask: np.ndarray) -> list:
    """Uncompressed COCO run lengths of a (h, w) bool mask: column-major, starting with a run of zeros."""
    flat = np.asarray(mask, dtype=bool).ravel(order="F")
    change = np.flatnonzero(flat[1:] != flat[:-1]) + 1
    edges = np.concatenate([[0], change, [flat.size]])
    runs = np.diff(edges).tolist()
    return ([0] + runs) if flat.size and flat[0] else runs


def rle_string(counts: list) -> str:
    """COCO's compressed RLE string of run lengths (the LEB128-like code of pycocotools' ``rleToString``)."""
    out = []
    for i, x in enumerate(counts):
        if i > 2:
            x -= counts[i - 2]  # runs are coded as differences to the run two before
        more = True
        while more:
            c = x & 0x1F
            x >>= 5  # arithmetic shift: negative differences end at −1
            more = x != -1 if c & 0x10 else x != 0
            if more:
                c |= 0x20
            out.append(chr(c + 48))
    return "".join(out)


def encode_mask(mask: np.ndarray) -> dict:
    """A (h, w) bool mask as COCO compressed RLE: ``{"size": [h, w], "counts": str}``."""
    h, w = mask.shape
    return {"size": [int(h), int(w)], "counts": rle_string(rle_counts(mask))}


def pieces(mask: np.ndarray) -> list:
    """The 8-connected pieces of a bool image, as bool images, in order of their first pixel."""
    from scipy import ndimage

    lab, n = ndimage.label(mask, structure=np.ones((3, 3), dtype=bool))
    return [lab == k for k in range(1, n + 1)]


def info_block(record) -> dict:
    """COCO ``info``: what made the images and when (the record's start time)."""
    from .._version import __version__

    start = str(record.attrs.get("start_time", ""))
    return {"description": "simulated side-scan sonar waterfalls (sonar_embree)", "version": __version__,
            "year": int(start[:4]) if start[:4].isdigit() else 0, "date_created": start,
            "contributor": "sonar_embree", "url": ""}


def coco_dict(record, file_name: str, categories=None, image_id: int = 0, first_annotation_id: int = 1,
              max_columns: int | None = 1024) -> dict:
    """COCO detection/segmentation dict of one record's waterfall image.

    Parameters
    ----------
    record : Record
        With labels (``simulate(labels=True)``).
    file_name : str
        The waterfall PNG the annotations refer to (written with the same ``max_columns``).
    categories : sequence of str, optional
        Category names, ids 1, 2, … in this order; default the record's object
        categories, sorted.
    image_id, first_annotation_id : int
        Ids, for merging several images into one dataset.
    max_columns : int or None
        As :meth:`Record.waterfall`.

    Returns
    -------
    dict
        ``info``, ``images`` (one), ``annotations`` (one per connected piece of each
        object's echo: ``bbox`` [x, y, width, height] in pixels, ``area`` (pixels),
        ``segmentation`` (compressed RLE), ``iscrowd`` 0, plus ``object_label`` and
        ``shadow_bbox``) and ``categories``.
    """
    lab = record.labels
    if lab is None:
        raise ConfigError("COCO boxes need labels: simulate(..., labels=True)")
    if categories is None:
        categories = sorted({category_of(lab.names[i]) for i in lab.objects})
    cat_id = {name: i + 1 for i, name in enumerate(categories)}
    image = record.waterfall(max_columns=max_columns)
    anns = []
    for box in lab.boxes(max_columns):
        cat = category_of(box["label"])
        if cat not in cat_id:
            raise ConfigError(f"object {box['label']!r}: category {cat!r} is not among {list(categories)}")
        for piece in pieces(box["mask"]):
            anns.append({"id": first_annotation_id + len(anns), "image_id": image_id, "category_id": cat_id[cat],
                         "bbox": _bbox(piece), "area": int(piece.sum()), "segmentation": encode_mask(piece),
                         "iscrowd": 0, "object_label": box["label"], "shadow_bbox": box["shadow_bbox"]})
    return {"info": info_block(record),
            "images": [{"id": image_id, "file_name": file_name, "width": int(image.shape[1]),
                        "height": int(image.shape[0])}],
            "annotations": anns,
            "categories": [{"id": i, "name": n, "supercategory": "object"} for n, i in cat_id.items()]}


def write_json(obj, path) -> None:
    """Write JSON atomically, with sorted keys (the same bytes for the same content)."""
    text = json.dumps(obj, indent=1, sort_keys=True)

    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)

    atomic_write(path, write, suffix=".json")


def merge(dicts) -> dict:
    """One COCO dataset from per-image dicts that share their categories."""
    out = {"info": None, "images": [], "annotations": [], "categories": None}
    for d in dicts:
        if out["categories"] is None:
            out["categories"] = d["categories"]
            out["info"] = d.get("info")
        out["images"] += d["images"]
        out["annotations"] += d["annotations"]
    out["categories"] = out["categories"] or []
    out["info"] = out["info"] or {}
    return out
