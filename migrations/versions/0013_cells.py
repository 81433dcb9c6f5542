"""plan_cells.geom holds a split cell whole: Polygon or MultiPolygon.

Why: a cell that a notch or hole cuts in two was stored as its largest part, so
the map, the exports, the job package and the as-applied report all saw a
different cell than the grid made (and its area no longer matched its polygon).
The column becomes ``geometry(Geometry, 4326)`` with a CHECK that it is a
Polygon or MultiPolygon; existing rows are unchanged (they are all Polygons).
New partitions copy the CHECK (``store.cells`` creates them ``LIKE plan_cells
INCLUDING CONSTRAINTS``; ATTACH PARTITION requires it).

Downgrade keeps each MultiPolygon's largest part again (what was stored before).

Revision ID: 0013_cells
Revises: 0012_tasks
"""

from __future__ import annotations

from collections.abc import Sequence

from alembic import op

revision: str = "0013_cells"
down_revision: str | Sequence[str] | None = "0012_tasks"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

CHECK = "plan_cells_geom_polygonal"


def upgrade() -> None:
    op.execute("ALTER TABLE plan_cells ALTER COLUMN geom TYPE geometry(Geometry, 4326)")
    op.execute(
        f"ALTER TABLE plan_cells ADD CONSTRAINT {CHECK}"
        " CHECK (GeometryType(geom) IN ('POLYGON', 'MULTIPOLYGON'))"
    )


def downgrade() -> None:
    op.execute(f"ALTER TABLE plan_cells DROP CONSTRAINT {CHECK}")
    op.execute(
        """
        CREATE FUNCTION fieldrx_largest_part(g geometry) RETURNS geometry
        LANGUAGE sql IMMUTABLE AS $$
          SELECT d.geom FROM ST_Dump(g) d ORDER BY ST_Area(d.geom) DESC LIMIT 1
        $$
        """
    )
    op.execute(
        "ALTER TABLE plan_cells ALTER COLUMN geom TYPE geometry(Polygon, 4326)"
        " USING fieldrx_largest_part(geom)"
    )
    op.execute("DROP FUNCTION fieldrx_largest_part(geometry)")
