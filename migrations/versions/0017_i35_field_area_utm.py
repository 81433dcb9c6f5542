"""fields.area_m2 measured in the field's UTM plane, the one area basis.

Why: cells, prescriptions and job reports measure areas in the field's UTM plane while
the stored field area was geodesic, so a field could show less area than its own cells
cover (the two differ by the UTM scale factor squared, up to 0.2 %). New fields store
the plane area (``geo.crs.plane_area_m2``); this recomputes the existing ones the same
way. Downgrade restores the geodesic area (PostGIS on the WGS84 spheroid).

Revision ID: 0017_i35_field_area_utm
Revises: 0017_i31_citus_keys
"""

from __future__ import annotations

from collections.abc import Sequence

from alembic import op

revision: str = "0017_i35_field_area_utm"
down_revision: str | Sequence[str] | None = "0017_i31_citus_keys"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.execute("UPDATE fields SET area_m2 = ST_Area(ST_Transform(boundary, utm_epsg))")


def downgrade() -> None:
    op.execute("UPDATE fields SET area_m2 = ST_Area(boundary::geography, true)")
