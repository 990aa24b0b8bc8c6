"""Object bounding boxes in the waterfall image as COCO JSON (standard library only)."""
from __future__ import annotations

import json

from ..record import atomic_write


def category_of(label: str) -> str:
    """The COCO category of an object label: the label up to any ``#`` (``"mine#3"`` → ``"mine"``)."""
    return label.split("#", 1)[0]


def coco_dict(record, file_name: str, categories=None, image_id: int = 0, first_annotation_id: int = 1,
              max_columns: int | None = 1024) -> dict:
    """COCO detection dict of one record's waterfall image.

    Parameters
    ----------
    record : Record
        With labels (``simulate(labels=True)``).
    file_name : str
        The waterfall PNG the boxes refer to (written with the same ``max_columns``).
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
        ``images`` (one), ``annotations`` (one per object with highlight pixels:
        ``bbox`` [x, y, width, height] in pixels, ``area``, ``iscrowd`` 0, plus
        ``object_label`` and ``shadow_bbox``) and ``categories``.
    """
    from ..errors import ConfigError

    lab = record.labels
    if lab is None:
        raise ConfigError("COCO boxes need labels: simulate(..., labels=True)")
    if categories is None:
        categories = sorted({category_of(lab.names[i]) for i in lab.objects})
    cat_id = {name: i + 1 for i, name in enumerate(categories)}
    image = record.waterfall(max_columns=max_columns)
    anns = []
    for k, box in enumerate(lab.boxes(max_columns)):
        cat = category_of(box["label"])
        if cat not in cat_id:
            raise ConfigError(f"object {box['label']!r}: category {cat!r} is not among {list(categories)}")
        anns.append({"id": first_annotation_id + k, "image_id": image_id, "category_id": cat_id[cat],
                     "bbox": box["bbox"], "area": box["area"], "iscrowd": 0, "object_label": box["label"],
                     "shadow_bbox": box["shadow_bbox"]})
    return {"images": [{"id": image_id, "file_name": file_name, "width": int(image.shape[1]),
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
    out = {"images": [], "annotations": [], "categories": None}
    for d in dicts:
        if out["categories"] is None:
            out["categories"] = d["categories"]
        out["images"] += d["images"]
        out["annotations"] += d["annotations"]
    out["categories"] = out["categories"] or []
    return out
