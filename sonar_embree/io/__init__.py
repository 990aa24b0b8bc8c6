"""File formats of a :class:`~sonar_embree.record.Record`: Zarr via xarray, XTF, COCO JSON.

Each module owns one format; all write atomically (a temporary name, then a rename).
"""
