"""Test data shared across test folders (import as `from tests.support import ...`)."""

from __future__ import annotations

# A 35 m x 23 m-ish plot near the demo farm (seed 001's trial plot size), and a larger field.
SMALL_PLOT = {
    "type": "Polygon",
    "coordinates": [
        [
            [112.32000, 32.13000],
            [112.32037, 32.13000],
            [112.32037, 32.13021],
            [112.32000, 32.13021],
            [112.32000, 32.13000],
        ]
    ],
}

FIELD_WITH_HOLE = {
    "type": "Polygon",
    "coordinates": [
        [
            [112.3180, 32.1290],
            [112.3220, 32.1290],
            [112.3220, 32.1320],
            [112.3180, 32.1320],
            [112.3180, 32.1290],
        ],
        [
            [112.3195, 32.1300],
            [112.3195, 32.1308],
            [112.3205, 32.1308],
            [112.3205, 32.1300],
            [112.3195, 32.1300],
        ],
    ],
}


def feature(geometry: dict, **props: object) -> dict:
    return {"type": "Feature", "geometry": geometry, "properties": {"name": "Test field", **props}}
