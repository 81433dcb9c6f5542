"""Pure planning geometry: CRS helpers, coverage path planning and the path-ordered grid.

Nothing here touches the database or the web (docs/architecture.md, "geo/").
"""


class PlanningError(ValueError):
    """Bad planning input (width, cell length, field geometry); the message says why."""


__all__ = ["PlanningError"]
